"""Tests for navbench.render.renderer on small scenes built here with trimesh and saved as GLB.

Scene "room" (camera at C = (0, 1, 0), identity rotation looks along -z):
  * wall: box x in [-5, 5], y in [-1, 4], z in [-3.1, -2.9] -> its front face is 2.9 m ahead;
  * obj_7: box 0.4 m wide centred (0.6, 0.5, -1.5), in view, colour (10, 200, 30);
  * obj_66053: box centred (-3, 1, 0), straight left of the camera, outside the 79 deg view (its id
    needs all three bytes of the id colour: 0x010205);
  * floor: one upward-facing quad at y = 0 (an open surface);
  * back_quad: one quad at z = +4 wound to face +z, i.e. away from a camera looking at it from
    the origin, only visible because open surfaces render two-sided.
"""

from __future__ import annotations

import ctypes.util
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import trimesh

from navbench.render import (
    CameraConfig,
    Renderer,
    RenderError,
    RenderOutput,
    backproject_image,
    culling,
    gl_platform,
    intrinsics,
    pyrender_fixes,
)
from navbench.scene.asset import load_scene

C = np.array([0.0, 1.0, 0.0])
IDENTITY = np.array([0.0, 0.0, 0.0, 1.0])
WALL_DIST = 2.9
WALL_RGB = (200, 100, 50)
OBJ7_RGB = (10, 200, 30)
OBJ7_MIN, OBJ7_MAX = np.array([0.4, 0.3, -1.7]), np.array([0.8, 0.7, -1.3])
LEFT_ID = 66053
LEFT_MIN, LEFT_MAX = np.array([-3.3, 0.7, -0.3]), np.array([-2.7, 1.3, 0.3])


def yaw(deg: float) -> np.ndarray:
    """Quaternion [x, y, z, w] for a rotation of ``deg`` about +y (counter-clockwise seen from above)."""
    h = np.radians(deg) / 2.0
    return np.array([0.0, np.sin(h), 0.0, np.cos(h)])


def pitch(deg: float) -> np.ndarray:
    h = np.radians(deg) / 2.0
    return np.array([np.sin(h), 0.0, 0.0, np.cos(h)])


def qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return (Rotation.from_quat(a) * Rotation.from_quat(b)).as_quat()


def _box(lo, hi, rgb) -> trimesh.Trimesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    b = trimesh.creation.box(extents=hi - lo)
    b.apply_translation((lo + hi) / 2)
    b.visual.face_colors = list(rgb) + [255]
    return b


def _quad(corners, rgb) -> trimesh.Trimesh:
    q = trimesh.Trimesh(np.asarray(corners, float), [[0, 1, 2], [0, 2, 3]], process=False)
    q.visual.face_colors = list(rgb) + [255]
    return q


def write_room(path: Path) -> Path:
    scene = trimesh.Scene()
    parts = {
        "wall": _box([-5, -1, -3.1], [5, 4, -2.9], WALL_RGB),
        "obj_7": _box(OBJ7_MIN, OBJ7_MAX, OBJ7_RGB),
        "obj_66053": _box(LEFT_MIN, LEFT_MAX, (250, 20, 200)),
        # counter-clockwise seen from above -> normal +y
        "floor": _quad([[-5, 0, 3], [5, 0, 3], [5, 0, -3], [-5, 0, -3]], (90, 90, 90)),
        # counter-clockwise seen from +z -> normal +z, facing away from the origin
        "back_quad": _quad([[-3, -1, 4], [3, -1, 4], [3, 4, 4], [-3, 4, 4]], (0, 0, 255)),
    }
    for name, mesh in parts.items():
        scene.add_geometry(mesh, node_name=name, geom_name=name)
    scene.export(str(path))
    return path


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    return load_scene(write_room(tmp_path_factory.mktemp("room") / "room.glb"))


@pytest.fixture(scope="module")
def renderer(room):
    with Renderer(room) as r:
        yield r


@pytest.fixture(scope="module")
def front(renderer) -> RenderOutput:
    return renderer.render(C, IDENTITY, rgb=True, depth=True, ids=True)


