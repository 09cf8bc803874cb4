"""CI smoke on the scan-like HM3D fixture at reduced size: ObjectNav-v1 episodes (split file + content/),
scene_ids under scene_datasets/, a Basis-textured .basis.glb, HM3D semantics, run with the oracle and
the memory agent through the real runner."""

from __future__ import annotations

import pytest

from navbench.bench_scan import make_scan_fixture
from navbench.cli import make_memory, make_oracle, prebuild_memories
from navbench.episodes.io import load_dataset
from navbench.eval.runner import RunConfig, read_records, run
from navbench.paths import POLICIES_DIR
from navbench.scene.cache import load_scene_and_navgrid

CHECKPOINT = POLICIES_DIR / "pointnav_navbench.pth"


@pytest.fixture(scope="module")
def scan(tmp_path_factory):
    try:
        import alktx2  # noqa: F401
        basis = True
    except ImportError:
        basis = False
    return make_scan_fixture(tmp_path_factory.mktemp("scan"), faces=30_000, texture_size=512, basis=basis,
                             episodes=2)


def _cfg(scan, agent, **kw):
    base = dict(task="objectnav", split=None, agent=agent, episodes=str(scan.episodes),
                scene_dir=str(scan.scene_datasets), success_distance=0.1, limit=2)
    base.update(kw)
    return RunConfig(**base)


def test_fixture_is_in_hm3d_layout(scan):
    ds = load_dataset(scan.episodes)  # episodes live in content/{scene}.json.gz
    assert len(ds.episodes) == 2 and all(e.scene_id == scan.scene_id for e in ds.episodes)
    assert scan.scene_id.startswith("hm3d/val/00999-nbScanHouse/nbScanHouse.")
    asset, grid = load_scene_and_navgrid(scan.scene_datasets / scan.scene_id)
    assert asset.is_textured and asset.textures[0].shape[:2] == (512, 512)
    cats = set(asset.categories)
    assert {"chair", "bed", "tv_monitor", "plant", "sofa", "toilet"} <= cats  # mapped from raw names ("tv", ...)
    assert not {"wall", "floor", "ceiling"} & cats
    assert all(o.room.startswith("region_") for o in asset.objects.values())
    assert abs(grid.floor_height) < 0.05  # the ground storey of the two


def test_oracle_reaches_its_goals_on_the_scan(scan, tmp_path):
    summary = run(_cfg(scan, "oracle"), make_oracle, tmp_path / "run")
    recs = read_records(tmp_path / "run" / "episodes.jsonl")
    assert summary["num_episodes"] == 2 and summary["success"] == 1.0
    assert all(r["stop_called"] and r["distance_to_goal"] < 0.1 for r in recs)


@pytest.mark.slow  # the pre-scan of both storeys takes about a minute on 2 cores
@pytest.mark.skipif(not CHECKPOINT.is_file(), reason="no shipped PointNav checkpoint")
def test_memory_agent_runs_on_the_scan(scan, tmp_path):
    cfg = _cfg(scan, "memory", limit=1, env={"max_steps": 60},
               agent_options={"memory_root": str(tmp_path / "memory"), "checkpoint": str(CHECKPOINT)})
    prebuild_memories(cfg)
    summary = run(cfg, make_memory, tmp_path / "run")
    (rec,) = read_records(tmp_path / "run" / "episodes.jsonl")
    assert summary["num_episodes"] == 1 and rec["num_steps"] <= 60
    assert rec["log"]["candidates"], "the oracle localiser must find the goal category in the scan's memory"
