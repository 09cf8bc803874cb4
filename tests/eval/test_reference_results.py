"""The committed reference runs: named and recorded as `navbench run` would today, and (slow, `make
test-slow`) reproduced by their own config.json as navbench.eval.reproduce defines it: outcomes, steps and
actions exactly; float metrics exactly on the recording machine's CPU class, within FLOAT_TOLERANCE on another."""

import hashlib
import json
from pathlib import Path

import pytest

from navbench.agents.registry import AGENTS, agent_options, run_label
from navbench.episodes.benchmark import HOUSE_SEED_BASE, per_scene_counts, split_rng
from navbench.episodes.generate import SceneGoals, objectnav_split
from navbench.episodes.io import file_split, save_dataset
from navbench.episodes.split_vocabulary import UNSEEN_CATEGORIES
from navbench.eval.reproduce import FLOAT_TOLERANCE, record_differences, same_cpu_class
from navbench.eval.runner import RunConfig, read_records, run
from navbench.paths import RESULTS_DIR, SCENES_DIR, split_file
from navbench.scene.procedural import generate_house
from navbench.scene.procedural.dataset import write_house

RUNS = RESULTS_DIR / "runs"
CHOICES = ("perception", "noise", "fusion", "rerank", "keyframe_res", "all_frames", "goal_tracking", "visibility_stop",
           "instruction", "look_round")


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
        split = cfg["split"] or file_split(cfg["episodes"])  # a bundled split, or the generated benchmark's file
        # a run under a named env configuration carries its name (navbench.evaluate's label)
        label = run_label(cfg["agent"], o, cfg["seed"]) + (f"-{cfg['env_config_name']}" if cfg.get("env_config_name")
                                                           else "")
        assert d.relative_to(RUNS).parts == (cfg["task"], split, label), d
        assert cfg["label"] == d.name and json.loads((d / "summary.json").read_text())["agent"] == d.name, d
        if cfg["split"] is None:  # a generated benchmark's run: its files named relative to it, with checksums
            files = json.loads((d / "provenance.json").read_text())["files"]
            assert files["episodes"]["root"] == files["scene_dir"]["root"] == "benchmark", d
            assert (files["episodes"]["path"], files["scene_dir"]["path"]) == (cfg["episodes"], cfg["scene_dir"]), d
            assert files["episodes"]["sha256"] == cfg["benchmark"]["episodes_sha256"], d


def ref_config(ref_dir: Path) -> RunConfig:
    cfg = json.loads((ref_dir / "config.json").read_text())
    return RunConfig(**{k: v for k, v in cfg.items() if k in RunConfig.__dataclass_fields__})


def assert_reproduces(cfg: RunConfig, ref_dir: Path, out: Path, n: int = 8) -> None:
    """Run the first ``n`` episodes of ``cfg`` in this process (the default execution: one worker) and
    compare each record with the committed one (floats exactly on the recording CPU class)."""
    cfg.limit = n
    run(cfg, AGENTS[cfg.agent], out)
    key = lambda r: (r["scene_id"], r["episode_id"])  # noqa: E731  (GOAT-Bench numbers episodes per file)
    ref = {key(r): r for r in read_records(ref_dir / "episodes.jsonl")}
    got = read_records(out / "episodes.jsonl")
    assert len(got) == n
    exact = same_cpu_class(ref_dir)
    diffs = {key(r): d for r in got if (d := record_differences(r, ref[key(r)], exact))}
    assert not diffs, f"floats compared {'exactly' if exact else f'to {FLOAT_TOLERANCE}'}: {diffs}"


@pytest.mark.slow
@pytest.mark.parametrize("name", ["pointnav/val/pointnav", "pointnav/val/pointnav-argmax",
                                  "pointnav/val/pointnav-pointnav_2h", "pointnav/val/pointnav-pointnav_v2",
                                  "pointnav/val/optimistic", "objectnav/val_unseen/memory-pointnav_v2",
                                  "objectnav/val_unseen/oracle", "objectnav/val_unseen/memory",
                                  "objectnav/val_unseen/memory-least-tried", "objectnav/val_unseen/frontier",
                                  "imagenav/val/oracle", "imagenav/val/memory", "imagenav/val/memory-nolookround",
                                  "instance_imagenav/val/oracle",
                                  "instance_imagenav/val/memory", "instance_imagenav/val/frontier", "goat/val/oracle",
                                  "goat/val/memory", "goat/val/frontier"])
def test_reference_run_reproduces_first_episodes(name, tmp_path, monkeypatch):
    monkeypatch.chdir(RESULTS_DIR.parent)  # a --checkpoint in a run's config is relative to the project root
    cfg = ref_config(RUNS / name)
    # bundled data is read from this checkout (config.json holds the writer's absolute paths)
    cfg.episodes, cfg.scene_dir = str(split_file(cfg.task, cfg.split)), str(SCENES_DIR)
    assert_reproduces(cfg, RUNS / name, tmp_path / "run")


@pytest.mark.slow
@pytest.mark.parametrize("agent", ["memory", "frontier"])
def test_benchmark_reference_run_reproduces_its_first_house(agent, tmp_path):
    """The generated benchmark (`navbench generate benchmark --houses 36 --episodes-per-split 3000`) is not
    bundled: its first house and that house's val_unseen episodes are redrawn alone (the split draws house
    after house), the house checked byte for byte against the run's provenance, and 8 episodes rerun."""
    ref_dir = RUNS / "objectnav" / "val_unseen_h36" / agent
    scenes = tmp_path / "scenes"
    glb = write_house(*generate_house(HOUSE_SEED_BASE * 1000), scenes / "val", "house_000")
    recorded = json.loads((ref_dir / "provenance.json").read_text())["files"]["scenes"]["val/house_000.glb"]
    assert hashlib.sha256(glb.read_bytes()).hexdigest() == recorded["sha256"]
    ds = objectnav_split([(SceneGoals(glb, scenes), per_scene_counts(3000, 36)[0])], UNSEEN_CATEGORIES, False,
                         split_rng(0, "val_unseen"), "val_unseen", "house_000")
    save_dataset(ds, tmp_path / "val_unseen_h36.json.gz")
    cfg = ref_config(ref_dir)
    cfg.episodes, cfg.scene_dir = str(tmp_path / "val_unseen_h36.json.gz"), str(scenes)
    assert_reproduces(cfg, ref_dir, tmp_path / "run")
