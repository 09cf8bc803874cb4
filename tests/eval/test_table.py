"""Tables carry each run's identity (checkpoint, decoding, seed, perception) as columns, read from config.json."""

import json

import pytest

from navbench.eval.table import TableError, render, run_identity, runs_frame


def _run(root, name, agent, split, options, seed=0, sr=0.5, label=None):
    d = root / name
    d.mkdir(parents=True)
    (d / "config.json").write_text(json.dumps({"task": "objectnav", "split": split, "agent": agent, "seed": seed,
                                               "agent_options": options}))
    (d / "summary.json").write_text(json.dumps({"agent": label or name, "task": "objectnav", "split": split,
                                                "num_episodes": 4, "success": sr, "spl": sr / 2,
                                                "soft_spl": sr / 2, "distance_to_goal": 1.0}))
    return d


def test_identity_of_policy_perception_and_privileged_agents(tmp_path):
    pn = _run(tmp_path, "pn", "pointnav", "val", {"checkpoint": "policies/pointnav_2h.pth", "decoding": "least-tried"},
              seed=3)
    assert run_identity(pn) == {"checkpoint": "pointnav_2h", "decoding": "least-tried", "seed": 3, "perception": "-"}
    mem = _run(tmp_path, "mem", "memory", "val", {"decoding": "argmax", "perception": "oracle", "noise": "default"})
    assert run_identity(mem) == {"checkpoint": "pointnav_navbench", "decoding": "argmax", "seed": 0,
                                 "perception": "oracle, noise default"}
    samp = _run(tmp_path, "s", "pointnav", "val", {"decoding": "sample", "temperature": 0.5})
    assert run_identity(samp)["decoding"] == "sample T=0.5"
    orc = _run(tmp_path, "orc", "oracle", "val", {})
    assert run_identity(orc) == {"checkpoint": "-", "decoding": "-", "seed": 0, "perception": "-"}


def test_wide_table_keeps_identity_columns_and_one_row_per_agent(tmp_path):
    runs = [_run(tmp_path, f"{a}_{s}", a, s, {"decoding": "argmax", "perception": "oracle"}, sr=0.25 * (i + 1),
                 label=a)
            for i, a in enumerate(("memory", "frontier")) for s in ("val_seen", "val_unseen")]
    text = render(runs_frame(runs))
    header = text.splitlines()[0]
    for col in ("agent", "checkpoint", "decoding", "seed", "perception", "val_seen SR", "val_unseen SPL"):
        assert col in header
    assert len(text.splitlines()) == 4  # header, rule, one row per agent
    assert render(runs_frame(runs), "csv").splitlines()[0].startswith("agent,checkpoint,decoding,seed,perception")


def test_a_user_files_runs_are_tabulated_under_the_files_name(tmp_path):
    # as `navbench run --episodes DIR/val_unseen_h36.json.gz` files them: runs/objectnav/val_unseen_h36/
    runs = []
    for a in ("memory", "frontier"):
        d = _run(tmp_path, a, a, None, {"decoding": "argmax", "perception": "oracle"})
        cfg = json.loads((d / "config.json").read_text())
        (d / "config.json").write_text(json.dumps({**cfg, "episodes": "/data/bench/objectnav/val_unseen_h36.json.gz"}))
        runs.append(d)
    assert list(runs_frame(runs, wide=False)["split"]) == ["val_unseen_h36"] * 2
    bundled = _run(tmp_path, "bundled", "memory", "val_unseen", {"decoding": "argmax", "perception": "oracle"})
    assert "val_unseen_h36 SR" in render(runs_frame([*runs, bundled])).splitlines()[0]


def test_missing_config_is_a_one_line_error(tmp_path):
    d = _run(tmp_path, "x", "oracle", "val", {})
    (d / "config.json").unlink()
    with pytest.raises(TableError, match="no config.json"):
        runs_frame([d])


def test_the_table_a_run_prints_says_what_its_agent_perceives_with(tmp_path):
    """After a run: a line under the table with the agent's checkpoint, decoding and perception, the perception
    in words (oracle ground truth or models); none for an agent without them."""
    from navbench.eval.table import load_summary, summary_markdown

    mem = _run(tmp_path, "mem", "memory", "val_unseen", {"decoding": "argmax", "perception": "oracle"})
    text = summary_markdown(load_summary(mem), mem)
    assert text.splitlines()[-1] == ("*agent mem: checkpoint pointnav_navbench, decoding argmax, perception oracle "
                                     "(the simulator's ground-truth object labels, not a model)*")
    model = _run(tmp_path, "fr", "frontier", "val_unseen",
                 {"decoding": "argmax", "perception": "siglip2+qwen2.5-vl+sam3", "noise": "none"})
    assert "perception siglip2+qwen2.5-vl+sam3 (objects detected in RGB by these models)" in \
        summary_markdown(load_summary(model), model)
    orc = _run(tmp_path, "orc", "oracle", "val_unseen", {})
    assert "agent" not in summary_markdown(load_summary(orc), orc).splitlines()[-1]


def test_the_table_a_goat_run_prints_is_in_goat_bench_measures():
    from navbench.eval.table import load_summary, summary_markdown
    from navbench.paths import RESULTS_DIR

    run = RESULTS_DIR / "runs" / "goat" / "val" / "memory"
    text = summary_markdown(load_summary(run), run)
    head = [h.strip() for h in text.splitlines()[0].strip("|").split("|")]
    assert head[-9:] == ["object SR", "object SPL", "description SR", "description SPL", "image SR", "image SPL",
                         "partial SR", "composite SR", "composite SPL"]
    assert "perception oracle" in text and "goat-bench's partial_success" in text