def test_output_types_and_shapes(front):
    assert front.rgb.shape == (224, 224, 3) and front.rgb.dtype == np.uint8
    assert front.depth.shape == (224, 224) and front.depth.dtype == np.float32
    assert front.ids.shape == (224, 224) and front.ids.dtype == np.int32
    assert front.rgb.flags.c_contiguous


def test_centre_depth_is_distance_to_wall(front):
    assert abs(front.depth[111, 111] - WALL_DIST) < 0.01
    assert abs(front.depth[112, 112] - WALL_DIST) < 0.01


def test_planar_wall_depth_is_perpendicular_distance(front):
    # Rows above the horizon see only the wall (its top is above the view); a ray-length depth
    # would reach 2.9 * 1.4 m in the corners.
    upper = front.depth[:100]
    np.testing.assert_allclose(upper, WALL_DIST, atol=0.01)


def test_instance_ids_match_object_in_view(front):
    k = intrinsics(CameraConfig())
    centre = (OBJ7_MIN + OBJ7_MAX) / 2 - C  # camera frame = world frame shifted (identity rotation)
    u = k[0, 0] * centre[0] / -centre[2] + k[0, 2]
    v = k[1, 1] * -centre[1] / -centre[2] + k[1, 2]
    assert front.ids[int(round(v)), int(round(u))] == 7
    assert set(np.unique(front.ids)) == {-1, 7}  # the left object is out of view
    assert (front.ids[:100] == -1).all()  # wall is structure
    # pixels labelled 7 see the box, which is nearer than the wall
    assert (front.depth[front.ids == 7] < 1.8).all()


def test_flat_rgb_equals_vertex_colour(front):
    assert (front.rgb[front.ids == 7] == OBJ7_RGB).all()
    assert (front.rgb[:100] == WALL_RGB).all()


def test_yaw_plus_90_looks_left(renderer, front):
    left = renderer.render(C, yaw(90.0), rgb=False, depth=True, ids=True)
    assert set(np.unique(left.ids)) == {-1, LEFT_ID}
    assert LEFT_ID not in front.ids
    right = renderer.render(C, yaw(-90.0), rgb=False, depth=False, ids=True)
    assert LEFT_ID not in right.ids


def test_backprojection_gives_world_points(renderer, front):
    cfg = renderer.camera
    pts = backproject_image(front.depth, cfg, C, IDENTITY)
    np.testing.assert_allclose(pts[:100, :, 2], -WALL_DIST, atol=0.01)
    obj = pts[front.ids == 7]
    assert (obj >= OBJ7_MIN - 0.01).all() and (obj <= OBJ7_MAX + 0.01).all()

    # A turned and pitched camera checks the rotation convention end to end.
    rot = qmul(yaw(80.0), pitch(-20.0))
    out = renderer.render(C + [0.3, 0.0, 0.2], rot, rgb=False, depth=True, ids=True)
    pts = backproject_image(out.depth, cfg, C + [0.3, 0.0, 0.2], rot)
    left = pts[out.ids == LEFT_ID]
    assert len(left) > 100
    assert (left >= LEFT_MIN - 0.01).all() and (left <= LEFT_MAX + 0.01).all()
    floor = pts[(out.ids == -1) & (np.abs(pts[..., 1]) < 0.05)]
    assert len(floor) > 1000  # the floor in view backprojects onto y = 0
    assert np.isnan(backproject_image(np.zeros((224, 224), np.float32), cfg, C, IDENTITY)).all()


def test_open_surfaces_render_from_both_sides(renderer):
    # back_quad faces away from this camera; a one-sided renderer would show nothing (depth 0).
    behind = renderer.render(C, yaw(180.0), rgb=True, depth=True)
    assert abs(behind.depth[60, 112] - 4.0) < 0.01
    assert (behind.rgb[60, 112] == (0, 0, 255)).all()
    depth_only = renderer.render(C, yaw(180.0), rgb=False, depth=True)
    np.testing.assert_array_equal(depth_only.depth, behind.depth)
    # from below, the upward floor quad is seen from its back side
    under = renderer.render(np.array([0.0, -0.5, 0.0]), pitch(90.0), rgb=False, depth=True)
    assert abs(under.depth[112, 112] - 0.5) < 0.01
    assert renderer.num_two_sided_faces == 4  # the two quads; the boxes are closed solids


