"""Pre-scan trajectory, memory building and the memory cache, on the smallest bundled val house."""

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from navbench.memory import KeyframeStore, select_keyframes
from navbench.memory.prescan import (
    MEMORY_FILE,
    Memory,
    PrescanConfig,
    PrescanError,
    build_memory,
    encoder_placement,
    load_or_build_memory,
    plan_trajectory,
)
from navbench.paths import SCENES_DIR
from navbench.scene.asset import load_scene
from navbench.scene.cache import load_scene_and_navgrid, navgrid_for
from navbench.scene.pose import yaw_from_quat

sys.path.insert(0, str(Path(__file__).parents[1] / "scene"))
from storeys import UPPER, furnished, furnished_mp3d  # noqa: E402

SCENE = SCENES_DIR / "houses" / "val" / "house_011.glb"
# Small and fast: a 64 x 48 camera, every frame rendered would still be cheap.
SMALL = PrescanConfig(width=64, height=48, viewpoint_spacing=0.0)


class MeanColourEncoder:
    """A stand-in encoder: mean RGB (+1 so it is never zero)."""

    name = "mean-colour"
    modality = "rgb"

    def encode_images(self, images):
        return np.stack([im.reshape(-1, 3).mean(axis=0) + 1.0 for im in images]).astype(np.float32)


@pytest.fixture(scope="module")
def scene():
    return load_scene_and_navgrid(SCENE)


def test_trajectory_visits_every_room_and_keyframes_thin_it(scene):
    asset, grid = scene
    traj = plan_trajectory(asset, grid, SMALL)
    assert traj.rooms_missed == []
    assert {r for r, _ in traj.viewpoints} == {r.name for r in asset.rooms}
    for room_name, p in traj.viewpoints:  # every look-around happens inside its room
        room = next(r for r in asset.rooms if r.name == room_name)
        assert room.aabb_min[0] < p[0] < room.aabb_max[0] and room.aabb_min[2] < p[2] < room.aabb_max[2]
        assert grid.is_navigable(p)
    assert np.allclose(traj.positions[:, 1], grid.floor_height + 0.88)
    # Consecutive frames are a hand-held video: at most a third of a step or turn apart.
    steps = np.linalg.norm(np.diff(traj.positions, axis=0), axis=1)
    yaws = np.array([yaw_from_quat(q) for q in traj.rotations])
    turns = np.abs((np.diff(yaws) + np.pi) % (2 * np.pi) - np.pi)
    assert steps.max() <= 0.25 / 3 + 1e-6 and np.degrees(turns.max()) <= 10.0 + 1e-6
    keep = select_keyframes(traj.poses())
    assert keep[0] == 0 and len(keep) < 0.6 * len(traj)
    # Smaller thresholds keep more.
    assert len(select_keyframes(traj.poses(), 0.1, 5.0)) > len(keep)


def test_trajectory_spacing_adds_viewpoints_in_large_rooms(scene):
    asset, grid = scene
    one = plan_trajectory(asset, grid, SMALL)
    several = plan_trajectory(asset, grid, PrescanConfig(width=64, height=48, viewpoint_spacing=3.0))
    assert len(several.viewpoints) > len(one.viewpoints) and several.rooms_missed == []


def test_build_memory_writes_store_index_and_stats(tmp_path):
    stats = build_memory(SCENE, tmp_path / "m", SMALL, MeanColourEncoder())
    memory = Memory.open(tmp_path / "m")
    assert stats.keyframes == len(memory.store) == len(memory.index) < stats.frames
    assert stats.bytes == sum(p.stat().st_size for p in (tmp_path / "m").rglob("*") if p.is_file())
    assert set(stats.rooms_visited) == {"living_room", "kitchen", "bathroom"} and stats.rooms_missed == ()
    assert memory.index.model == "mean-colour" and memory.info["encoder"] == "mean-colour"
    # Keyframe records keep their index in the full trajectory, and poses are the camera's.
    store = KeyframeStore.open(tmp_path / "m")
    assert store.stats.frames == stats.frames
    idx = [r.frame_index for r in store.records]
    assert idx == sorted(idx) and idx[-1] < stats.frames and idx[0] == 0
    assert store.depth(0).shape == (48, 64) and store.instance_ids(0).shape == (48, 64)
    assert np.allclose(store.positions()[:, 1], 0.88)
    # Images come from the poses they are stored with: keyframes 0 and 1 differ.
    assert not np.array_equal(store.depth(0), store.depth(1))


