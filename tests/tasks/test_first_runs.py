"""What a newcomer meets on a first run of each task: a file is run as its own task (or refused naming it), the
default agent is a non-privileged baseline, privileged agents run under every configuration of their task, a
named configuration says what it changes and fits its own task only, and the listings say all of it."""

import gzip
import json

import numpy as np
import pytest

import navbench
from navbench.agents.registry import AGENTS, check_conditions, check_task, is_privileged
from navbench.api import _task_env, env_config_line, resolve_episodes
from navbench.cli import main
from navbench.env.config import EnvConfig
from navbench.env.make import task_env
from navbench.env.sensors import AGENT_POSE
from navbench.paths import EPISODES_DIR
from navbench.tasks import TASKS, Task

R2R = EPISODES_DIR / "r2r_ce" / "val" / "val.json.gz"
BUNDLED = {"pointnav": EPISODES_DIR / "pointnav" / "val" / "val.json.gz",
           "objectnav": EPISODES_DIR / "objectnav" / "val_unseen" / "val_unseen.json.gz",
           "instance_imagenav": EPISODES_DIR / "instance_imagenav" / "val" / "val.json.gz",
           "goat": EPISODES_DIR / "goat" / "val" / "val.json.gz",
           "r2r_ce": R2R}
# an RxR-CE guide episode, shaped like RxR_VLNCE_v0's (VLN-CE habitat_extensions/task.py RxRVLNCEDatasetV1)
RXR_EP = {"episode_id": "1", "trajectory_id": "7", "scene_id": "mp3d/zsNo4HB9uLZ/zsNo4HB9uLZ.glb",
          "start_position": [-16.27, 0.15, 0.71], "start_rotation": [0, 0.97, 0, -0.24], "info": {"role": "guide"},
          "goals": [{"position": [-9.9, 0.15, 2.6], "radius": 3.0}],
          "reference_path": [[-16.27, 0.15, 0.71], [-9.9, 0.15, 2.6]],
          "instruction": {"instruction_id": "12", "instruction_text": "Turn around and walk to the kitchen.",
                          "language": "en-IN"}}


@pytest.fixture(scope="module")
def rxr_file(tmp_path_factory):
    d = tmp_path_factory.mktemp("RxR_VLNCE_v0") / "val_unseen"
    d.mkdir()
    path = d / "val_unseen_guide.json.gz"
    path.write_bytes(gzip.compress(json.dumps({"episodes": [RXR_EP]}).encode()))
    gt = {"1": {"locations": [[-16.27, 0.15, 0.71], [-9.9, 0.15, 2.6]], "actions": [1, 0], "forward_steps": 1}}
    (d / "val_unseen_guide_gt.json.gz").write_bytes(gzip.compress(json.dumps(gt).encode()))
    return path


# ------------------------------------------------------------------------------- a file is run as its own task
def test_a_vlnce_file_without_task_is_run_as_its_task_not_pointnav(rxr_file):
    assert resolve_episodes(None, None, R2R) == ("r2r_ce", None, R2R, 3.0)
    assert resolve_episodes(None, None, rxr_file)[::3] == ("rxr_ce", 3.0)


def _files(rxr):
    return {**BUNDLED, "rxr_ce": rxr}


@pytest.mark.parametrize("task", list(TASKS))
def test_a_file_under_another_tasks_flag_is_refused_naming_the_task_it_belongs_to(task, rxr_file):
    for belongs, path in _files(rxr_file).items():
        if TASKS[belongs].episode_format == TASKS[task].episode_format:
            assert resolve_episodes(task, None, path)[0] == task  # ImageNav reads PointNav-v1 files
            continue
        with pytest.raises(ValueError, match=rf"looks like an? {TASKS[belongs].display_name} file .*use --task "
                                             rf"{belongs}\b"):
            resolve_episodes(task, None, path)


