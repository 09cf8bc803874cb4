import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from navbench.memory import Frame, Intrinsics, KeyframeStore, StoreConfig, StoreError

W, H = 320, 240


def make_frame(i: int, rng: np.random.Generator, with_ids: bool = True) -> Frame:
    yy, xx = np.mgrid[0:H, 0:W]
    rgb = np.stack([(xx + 7 * i) % 256, (yy * 2) % 256, np.full_like(xx, 40 * i % 256)], axis=2).astype(np.uint8)
    depth = rng.uniform(0.3, 12.0, size=(H, W)).astype(np.float32)
    depth[:5, :5] = 0.0  # no hit
    ids = rng.integers(-1, 60, size=(H, W)) if with_ids else None
    rotation = Rotation.from_euler("y", 40 * i, degrees=True).as_quat()
    return Frame(rgb, depth, np.array([0.3 * i, 0.88, -0.1 * i]), rotation, Intrinsics.from_hfov(W, H, 79.0), ids)


def test_round_trip_png_exact_rgb_mm_depth_ids_and_poses(tmp_path):
    rng = np.random.default_rng(0)
    frames = [make_frame(i, rng) for i in range(3)]
    cfg = StoreConfig(rgb_format="png", keyframes=False, keep_instance_ids=True)
    written = KeyframeStore.write(tmp_path / "kf", frames, scene_id="house_001", config=cfg,
                                  metadata={"trajectory": "t"})
    store = KeyframeStore.open(tmp_path / "kf")
    assert len(store) == 3 and store.scene_id == "house_001" and store.metadata == {"trajectory": "t"}
    assert store.config == cfg and store.stats == written.stats
    for i, f in enumerate(frames):
        assert np.array_equal(store.rgb(i), f.rgb)
        depth = store.depth(i)
        assert depth.dtype == np.float32 and depth.shape == (H, W)
        assert np.abs(depth - f.depth).max() <= 0.0005 + 1e-6  # millimetre rounding
        assert depth[0, 0] == 0.0
        assert np.array_equal(store.instance_ids(i), f.instance_ids)
        assert np.allclose(store.pose(i)[:3, 3], f.position)
        assert np.allclose(store.pose(i)[:3, :3], Rotation.from_quat(f.rotation).as_matrix())
        assert np.allclose(store.pose(i)[3], [0, 0, 0, 1])
        assert np.allclose(store.K(i), f.intrinsics.K)
    # camera-to-world puts the camera's -z axis along the rotated forward direction
    fwd = store.pose(1)[:3, :3] @ np.array([0.0, 0.0, -1.0])
    assert np.allclose(fwd, [-np.sin(np.radians(40)), 0.0, -np.cos(np.radians(40))])
    doc = json.loads((tmp_path / "kf" / "keyframes.json").read_text())
    assert doc["keyframes"][2]["intrinsics"]["width"] == W and len(doc["keyframes"][2]["cam_to_world"]) == 4


def test_keyframe_selection_and_stats(tmp_path):
    rng = np.random.default_rng(1)
    # 0.1 m steps, no turning: keyframes 0, 3, 6 of 8 frames; a generator is consumed lazily.
    def frames():
        for i in range(8):
            f = make_frame(0, rng, with_ids=False)
            f.position = np.array([0.0, 0.88, -0.1 * i])
            yield f

    store = KeyframeStore.write(tmp_path, frames(), config=StoreConfig())
    assert [r.frame_index for r in store.records] == [0, 3, 6]
    assert (store.stats.frames, store.stats.keyframes) == (8, 3)
    assert store.stats.build_seconds >= 0.0
    assert store.stats.bytes == store.disk_bytes()  # includes keyframes.json itself
    assert store.records[0].rgb_file.endswith(".jpg")
    assert np.abs(store.rgb(0).astype(int) - make_frame(0, rng).rgb.astype(int)).mean() < 4  # JPEG, close
    with pytest.raises(StoreError, match="without instance ids"):
        store.instance_ids(0)