def test_pass_combinations_agree(renderer, front):
    depth_only = renderer.render(C, IDENTITY, rgb=False, depth=True, ids=False)
    depth_ids = renderer.render(C, IDENTITY, rgb=False, depth=True, ids=True)
    rgb_only = renderer.render(C, IDENTITY, rgb=True, depth=False, ids=False)
    np.testing.assert_array_equal(depth_only.depth, front.depth)
    np.testing.assert_array_equal(depth_ids.depth, front.depth)
    np.testing.assert_array_equal(depth_ids.ids, front.ids)
    np.testing.assert_array_equal(rgb_only.rgb, front.rgb)
    assert depth_only.rgb is None and depth_only.ids is None and rgb_only.depth is None
    with pytest.raises(RenderError):
        renderer.render(C, IDENTITY, rgb=False, depth=False, ids=False)


def test_culling_never_removes_visible_geometry(room):
    rng = np.random.default_rng(0)
    # a yaw sweep moves every object across both frustum edges; random poses add pitch and height
    poses = [(C, yaw(a)) for a in range(0, 360, 6)] + [
        (np.array([rng.uniform(-2, 2), rng.uniform(0.3, 2.0), rng.uniform(-2, 2)]),
         qmul(yaw(rng.uniform(0, 360)), pitch(rng.uniform(-40, 40))))
        for _ in range(20)
    ]
    culled_any = False
    with (
        Renderer(room, max_chunk_faces=4) as culled,
        Renderer(room, max_chunk_faces=4, frustum_culling=False) as full,
    ):
        assert culled.num_chunks >= 8
        for p, q in poses:
            a = culled.render(p, q, ids=True)
            b = full.render(p, q, ids=True)
            np.testing.assert_array_equal(a.rgb, b.rgb)
            np.testing.assert_array_equal(a.depth, b.depth)
            np.testing.assert_array_equal(a.ids, b.ids)
            culled_any |= not culled.visible_chunks(p, q).all()
    assert culled_any  # otherwise this test checked nothing


def test_frustum_test_is_conservative():
    cfg = CameraConfig()
    cam = pyrender_fixes.pyrender.PerspectiveCamera(yfov=cfg.yfov, znear=cfg.znear, zfar=cfg.zfar)
    planes = culling.frustum_planes(cam.get_projection_matrix(224, 224))  # camera at origin, looking -z
    lo = np.array(
        [[-0.1, -0.1, -2.1], [-0.1, -0.1, 1.0], [5.0, -0.1, -2.1], [-3.0, -3.0, -2.0], [-0.1, -0.1, -60.0]]
    )
    hi = lo + [[0.2, 0.2, 0.2], [0.2, 0.2, 0.2], [0.2, 0.2, 0.2], [6.0, 6.0, 0.1], [0.2, 0.2, 0.2]]
    keep = culling.boxes_in_frustum(planes, lo, hi)
    # ahead: in; behind: out; far right at 2 m: out; a box enclosing the view axis: in; beyond zfar: out
    assert keep.tolist() == [True, False, False, True, False]


def test_shader_cache_stays_small(renderer):
    for i in range(6):
        renderer.render(C, yaw(10.0 * i), rgb=True, depth=True, ids=True)
        renderer.render(C, yaw(10.0 * i), rgb=False, depth=True)
    n = renderer.num_shader_programs
    for i in range(6):
        renderer.render(C, yaw(-10.0 * i), rgb=True, depth=True, ids=True)
        renderer.render(C, yaw(-10.0 * i), rgb=False, depth=True)
    assert renderer.num_shader_programs == n <= 4
    patched = pyrender_fixes.pyrender.shader_program.ShaderProgramCache.get_program
    pyrender_fixes.patch_shader_cache()  # idempotent
    assert pyrender_fixes.pyrender.shader_program.ShaderProgramCache.get_program is patched


