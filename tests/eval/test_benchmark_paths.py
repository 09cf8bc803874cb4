"""A run of a generated benchmark (a directory holding benchmark.json) records its episode file and scene dir
relative to that directory, with the checksums that identify them; resume, merge, table and compare read them."""

from __future__ import annotations

import hashlib
import json
import shutil

import pytest

from navbench.agents.registry import make_oracle
from navbench.eval.config import recorded_paths
from navbench.eval.merge import merge
from navbench.eval.rundir import RunError
from navbench.eval.runner import RunConfig, read_records, run
from navbench.eval.stats import compare_runs, first_per_scene
from navbench.eval.table import first_records
from navbench.paths import SCENES_DIR
from navbench.viz.replay import Run


@pytest.fixture()
def bench(objectnav_file, tmp_path, monkeypatch):
    """A benchmark-shaped directory (benchmark.json, SHA256SUMS, objectnav/, scenes/) in the working dir, which
    stands for a checkout (make results-benchmark writes it to runs/benchmark_h36)."""
    root = tmp_path / "work" / "bench"
    (root / "objectnav").mkdir(parents=True)
    shutil.copy(objectnav_file, root / "objectnav" / "val_unseen_h1.json.gz")
    shutil.copytree(SCENES_DIR / "houses" / "val", root / "scenes" / "houses" / "val",
                    ignore=lambda d, names: [n for n in names if not n.startswith("house_008.")])
    (root / "benchmark.json").write_text("{}\n")
    files = sorted(p for p in root.rglob("*") if p.is_file())
    (root / "SHA256SUMS").write_text("".join(f"{hashlib.sha256(p.read_bytes()).hexdigest()}  "
                                             f"{p.relative_to(root).as_posix()}\n" for p in files))
    monkeypatch.chdir(tmp_path / "work")
    monkeypatch.setattr("navbench.eval.provenance.ROOT", tmp_path / "work")  # as `runs/` of a checkout is
    return root


def _cfg(**kw) -> RunConfig:
    return RunConfig(task="objectnav", split=None, agent="oracle", episodes="bench/objectnav/val_unseen_h1.json.gz",
                     scene_dir="bench/scenes", success_distance=0.1, **kw)


def test_benchmark_run_records_paths_relative_to_the_benchmark_with_checksums(bench, tmp_path):
    run(_cfg(limit=2), make_oracle, tmp_path / "run")
    cfg = json.loads((tmp_path / "run" / "config.json").read_text())
    sha = hashlib.sha256((bench / "objectnav" / "val_unseen_h1.json.gz").read_bytes()).hexdigest()
    assert (cfg["episodes"], cfg["scene_dir"], cfg["benchmark_dir"]) == ("objectnav/val_unseen_h1.json.gz", "scenes",
                                                                         "bench")
    assert cfg["benchmark"] == {"episodes_sha256": sha}
    files = json.loads((tmp_path / "run" / "provenance.json").read_text())["files"]
    assert files["episodes"] == {"path": "objectnav/val_unseen_h1.json.gz", "root": "benchmark", "sha256": sha,
                                 "split_sha256": sha}
    assert files["scene_dir"] == {"path": "scenes", "root": "benchmark"}
    assert files["benchmark"] == {"sha256sums": hashlib.sha256((bench / "SHA256SUMS").read_bytes()).hexdigest()}
    assert str(tmp_path) not in (tmp_path / "run" / "config.json").read_text() + json.dumps(files)

    # resumed (from the benchmark's own directory too), table --first, compare --per-scene, replay
    run(_cfg(limit=3), make_oracle, tmp_path / "run", resume=True)
    assert len(read_records(tmp_path / "run" / "episodes.jsonl")) == 3
    assert len(first_records(tmp_path / "run", 2)) == 2 and len(first_per_scene(tmp_path / "run", 1)) == 1
    assert recorded_paths(cfg) == ("bench/objectnav/val_unseen_h1.json.gz", "bench/scenes")
    assert Run.load(tmp_path / "run").cfg.scene_dir == "bench/scenes"
    assert compare_runs(tmp_path / "run", [tmp_path / "run"], per_scene=2)[0]["episodes"] == 2

    # the same benchmark elsewhere: read from its directory; the config is the same, so it resumes
    shutil.move(bench, tmp_path / "moved")
    with pytest.raises(RunError, match="run from the benchmark's directory"):
        recorded_paths(cfg)
    with pytest.raises(ValueError):
        first_per_scene(tmp_path / "run", 1)
    moved = RunConfig(**{**vars(_cfg(limit=4)), "episodes": str(tmp_path / "moved/objectnav/val_unseen_h1.json.gz"),
                         "scene_dir": str(tmp_path / "moved/scenes")})
    run(moved, make_oracle, tmp_path / "run", resume=True)
    after = json.loads((tmp_path / "run" / "config.json").read_text())
    assert "benchmark_dir" not in after and after["episodes"] == cfg["episodes"]
    assert str(tmp_path) not in json.dumps(after)


def test_shards_of_a_benchmark_run_merge(bench, tmp_path):
    for s in ("1/2", "2/2"):
        run(_cfg(limit=2, shard=s), make_oracle, tmp_path / s.replace("/", "of"))
    summary = merge([tmp_path / "1of2", tmp_path / "2of2"], tmp_path / "merged", note=lambda m: None)
    assert summary["num_episodes"] == 2
    merged = json.loads((tmp_path / "merged" / "config.json").read_text())
    assert merged["episodes"] == "objectnav/val_unseen_h1.json.gz" and "shard" not in merged