def test_downsampling_scales_intrinsics_and_keeps_depth_and_ids_unblended(tmp_path):
    rng = np.random.default_rng(2)
    f = make_frame(0, rng)
    f.rgb[:] = 0
    f.rgb[60:100, 100:140] = 255  # a bright square whose centre is at continuous (u, v) = (119.5, 79.5)
    intr = f.intrinsics
    store = KeyframeStore.write(tmp_path, [f], config=StoreConfig(width=160, height=120, rgb_format="png",
                                                                  keep_instance_ids=True))
    K = store.K(0)
    # Pixel centres at integer coordinates: cx = (W - 1) / 2 at either size.
    assert np.allclose(K, [[intr.fx / 2, 0, 79.5], [0, intr.fy / 2, 59.5], [0, 0, 1]])
    rgb = store.rgb(0)
    assert rgb.shape == (120, 160, 3)
    rows, cols = np.nonzero(rgb[..., 0] > 127)
    # Same ray before and after: the square's centre maps through the scaled intrinsics.
    ray_full = np.array([(119.5 - intr.cx) / intr.fx, (79.5 - intr.cy) / intr.fy])
    ray_small = np.array([(cols.mean() - K[0, 2]) / K[0, 0], (rows.mean() - K[1, 2]) / K[1, 1]])
    assert np.allclose(ray_full, ray_small, atol=1e-9)
    # Depth and ids are sampled, never interpolated: every value exists in the source.
    depth = store.depth(0)
    src_mm = np.unique(np.rint(f.depth * 1000))
    assert np.isin(np.rint(depth * 1000), src_mm).all()
    assert np.isin(store.instance_ids(0), np.unique(f.instance_ids)).all()
    # Non-uniform scaling scales fy and cy on their own.
    s2 = KeyframeStore.write(tmp_path / "b", [f], config=StoreConfig(width=160, height=160))
    assert np.allclose(s2.K(0), [[intr.fx / 2, 0, 79.5], [0, intr.fy * 2 / 3, 79.5], [0, 0, 1]])
    assert s2.depth(0).shape == (160, 160)


def test_errors_name_the_path(tmp_path):
    with pytest.raises(StoreError, match="no keyframe store at .*nowhere"):
        KeyframeStore.open(tmp_path / "nowhere")
    rng = np.random.default_rng(3)
    store = KeyframeStore.write(tmp_path / "s", [make_frame(0, rng), make_frame(1, rng)],
                                config=StoreConfig(keyframes=False))
    with pytest.raises(StoreError, match="already exists"):
        KeyframeStore.write(tmp_path / "s", [make_frame(0, rng)])
    (tmp_path / "s" / store.records[1].rgb_file).unlink()
    reopened = KeyframeStore.open(tmp_path / "s")
    assert reopened.rgb(0).shape == (H, W, 3)  # lazy: only the missing file fails
    with pytest.raises(StoreError, match="000001.jpg"):
        reopened.rgb(1)
    with pytest.raises(IndexError):
        reopened.depth(5)
    bad = make_frame(0, rng)
    bad.depth = bad.depth[:, :10]
    with pytest.raises(StoreError, match="frame 0"):
        KeyframeStore.write(tmp_path / "t", [bad])
    overwritten = KeyframeStore.write(tmp_path / "s", [make_frame(0, rng)], overwrite=True)
    assert len(KeyframeStore.open(tmp_path / "s")) == 1 and overwritten.stats.bytes == overwritten.disk_bytes()


def test_preselected_frames_keep_their_trajectory_indices(tmp_path):
    rng = np.random.default_rng(4)
    frames = [make_frame(i, rng) for i in range(3)]
    store = KeyframeStore.write(tmp_path / "p", frames, frame_indices=[0, 7, 19], total_frames=25)
    assert [r.frame_index for r in store.records] == [0, 7, 19]
    assert store.stats.frames == 25 and store.stats.keyframes == 3
    with pytest.raises(StoreError, match="both"):
        KeyframeStore.write(tmp_path / "q", frames, frame_indices=[0, 1, 2])
    with pytest.raises(StoreError, match="frame_indices"):
        KeyframeStore.write(tmp_path / "r", frames, frame_indices=[0, 1], total_frames=5)
