"""The committed reference runs: named and recorded as `navbench run` would today, and (slow, `make
test-slow`) reproduced to the last digit by their own config.json."""

import json
from pathlib import Path

import pytest

from navbench.agents.registry import AGENTS, agent_options, run_label
from navbench.eval.runner import RunConfig, read_records, run
from navbench.paths import RESULTS_DIR, SCENES_DIR, split_file

RUNS = RESULTS_DIR / "runs"
CHOICES = ("perception", "noise", "fusion", "rerank", "keyframe_res", "all_frames", "goal_tracking", "visibility_stop")


def reference_runs() -> list[Path]:
    return sorted(p.parent for p in RUNS.glob("*/*/*/config.json"))


def test_every_reference_run_is_named_and_recorded_as_the_cli_would():
    runs = reference_runs()
    assert len(runs) >= 30
    for d in runs:
        cfg = json.loads((d / "config.json").read_text())
        o = cfg["agent_options"]
        expected = agent_options(cfg["agent"], checkpoint=o.get("checkpoint"), decoding=o.get("decoding"),
                                 temperature=o.get("temperature"), models=o.get("models"),
                                 **{k: o[k] for k in CHOICES if k in o})
        assert o == expected, d
        assert d.relative_to(RUNS).parts == (cfg["task"], cfg["split"], run_label(cfg["agent"], o, cfg["seed"])), d
        assert cfg["label"] == d.name and json.loads((d / "summary.json").read_text())["agent"] == d.name, d


@pytest.mark.slow
@pytest.mark.parametrize("name", ["pointnav/val/pointnav", "pointnav/val/pointnav-argmax",
                                  "pointnav/val/pointnav-pointnav_2h", "pointnav/val/optimistic",
                                  "objectnav/val_unseen/oracle", "objectnav/val_unseen/memory",
                                  "objectnav/val_unseen/memory-least-tried", "objectnav/val_unseen/frontier"])
def test_reference_run_reproduces_first_episodes(name, tmp_path, monkeypatch):
    monkeypatch.chdir(RESULTS_DIR.parent)  # a --checkpoint in a run's config is relative to the project root
    ref_dir = RUNS / name
    cfg = RunConfig(**{k: v for k, v in json.loads((ref_dir / "config.json").read_text()).items()
                       if k in RunConfig.__dataclass_fields__})
    cfg.limit = 8  # run in this process (the default execution: one worker)
    # bundled data is read from this checkout (config.json holds the writer's absolute paths)
    cfg.episodes, cfg.scene_dir = str(split_file(cfg.task, cfg.split)), str(SCENES_DIR)
    run(cfg, AGENTS[cfg.agent], tmp_path / "run")
    ref = {r["episode_id"]: r for r in read_records(ref_dir / "episodes.jsonl")}
    got = read_records(tmp_path / "run" / "episodes.jsonl")
    assert len(got) == 8
    for r in got:
        for k in ("success", "spl", "soft_spl", "distance_to_goal", "num_steps", "path_length"):
            assert r[k] == ref[r["episode_id"]][k], (r["episode_id"], k)