def test_memory_cache_reuse_and_invalidation(tmp_path):
    scene_dir = tmp_path / "scenes"
    scene_dir.mkdir()
    scene = scene_dir / SCENE.name
    shutil.copy(SCENE, scene)
    shutil.copy(SCENE.with_name("house_011.semantic.json"), scene_dir / "house_011.semantic.json")
    cache = tmp_path / "cache"
    enc = MeanColourEncoder()

    first = load_or_build_memory(scene, cache, SMALL, enc)
    assert first.built_now
    stamp = (first.directory / MEMORY_FILE).stat().st_mtime_ns
    again = load_or_build_memory(scene, cache, SMALL, enc)
    assert not again.built_now and again.directory == first.directory
    assert (first.directory / MEMORY_FILE).stat().st_mtime_ns == stamp
    assert len(again.store) == len(first.store)

    # A changed config is another memory (the first one stays reusable).
    other = load_or_build_memory(scene, cache, PrescanConfig(width=64, height=48, viewpoint_spacing=0.0,
                                                             store_resolution=(32, 24)), enc)
    assert other.built_now and other.directory != first.directory and other.store.depth(0).shape == (24, 32)
    assert not load_or_build_memory(scene, cache, SMALL, enc).built_now

    # Another encoder too.
    class Other(MeanColourEncoder):
        name = "other"

    assert load_or_build_memory(scene, cache, SMALL, Other()).built_now

    # The same encoder computing in bfloat16 (or on a GPU) is another memory: its embeddings round differently.
    import torch

    class Half(MeanColourEncoder):
        device, dtype = torch.device("cpu"), torch.bfloat16

    assert encoder_placement(enc) is None and encoder_placement(Half()) == "cpu bfloat16"
    half = load_or_build_memory(scene, cache, SMALL, Half())
    assert half.built_now and half.directory != first.directory and half.info["placement"] == "cpu bfloat16"
    assert not load_or_build_memory(scene, cache, SMALL, enc).built_now  # the CPU float32 one stays
    assert "placement" not in load_or_build_memory(scene, cache, SMALL, enc).info

    # Editing the scene file (same path, new sha1) rebuilds in place.
    with open(scene, "ab") as f:
        f.write(b"\0\0\0\0")  # trailing bytes after the GLB chunks: same geometry, new digest
    rebuilt = load_or_build_memory(scene, cache, SMALL, enc)
    assert rebuilt.built_now and rebuilt.directory == first.directory
    assert rebuilt.info["scene_digest"] != first.info["scene_digest"]

    # A damaged memory.json is rebuilt, not trusted.
    (first.directory / MEMORY_FILE).write_text("{not json")
    assert load_or_build_memory(scene, cache, SMALL, enc).built_now
    assert json.loads((first.directory / MEMORY_FILE).read_text())["encoder"] == "mean-colour"


def test_errors_name_the_problem(tmp_path):
    with pytest.raises(PrescanError, match="no memory at"):
        Memory.open(tmp_path)
    with pytest.raises(PrescanError, match="store_resolution"):
        PrescanConfig(store_resolution=(0, 10))


# Two storeys nothing joins, whose room boxes start at the underside of a 0.3 m floor slab (deeper than the
# 0.2 m climb), as boxes built from a room's faces do: the upper storey's floor is found within its rooms'
# height range, so the scan covers it, never a surface on the ground floor under the upper rooms' box bottoms.
@pytest.mark.parametrize("annotations", ["sidecar", "mp3d"])
def test_scan_covers_a_storey_whose_room_boxes_start_below_its_floor(tmp_path, annotations):
    path = (furnished(None, tmp_path, slab=0.3, rooms_from_slab=True) if annotations == "sidecar"
            else furnished_mp3d(tmp_path, slab=0.3))
    asset = load_scene(path)
    assert all(r.aabb_min[1] < f - 0.25 for r, f in zip(sorted(asset.rooms, key=lambda r: r.aabb_min[1]),
                                                         (0.0, UPPER)))
    for start in (0.0, UPPER):
        grid = navgrid_for(asset, floor_hint=start, use_cache=False)
        assert grid.floor_height == pytest.approx(start, abs=0.01)
        config = PrescanConfig()
        floors = plan_trajectory(asset, grid, config).positions[:, 1] - config.camera_height
        on = {y: int((np.abs(floors - y) < 0.01).sum()) for y in (0.0, UPPER)}
        assert on[0.0] > 20 and on[UPPER] > 20, on
        assert np.all((np.abs(floors) < 0.01) | (np.abs(floors - UPPER) < 0.01))  # never on a table top
