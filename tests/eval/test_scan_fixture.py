"""CI smoke on the scan-like HM3D fixture at reduced size: ObjectNav-v1 episodes (split file + content/),
scene_ids under scene_datasets/, a Basis-textured .basis.glb, HM3D semantics, run with the oracle and
the memory agent through the real runner."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from navbench.agents.registry import make_memory, make_oracle, prebuild_memories
from navbench.bench.scan import agent_walk
from navbench.bench.scan_fixture import make_scan_fixture
from navbench.env.config import EnvConfig
from navbench.env.pointnav import PointNavEnv
from navbench.episodes.io import load_dataset
from navbench.episodes.types import Episode, EpisodeDataset, NavigationGoal
from navbench.eval.runner import RunConfig, read_records, run, select_episodes
from navbench.paths import POLICIES_DIR
from navbench.render import Renderer
from navbench.scene.cache import load_scene_and_navgrid
from navbench.scene.navigability import NavGrid, NavGridConfig

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
    prebuild_memories(cfg, select_episodes(load_dataset(cfg.episodes), cfg.limit))
    summary = run(cfg, make_memory, tmp_path / "run")
    (rec,) = read_records(tmp_path / "run" / "episodes.jsonl")
    assert summary["num_episodes"] == 1 and rec["num_steps"] <= 60
    assert rec["log"]["candidates"], "the oracle localiser must find the goal category in the scan's memory"


def test_occlusion_culling_changes_no_pixel_along_a_walk(scan):
    """Visibility sets skip chunks behind walls; every frame of a walk must equal the unculled one."""
    asset, grid = load_scene_and_navgrid(scan.scene_datasets / scan.scene_id)
    poses = agent_walk(grid, 60, seed=3)
    with Renderer(asset, occlusion_culling=True, max_chunk_faces=2_000) as culled, \
            Renderer(asset, occlusion_culling=False, max_chunk_faces=2_000) as full:
        assert culled.num_chunks >= 12
        skipped = 0
        for p, q in poses:
            a = culled.render(p, q, ids=True)
            b = full.render(p, q, ids=True)
            assert np.array_equal(a.rgb, b.rgb) and np.array_equal(a.ids, b.ids)
            np.testing.assert_array_equal(a.depth, b.depth)
            skipped += int((~culled.visible_chunks(p, q) & full.visible_chunks(p, q)).sum())
    assert skipped > 0  # the walls did hide something


def test_episode_on_the_upper_storey_uses_that_floor(scan):
    """A start on the upper storey gets the upper floor's grid (the default grid is the ground floor)."""
    mesh = scan.scene_datasets / scan.scene_id
    asset, ground = load_scene_and_navgrid(mesh)
    upper_y = NavGrid.floor_for(asset.mesh, ground.floor_height + 2.8)
    assert upper_y > ground.floor_height + 2.0
    upper = NavGrid.from_mesh(asset.mesh, dataclasses.replace(NavGridConfig(), floor_height=upper_y))
    rng = np.random.default_rng(0)
    s, g = upper.sample_navigable_point(rng), upper.sample_navigable_point(rng)
    ep = Episode("up", scan.scene_id, [float(v) for v in s], [0.0, 0.0, 0.0, 1.0],
                 goals=[NavigationGoal([float(v) for v in g])])
    env = PointNavEnv(EpisodeDataset(episodes=[ep]), scene_dir=scan.scene_datasets,
                      config=EnvConfig(rgb=False, depth=True))
    try:
        env.reset(options={"episode": 0})
        assert abs(env.navgrid.floor_height - upper_y) < 0.05
        assert env.agent_position[1] == env.navgrid.floor_height
        assert np.isfinite(env.distance_to_goal()) or not upper.same_island(s, g)
    finally:
        env.close()