def test_intrinsics_convention():
    k = intrinsics(CameraConfig(width=320, height=240, hfov_deg=90.0))
    np.testing.assert_allclose(k, [[160.0, 0, 159.5], [0, 160.0, 119.5], [0, 0, 1]])
    assert abs(np.degrees(CameraConfig(width=320, height=240, hfov_deg=90.0).yfov) - 73.74) < 0.01


def test_non_square_image_matches_intrinsics(room):
    cfg = CameraConfig(width=160, height=96)
    with Renderer(room, cfg) as r:
        out = r.render(C, IDENTITY, ids=True)
    assert out.rgb.shape == (96, 160, 3)
    pts = backproject_image(out.depth, cfg, C, IDENTITY)
    obj = pts[out.ids == 7]
    assert len(obj) > 20 and (obj >= OBJ7_MIN - 0.01).all() and (obj <= OBJ7_MAX + 0.01).all()


def test_bad_inputs_raise_value_errors(room, renderer):
    with pytest.raises(ValueError, match="hfov"):
        CameraConfig(hfov_deg=180.0)
    with pytest.raises(ValueError, match="size"):
        CameraConfig(width=0)
    with pytest.raises(ValueError, match="quaternion"):
        renderer.render(C, np.zeros(4))
    with pytest.raises(ValueError, match="position"):
        renderer.render(np.array([0.0, np.nan, 0.0]), IDENTITY)
    other = "egl" if gl_platform.bound_platform() == "osmesa" else "osmesa"
    with pytest.raises(ValueError, match="PYOPENGL_PLATFORM"):
        Renderer(room, platform=other)
    with pytest.raises(ValueError, match="platform"):
        Renderer(room, platform="vulkan")
    r = Renderer(room)
    r.close()
    r.close()
    with pytest.raises(ValueError, match="closed"):
        r.render(C, IDENTITY)


def test_renderers_closed_in_turn_free_their_context_and_leave_later_ones_exact(room, front):
    # close() frees the GL context itself (without pyrender's per-call gc.collect); a scene switch
    # closes one renderer and opens the next, so later contexts must render exactly as the first.
    for _ in range(3):
        r = Renderer(room)
        out = r.render(C, IDENTITY, rgb=True, depth=True, ids=True)
        gl = r._gl
        r.close()
        assert gl._renderer is None and gl._platform is None
        np.testing.assert_array_equal(out.depth, front.depth)
        np.testing.assert_array_equal(out.rgb, front.rgb)
        np.testing.assert_array_equal(out.ids, front.ids)