def test_the_refusal_is_one_line_exit_2(capsys, tmp_path):
    assert main(["run", "--task", "objectnav", "--episodes", str(R2R), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "looks like an R2R-CE file" in err[0] and "use --task r2r_ce" in err[0]
    assert str(R2R) in err[0] and not (tmp_path / "o").exists()


# ------------------------------------------------------------------------- defaults are non-privileged baselines
DEFAULTS = {"pointnav": "pointnav", "objectnav": "memory", "imagenav": "memory", "instance_imagenav": "memory",
            "goat": "memory", "r2r_ce": "vln_memory", "rxr_ce": "vln_memory"}


@pytest.mark.parametrize("task", list(TASKS))
def test_every_default_agent_is_a_non_privileged_baseline_that_runs_under_the_tasks_own_conditions(task):
    name = TASKS[task].default_agent
    assert name == DEFAULTS[task] and not AGENTS[name].privileged
    env = _task_env(task) or EnvConfig()
    check_task(name, task, env)
    check_conditions(name, task, env)


def test_privileged_agents_are_the_oracles_and_run_under_every_configuration_of_their_task():
    assert {n for n, s in AGENTS.items() if s.privileged} == {"oracle", "optimistic", "vln_oracle"}
    for config in ("r2r-ce", "navbench-r2r-ce"):
        for agent in ("oracle", "vln_oracle"):
            check_conditions(agent, "r2r_ce", EnvConfig.load(config))
    check_conditions("oracle", "pointnav", EnvConfig.load("habitat-challenge-pointnav-2021"))
    with pytest.raises(ValueError, match="GPS\\+compass"):  # a non-privileged agent is held to the sensors
        check_conditions("memory", "objectnav", EnvConfig.load("navbench-dead-reckoning"))
    assert is_privileged("oracle") and not is_privileged("memory") and not is_privileged("their.module:Oracle")


def test_the_privileged_pose_is_the_simulators_in_the_frame_gps_compass_would_give(pointnav_file):
    env = task_env("pointnav", pointnav_file, config=EnvConfig(rgb=False, depth=False))
    obs, _ = env.reset(seed=0, options={"episode": 0})
    assert AGENT_POSE not in obs
    env.give_agent_pose()
    for action in (None, 1, 2, 1):
        obs = env.reset(seed=0, options={"episode": 0})[0] if action is None else env.step(action)[0]
        assert obs[AGENT_POSE].dtype == np.float32 and env.observation_space.contains(obs)
        assert np.array_equal(obs[AGENT_POSE], np.concatenate([obs["gps"], obs["compass"]]))
    blind = task_env("pointnav", pointnav_file, config=EnvConfig(rgb=False, depth=False, gps_compass=False))
    blind.give_agent_pose()
    obs, _ = blind.reset(seed=0, options={"episode": 0})
    assert "gps" not in obs and obs[AGENT_POSE].shape == (3,)


def test_the_oracle_without_gps_compass_walks_as_it_does_with_them(pointnav_file, tmp_path):
    """Its pose is the simulator's either way, so its records are the same."""
    runs = {}
    for name, config in (("gps", None), ("blind", "navbench-dead-reckoning")):
        navbench.evaluate("oracle", task="pointnav", episodes=pointnav_file, limit=2, workers=1, env_config=config,
                          out=tmp_path / name)
        runs[name] = [json.loads(line) for line in (tmp_path / name / "episodes.jsonl").read_text().splitlines()]
    assert [r["trace"]["actions"] for r in runs["gps"]] == [r["trace"]["actions"] for r in runs["blind"]]
    assert all(r["success"] == 1.0 for r in runs["blind"])


def test_the_reference_path_oracle_runs_under_r2r_ces_own_configuration(tmp_path):
    s = navbench.evaluate("vln_oracle", episodes=R2R, limit=1, workers=1, out=tmp_path / "o")
    cfg = json.loads((tmp_path / "o" / "config.json").read_text())
    assert s["num_failed"] == 0 and s["success"] == 1.0 and cfg["task"] == "r2r_ce"
    assert cfg["env"]["gps_compass"] is False


# ------------------------------------------------------------------------------------------------ the listings
def test_tasks_lists_each_default_agent_and_no_default_split_where_none_is_bundled(capsys):
    assert main(["tasks"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split()[-2:] == ["default", "agent"]
    for t in TASKS.values():
        line = next(ln for ln in lines if ln.startswith(t.name + " "))
        assert line.split()[-1] == t.default_agent
    rxr = next(ln for ln in lines if ln.startswith("rxr_ce "))
    assert "none: --episodes" in rxr and " val " not in rxr
    with pytest.raises(ValueError, match="bundles no split"):
        Task("x", "navbench/X-v0", "", "", (), default_split="val")


def test_agents_says_what_each_is_and_whether_it_is_privileged(capsys):
    assert main(["agents"]) == 0
    lines = {ln.split()[0]: ln for ln in capsys.readouterr().out.splitlines() if ln.strip()}
    for name, spec in AGENTS.items():
        assert ("non-privileged" not in lines[name]) == spec.privileged and spec.help in lines[name]
    assert "built-in, privileged" in lines["oracle"] and "built-in, non-privileged" in lines["memory"]


# ------------------------------------------------------------------------------------- named configurations
def test_a_named_configuration_says_what_it_changes_from_the_tasks_defaults():
    line = env_config_line("habitat-objectnav-hm3d", "objectnav", 0.25)
    assert line.startswith("--env-config habitat-objectnav-hm3d changes objectnav's defaults: ")
    for part in ("actions +LOOK_UP, +LOOK_DOWN (tilts of 30 deg)", "success 0.25 -> 0.1 m",
                 "camera 224x224 -> 640x480"):
        assert part in line
    assert "max_steps" not in line and "steps" not in line  # 500 in both
    assert env_config_line("navbench-r2r-ce", "r2r_ce", 3.0).endswith(": GPS+compass on")
    assert "unchanged" in env_config_line("r2r-ce", "r2r_ce", 3.0)


def test_run_prints_that_line_once_the_run_starts(objectnav_file, capsys, tmp_path):
    assert main(["run", "--task", "objectnav", "--episodes", str(objectnav_file), "--agent", "oracle", "--limit", "1",
                 "--workers", "1", "--env-config", "habitat-objectnav-hm3d", "--out", str(tmp_path / "o")]) == 0
    err = capsys.readouterr().err
    assert "--env-config habitat-objectnav-hm3d changes objectnav's defaults: actions +LOOK_UP" in err


@pytest.mark.parametrize("task,config", [("pointnav", "goat-bench"), ("r2r_ce", "habitat-objectnav-hm3d"),
                                         ("objectnav", "r2r-ce"), ("goat", "habitat-challenge-pointnav-2021")])
def test_a_configuration_made_for_another_task_is_refused_in_one_line(task, config, capsys, tmp_path):
    assert main(["run", "--task", task, "--env-config", config, "--limit", "1", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{config}.toml: a configuration for " in err[0] and f"not {task}" in err[0]
    assert not (tmp_path / "o").exists()
    with pytest.raises(ValueError, match="a configuration for"):
        navbench.evaluate("random", task=task, env_config=config, limit=1, out=tmp_path / "api")


def test_navbenchs_own_conditions_fit_every_task():
    for task in TASKS:
        env_config_line("navbench-actuation-x0_5", task, TASKS[task].success_distance)
        env_config_line("navbench", task, TASKS[task].success_distance)
