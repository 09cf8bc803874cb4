"""The renderer's images are pinned: RGB and instance ids bit-exact, depth within 1e-4 m, on a bundled house.

``data/house_008_frames.npz`` holds frames rendered by the renderer as it was before its per-frame
draw path was rewritten (pyrender's ``Renderer.render`` for every pass, commit 37ef89d), from the
fixed poses below: seven at the agent's 224x224 camera with the default chunking (one chunk), and four
at a small non-square camera with the house cut into chunks of 300 triangles, so frustum culling and
the near-to-far chunk order are exercised too. Any change to the draw path, the read-back or the
culling must reproduce them. Regenerate only deliberately, when the images are meant to change:

    PYTHONPATH=$PWD PYOPENGL_PLATFORM=osmesa python tests/render/test_image_equality.py --regenerate
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from navbench.render import CameraConfig, Renderer
from navbench.scene.asset import load_scene
from navbench.scene.pose import quat_from_yaw

DATA = Path(__file__).with_name("data") / "house_008_frames.npz"
HOUSE = Path(__file__).resolve().parents[2] / "envs" / "houses" / "val" / "house_008.glb"
DEPTH_TOL = 1e-4  # metres


def _pitched(yaw: float, pitch: float) -> np.ndarray:
    """[x, y, z, w] of yaw about +y, then pitch about the camera's x axis."""
    qy = quat_from_yaw(yaw)
    qx = np.array([np.sin(pitch / 2), 0.0, 0.0, np.cos(pitch / 2)])
    x1, y1, z1, w1 = qy
    x2, y2, z2, w2 = qx
    return np.array([w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2, w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2, w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2])


# (position, rotation): views with many objects (picked by their id counts), pitched views, and one from outside.
POSES = [
    ([4.0, 0.88, 5.0], quat_from_yaw(0.785)),
    ([0.0, 0.88, 3.0], quat_from_yaw(1.57)),
    ([2.0, 0.88, -5.0], quat_from_yaw(3.925)),
    ([4.0, 0.88, 0.0], quat_from_yaw(2.355)),
    ([-5.0, 1.2, -4.2], _pitched(0.7, -0.5)),
    ([2.0, 2.4, -1.0], _pitched(-0.4, -1.2)),
    ([0.0, 6.0, 14.0], _pitched(0.0, -0.45)),  # outside, above: background (depth 0, id -1) too
]
SMALL = CameraConfig(width=96, height=72, hfov_deg=90.0)
SMALL_CHUNK_FACES = 300


def _frames() -> dict[str, np.ndarray]:
    """Every pass combination the env asks for, from the poses above."""
    asset = load_scene(HOUSE)
    out: dict[str, np.ndarray] = {}
    with Renderer(asset, CameraConfig()) as r:
        for k, (p, q) in enumerate(POSES):
            p = np.asarray(p, float)
            full = r.render(p, q, rgb=True, depth=True, ids=True)
            out[f"big{k}_rgb"], out[f"big{k}_depth"], out[f"big{k}_ids"] = full.rgb, full.depth, full.ids
            only = r.render(p, q, rgb=False, depth=True, ids=False).depth  # the DEPTH_ONLY pass
            assert np.array_equal(only, full.depth)  # so the fixture stores one depth image per pose
    with Renderer(asset, SMALL, max_chunk_faces=SMALL_CHUNK_FACES) as r:
        assert r.num_chunks > 8
        for k, (p, q) in enumerate(POSES[:4]):
            p = np.asarray(p, float)
            full = r.render(p, q, rgb=True, depth=True, ids=True)
            out[f"small{k}_rgb"], out[f"small{k}_depth"], out[f"small{k}_ids"] = full.rgb, full.depth, full.ids
            assert np.array_equal(r.render(p, q, rgb=False, depth=True, ids=False).depth, full.depth)
    return out


@pytest.fixture(scope="module")
def reference() -> dict[str, np.ndarray]:
    with np.load(DATA) as z:
        return {k: z[k] for k in z.files}


def _check(ref: dict[str, np.ndarray], key: str, rgb=None, depth=None, ids=None) -> None:
    if rgb is not None:
        assert rgb.dtype == np.uint8 and rgb.shape == ref[f"{key}_rgb"].shape
        differ = (rgb != ref[f"{key}_rgb"]).any(-1).sum()
        assert np.array_equal(rgb, ref[f"{key}_rgb"]), f"{key}: {differ} RGB pixels differ"
    if ids is not None:
        assert ids.dtype == np.int32
        assert np.array_equal(ids, ref[f"{key}_ids"]), f"{key}: {(ids != ref[f'{key}_ids']).sum()} id pixels differ"
    if depth is not None:
        assert depth.dtype == np.float32 and depth.shape == ref[f"{key}_depth"].shape
        err = np.abs(depth.astype(np.float64) - ref[f"{key}_depth"])
        assert err.max() <= DEPTH_TOL, f"{key}: depth off by up to {err.max():.2e} m"


