"""`navbench run`'s options: what reaches the agent's config, the per-agent defaults, and the run's name."""

import argparse
import os

import pytest

from navbench.agents.registry import AGENTS, DEFAULT_DECODING, agent_factory, agent_options, decoding_of, run_label
from navbench.cli import _agent_options, build_parser, main, run_dir
from navbench.policy.net import DECODINGS


def _run(*flags):
    """(options as config.json records them, the run's label) for `navbench run FLAGS`."""
    args = build_parser().parse_args(["run", *flags])
    args.agent = args.agent or "pointnav"
    opts = _agent_options(args)
    return opts, run_label(args.agent, opts, args.seed)


def test_each_policy_agent_has_its_reported_decoding_by_default_and_records_it():
    # pointnav: its table's headline row is least-tried; the ObjectNav tables are argmax
    assert DEFAULT_DECODING == {"pointnav": "least-tried", "memory": "argmax", "frontier": "argmax",
                                "vln_memory": "argmax"}
    opts, label = _run("--task", "pointnav", "--agent", "pointnav")
    assert opts == {"decoding": "least-tried"} and label == "pointnav"
    for agent in ("memory", "frontier"):
        opts, label = _run("--agent", agent)
        assert opts["decoding"] == "argmax" and "temperature" not in opts and label == agent
    assert _run("--agent", "oracle") == ({}, "oracle")  # no policy, no decoding


def test_decoding_flags_name_the_run_when_they_differ_from_the_agents_default():
    assert _run("--task", "pointnav", "--decoding", "argmax") == ({"decoding": "argmax"}, "pointnav-argmax")
    assert _run("--agent", "memory", "--decoding", "least-tried")[1] == "memory-least-tried"
    opts, label = _run("--task", "pointnav", "--decoding", "sample")
    assert opts == {"decoding": "sample", "temperature": 1.0} and label == "pointnav-sample"
    opts, label = _run("--task", "pointnav", "--decoding", "sample", "--temperature", "0.5")
    assert opts["temperature"] == 0.5 and label == "pointnav-sample_t0.5"
    for decoding in DECODINGS:  # the CLI offers every decoding the policy has
        assert _run("--task", "pointnav", "--decoding", decoding)[0]["decoding"] == decoding


@pytest.mark.parametrize("flags,match", [
    (["--task", "pointnav", "--temperature", "0.5"], "temperature"),  # least-tried draws no temperature
    (["--task", "pointnav", "--decoding", "sample", "--temperature", "0"], "temperature"),
    (["--agent", "oracle", "--decoding", "sample"], "read by pointnav, memory, frontier"),  # no policy to draw from
    (["--agent", "frontier", "--no-fusion"], "fusion"),  # a memory agent ablation
    (["--task", "pointnav", "--noise", "default"], "noise"),
    (["--task", "pointnav", "--noise", "none"], "noise"),  # given at its default is still given
    (["--agent", "oracle", "--agent-opt", "decoding=sample"], "takes no option 'decoding'"),
    (["--agent", "memory", "--agent-opt", "fusion=1"], "true or false"),
])
def test_options_an_agent_does_not_use_are_refused_in_one_line(flags, match):
    with pytest.raises(ValueError, match=match) as exc:
        _run(*flags)
    assert "\n" not in str(exc.value)