def test_import_picks_egl_on_a_gpu_else_osmesa_and_creates_no_context():
    code = textwrap.dedent(
        """
        import os
        import navbench.render  # first: it must pick the platform before OpenGL is imported
        import OpenGL.platform
        want = "egl" if navbench.render.gl_platform.egl_device_present() else "osmesa"
        assert os.environ["PYOPENGL_PLATFORM"] == want, os.environ["PYOPENGL_PLATFORM"]
        assert not OpenGL.platform.PLATFORM.GetCurrentContext()
        assert navbench.render.gl_platform.bound_platform() == want
        print("ok")
        """
    )
    env = {k: v for k, v in os.environ.items() if k != "PYOPENGL_PLATFORM"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_exit_without_closing_the_env_is_quiet():
    """A script that makes an env, resets it and exits without ``env.close()`` ends with nothing on
    stderr: renderers still open are closed at exit while PyOpenGL can still import what it needs,
    not during module teardown (where PyOpenGL's lazy imports fail and print their errors)."""
    code = textwrap.dedent(
        """
        import os, sys
        import gymnasium as gym
        import navbench
        from navbench.render.renderer import Renderer

        close = Renderer.close

        def checked_close(self):
            if self._gl is not None and sys.meta_path is None:  # module teardown has begun
                os.write(2, b"a renderer was closed during module teardown\\n")
            close(self)

        Renderer.close = checked_close
        env = gym.make("navbench/ObjectNav-v0")
        env.reset(seed=0)
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stderr == ""


@pytest.mark.skipif(ctypes.util.find_library("EGL") is None, reason="libEGL not installed")
def test_egl_matches_osmesa_without_msaa_blending(room, front):
    """EGL renders into pyrender's 4x MSAA buffer; ids and colours must still equal OSMesa's exactly."""
    code = textwrap.dedent(
        f"""
        import sys, numpy as np
        from navbench.render import Renderer
        from navbench.scene.asset import load_scene
        try:
            r = Renderer(load_scene({str(room.path)!r}), platform="egl")
        except Exception as exc:  # no EGL device on this machine
            print("NO_EGL", exc); sys.exit(0)
        out = r.render(np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 0.0, 1.0]), ids=True)
        np.savez(sys.argv[1], rgb=out.rgb, ids=out.ids, depth=out.depth)
        """
    )
    dest = room.path.with_name("egl.npz")
    env = dict(os.environ, PYOPENGL_PLATFORM="egl")
    cmd = [sys.executable, "-c", code, str(dest)]
    res = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    if res.stdout.startswith("NO_EGL"):
        pytest.skip(res.stdout.strip())
    egl = np.load(dest)
    np.testing.assert_array_equal(egl["ids"], front.ids)
    np.testing.assert_array_equal(egl["rgb"], front.rgb)
    np.testing.assert_allclose(egl["depth"], front.depth, atol=1e-3)


def test_auto_platform_is_egl_only_where_a_gpu_and_libegl_are(monkeypatch, room):
    from navbench.env.config import EnvConfig

    nodes = {"/dev/nvidia[0-9]*": [], "/dev/dri/renderD*": []}
    libs = {"EGL", "EGL_mesa", "EGL_nvidia"}
    monkeypatch.setattr(gl_platform.glob, "glob", lambda pattern: nodes[pattern])
    monkeypatch.setattr(gl_platform.ctypes.util, "find_library",
                        lambda name: f"lib{name}.so.0" if name in libs else None)
    assert gl_platform.auto_platform() == "osmesa"  # a CPU-only machine: Mesa's EGL would run on llvmpipe
    nodes["/dev/dri/renderD*"] = ["/dev/dri/renderD128"]
    assert gl_platform.auto_platform() == "egl"
    nodes["/dev/dri/renderD*"], nodes["/dev/nvidia[0-9]*"] = [], ["/dev/nvidia0"]
    assert gl_platform.auto_platform() == "egl"
    libs.discard("EGL_nvidia")  # a GPU container without the graphics capability
    assert gl_platform.auto_platform() == "osmesa"
    libs.clear()
    nodes["/dev/dri/renderD*"] = ["/dev/dri/renderD128"]
    assert gl_platform.auto_platform() == "osmesa"
    monkeypatch.undo()
    r = Renderer(room, platform="auto")
    assert r.platform == gl_platform.bound_platform() and EnvConfig().gl_platform == "auto"
    r.close()


def test_rgba_is_the_rgb_with_alpha_255_on_both_draw_paths(room):
    with Renderer(room, CameraConfig(width=40, height=30, hfov_deg=90.0)) as r:
        for path in ("direct", "pyrender"):
            if path == "pyrender":
                r._direct = None  # pyrender's draw path (EGL's), on this context
            rot = pitch(60.0)  # the wall, the floor and empty sky (the clear colour, alpha 0 in the framebuffer)
            a, b = r.render(C, rot), r.render(C, rot, rgba=True)
            assert b.rgb.shape == (30, 40, 4) and b.rgb.dtype == np.uint8 and b.rgb.flags.c_contiguous, path
            assert np.array_equal(b.rgb[..., :3], a.rgb) and (b.rgb[..., 3] == 255).all(), path
            assert np.array_equal(b.depth, a.depth) and (a.depth == 0).any() and (a.depth > 0).any(), path