def test_reference_frames_are_not_trivial(reference):
    for k in range(len(POSES)):
        assert (reference[f"big{k}_depth"] > 0).mean() > 0.2
        assert len(np.unique(reference[f"big{k}_rgb"].reshape(-1, 3), axis=0)) > 3
    assert sum(len(np.unique(reference[f"big{k}_ids"])) > 1 for k in range(len(POSES))) >= 5
    assert (reference[f"big{len(POSES) - 1}_depth"] == 0).mean() > 0.1  # background seen from outside


@pytest.mark.parametrize("chunked", [False, True], ids=["one_chunk_224", "chunks_96x72"])
def test_every_pass_combination_matches_reference(reference, chunked):
    cfg, kw, prefix, poses = ((SMALL, {"max_chunk_faces": SMALL_CHUNK_FACES}, "small", POSES[:4]) if chunked
                              else (CameraConfig(), {}, "big", POSES))
    with Renderer(load_scene(HOUSE), cfg, **kw) as r:
        for k, (p, q) in enumerate(poses):
            key, p = f"{prefix}{k}", np.asarray(p, float)
            for _ in range(2):  # a second round: nothing carries over from frame to frame
                out = r.render(p, q, rgb=True, depth=True, ids=True)
                _check(reference, key, rgb=out.rgb, depth=out.depth, ids=out.ids)
                out = r.render(p, q, rgb=True, depth=True, ids=False)
                _check(reference, key, rgb=out.rgb, depth=out.depth)
                assert out.ids is None
                out = r.render(p, q, rgb=True, depth=False, ids=False)
                _check(reference, key, rgb=out.rgb)
                assert out.depth is None
                out = r.render(p, q, rgb=False, depth=True, ids=False)
                assert out.rgb is None and out.ids is None
                _check(reference, key, depth=out.depth)  # the DEPTH_ONLY pass (bit-equal at generation)
                out = r.render(p, q, rgb=False, depth=True, ids=True)
                _check(reference, key, depth=out.depth, ids=out.ids)
                out = r.render(p, q, rgb=False, depth=False, ids=True)
                _check(reference, key, ids=out.ids)


def test_direct_path_equals_pyrender_path_on_a_textured_scan(tmp_path, monkeypatch):
    """A small textured scan (texture atlas, vertex-coloured parts, occlusion culling on, 8 chunks
    or more): frames of the direct OSMesa path equal those of pyrender's own render(), which the
    renderer still uses on EGL, for every pass combination along an agent's walk."""
    from navbench.bench.scan import agent_walk
    from navbench.bench.scan_fixture import make_scan_fixture
    from navbench.render.gl_direct import DirectDraw
    from navbench.scene.cache import load_scene_and_navgrid

    fx = make_scan_fixture(tmp_path, faces=30_000, texture_size=512, basis=False, episodes=1)
    monkeypatch.setenv("NAVBENCH_CACHE", str(tmp_path / "cache"))
    asset, grid = load_scene_and_navgrid(fx.glb)
    assert asset.is_textured
    kw = dict(occlusion_culling=True, max_chunk_faces=4_000)
    with monkeypatch.context() as m:
        m.setattr(DirectDraw, "create", classmethod(lambda cls, *a: None))
        reference = Renderer(asset, **kw)
    direct = Renderer(asset, **kw)
    assert reference._direct is None and direct._direct is not None and direct.num_chunks >= 8
    with reference, direct:
        for p, q in agent_walk(grid, 40, seed=3)[::2]:
            for flags in ((True, True, True), (True, True, False), (False, True, False), (False, True, True),
                          (False, False, True)):
                a, b = reference.render(p, q, *flags), direct.render(p, q, *flags)
                for name in ("rgb", "depth", "ids"):
                    x, y = getattr(a, name), getattr(b, name)
                    assert (x is None) == (y is None)
                    if x is not None:
                        assert x.dtype == y.dtype, (name, flags, p)
                        if name == "depth":
                            assert np.abs(x.astype(np.float64) - y).max() <= DEPTH_TOL, (flags, p)
                        else:
                            assert np.array_equal(x, y), (name, flags, p)


def test_camera_rotation_equals_scipy_bit_for_bit():
    """camera_pose builds the rotation itself; the view matrix, so every pixel, depends on its last bits."""
    from scipy.spatial.transform import Rotation

    from navbench.render.camera import _quat_matrix

    rng = np.random.default_rng(0)
    qs = rng.normal(size=(20000, 4)) * rng.uniform(0.01, 100.0, size=(20000, 1))
    qs[:2000, [0, 2]] = 0.0  # yaw only, as the agent turns
    qs[2000:2100] = [quat_from_yaw(float(a)) for a in rng.uniform(-7, 7, 100)]
    for q in qs:
        assert np.array_equal(_quat_matrix(q), Rotation.from_quat(q).as_matrix()), q


if __name__ == "__main__":
    if "--regenerate" not in sys.argv:
        sys.exit(__doc__)
    DATA.parent.mkdir(exist_ok=True)
    np.savez_compressed(DATA, **_frames())
    print(DATA, DATA.stat().st_size, "bytes")