@pytest.mark.parametrize("argv,flag", [
    (["--agent", "oracle", "--checkpoint", "x.pth"], "--checkpoint"),
    (["--agent", "random", "--perception", "oracle"], "--perception"),
    (["--agent", "pointnav", "--no-fusion"], "--no-fusion"),
    (["--agent", "frontier", "--rerank", "none"], "--rerank"),
    (["--agent", "frontier", "--keyframe-res", "160x120"], "--keyframe-res"),
    (["--agent", "memory", "--agent-opt", "nope=1"], "'nope'"),
    (["--agent", "walkmod:Walker", "--siglip2", "/models/s"], "--siglip2"),  # a plug-in reads --agent-opt only
    (["--agent", "walkmod:Walker", "--no-tracking"], "--no-tracking"),
])
def test_a_flag_the_agent_does_not_read_exits_2_naming_it(argv, flag, capsys):
    assert main(["run", "--task", "pointnav", "--episodes", "nowhere.json", *argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and flag in err, err


@pytest.mark.parametrize("argv,match", [
    (["--agent", "oracle", "--backend", "ray", "--address", "auto", "--workers", "3"], "--workers"),
    (["--agent", "oracle", "--envs-per-worker", "4"], "--envs-per-worker"),
    (["--agent", "random", "--envs-per-worker", "2"], "--envs-per-worker"),
])
def test_an_execution_flag_that_cannot_apply_exits_2(argv, match, capsys, tmp_path):
    assert main(["run", "--task", "pointnav", "--limit", "1", "--out", str(tmp_path / "r"), "-q", *argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and match in err, err
    assert not (tmp_path / "r").exists()


def test_removed_flags_are_gone():
    for flag in ("--sample-actions", "--sample-on-revisit", "--least-tried", "--no-verify", "--no-recovery",
                 "--no-standoff", "--no-detour", "--no-route", "--no-probe", "--no-guidance"):
        with pytest.raises(SystemExit):
            build_parser().parse_args(["run", flag])


def test_memory_ablations_are_recorded_and_labelled_in_one_order():
    opts, label = _run("--agent", "memory")
    assert opts == {"decoding": "argmax", "perception": "oracle", "noise": "none", "fusion": True, "rerank": True,
                    "keyframe_res": "full", "all_frames": False, "goal_tracking": True, "visibility_stop": True,
                    "models": {}}
    assert _run("--agent", "memory", "--rerank", "none")[1] == "memory-norerank"
    assert _run("--agent", "memory", "--noise", "default")[1] == "memory-noise_default"
    opts, label = _run("--agent", "memory", "--no-look-round")
    assert opts["look_round"] is False and label == "memory-nolookround"
    _, label = _run("--agent", "memory", "--all-frames", "--keyframe-res", "160x120", "--no-visibility-stop",
                    "--no-tracking", "--no-fusion", "--rerank", "none", "--noise", "heavy", "--decoding", "least-tried",
                    "--seed", "1", "--checkpoint", "policies/pointnav_2h.pth")
    assert label == ("memory-pointnav_2h-least-tried-seed1-noise_heavy-norerank-nofusion-notrack-novisstop-160x120-"
                     "allframes")


def test_the_seed_names_a_run_only_when_the_agent_draws():
    assert _run("--task", "pointnav", "--checkpoint", "policies/pointnav_2h.pth", "--seed", "3")[1] == \
        "pointnav-pointnav_2h-seed3"
    assert _run("--task", "pointnav", "--decoding", "argmax", "--seed", "3")[1] == "pointnav-argmax"
    assert _run("--agent", "memory", "--seed", "3")[1] == "memory"  # argmax: the seed changes nothing
    assert _run("--agent", "random", "--seed", "3")[1] == "random-seed3"
    assert _run("--agent", "oracle", "--seed", "3")[1] == "oracle"
    assert _run("--task", "pointnav", "--checkpoint", "policies/pointnav_navbench.pth")[1] == "pointnav"


def test_registry_lookup_and_run_directory():
    assert set(AGENTS) == {"oracle", "optimistic", "random", "pointnav", "memory", "frontier", "vln_random",
                           "vln_forward", "vln_oracle", "vln_memory"}
    assert agent_factory("memory") is AGENTS["memory"]
    with pytest.raises(ValueError, match="unknown agent 'nope': choose from oracle"):
        agent_factory("nope")
    assert str(run_dir("pointnav", "val", "pointnav-argmax")) == "runs/pointnav/val/pointnav-argmax"


def test_unknown_agent_is_one_line_and_exit_code_2(capsys):
    assert main(["run", "--agent", "nope"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unknown agent 'nope'" in err


def test_configs_written_before_the_decoding_option_still_say_how_they_decoded():
    assert decoding_of({}) == ("argmax", 1.0)
    assert decoding_of({"sample_actions": True, "temperature": 0.5}) == ("sample", 0.5)
    assert decoding_of({"sample_actions": True, "sample_on_revisit": True, "least_tried": True}) == \
        ("least-tried", 1.0)
    with pytest.raises(ValueError, match="least-tried"):
        decoding_of({"sample_actions": True, "sample_on_revisit": True})
    assert agent_options("pointnav") == {"decoding": "least-tried"}


def test_default_run_directory_is_task_split_label(pointnav_file, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["run", "--episodes", str(pointnav_file), "--agent", "oracle", "--limit", "1", "--workers", "1",
                 "-q"]) == 0
    stem = pointnav_file.name.split(".")[0]
    assert (tmp_path / "runs" / "pointnav" / stem / "oracle" / "episodes.jsonl").is_file()


def test_run_resolves_the_episode_source_once(objectnav_file, tmp_path, monkeypatch):
    """`navbench run` picks the task's default agent from the resolved episodes and hands them to
    navbench.evaluate, so a user's file (its first episode tells the task) is read for it once."""
    import navbench.api
    import navbench.cli

    calls = []
    resolve = navbench.api.resolve_episodes

    def counted(*args):
        calls.append(args)
        return resolve(*args)

    monkeypatch.setattr(navbench.api, "resolve_episodes", counted)
    monkeypatch.setattr(navbench.cli, "resolve_episodes", counted)
    assert main(["run", "--episodes", str(objectnav_file), "--agent", "oracle", "--limit", "1", "--workers", "1",
                 "--out", str(tmp_path / "run"), "-q"]) == 0
    assert calls == [(None, None, str(objectnav_file))]


def test_every_help_text_renders_its_percent_signs_once():
    # argparse %-formats `help` strings but prints a `description` as written
    parser = build_parser()
    subs = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, sub in subs.choices.items():
        assert "%%" not in sub.format_help(), name


@pytest.mark.parametrize("quiet", [True, False])
def test_quiet_run_silences_the_loops_it_starts(quiet, monkeypatch):
    # -q reaches the memory pre-scans and the workers, which print through navbench.loop_progress
    import navbench.api

    class Seen(Exception):
        pass

    def evaluate(*args, **kwargs):
        raise Seen(os.environ.get("NAVBENCH_PROGRESS"))

    monkeypatch.delenv("NAVBENCH_PROGRESS", raising=False)
    monkeypatch.setattr(navbench.api, "evaluate", evaluate)
    with pytest.raises(Seen) as seen:
        main(["run", "--split", "val_unseen", "--limit", "1", *(["-q"] if quiet else [])])
    assert seen.value.args[0] == ("0" if quiet else None)
    assert "NAVBENCH_PROGRESS" not in os.environ
