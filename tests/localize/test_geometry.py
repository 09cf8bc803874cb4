from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from navbench.localize import GeometryConfig, backproject, keep_view, median_masked_depth, project, world_to_camera
from navbench.localize.geometry import voxel_downsample, voxel_firsts
from navbench.memory import Intrinsics
from navbench.render.camera import camera_pose

INTR = Intrinsics.from_hfov(224, 224, 79.0)


def camera(position, yaw_deg):
    return camera_pose(position, Rotation.from_euler("y", yaw_deg, degrees=True).as_quat())


def test_fronto_parallel_wall_lands_at_the_right_world_coordinates():
    # Camera at (1, 0.88, 3) turned 90 deg left (yaw +90 about y): it looks along world -x.
    # A wall 2 m in front of it is the plane x = -1; depth is 2 m for every pixel.
    T = camera([1.0, 0.88, 3.0], 90.0)
    depth = np.full((224, 224), 2.0, np.float32)
    pts = backproject(depth, None, INTR.K, T)
    assert pts.shape == (224 * 224, 3)
    assert np.allclose(pts[:, 0], -1.0)
    # Extent of the wall seen through a 79 deg HFOV at 2 m: half-width 2 tan(39.5 deg), minus half a pixel
    # (the outermost pixel centres lie half a pixel inside the image edge).
    half = 2.0 * np.tan(np.radians(39.5)) * (1 - 1 / 224)
    assert (pts[:, 2].min(), pts[:, 2].max()) == pytest.approx((3.0 - half, 3.0 + half), abs=1e-6)
    assert (pts[:, 1].min(), pts[:, 1].max()) == pytest.approx((0.88 - half, 0.88 + half), abs=1e-6)
    # Image right (+u) is world -z for this camera (its +x is world -z), image up (-v) is world +y.
    grid = pts.reshape(224, 224, 3)
    assert grid[112, 200, 2] < 3.0 < grid[112, 20, 2]
    assert grid[10, 112, 1] > 0.88 > grid[210, 112, 1]
    # Pixel centres sit at integer coordinates and cx = (W - 1) / 2 = 111.5: pixel 112 is half a pixel
    # right-below the optical axis.
    assert grid[112, 112] == pytest.approx([-1.0, 0.88 - 1.0 / INTR.fy, 3.0 - 1.0 / INTR.fx])


def test_mask_and_depth_limits():
    T = camera([0, 0, 0], 0)
    depth = np.full((4, 5), 1.0, np.float32)
    depth[0, 0], depth[0, 1], depth[0, 2] = 0.05, 25.0, np.nan
    mask = np.ones((4, 5), bool)
    mask[3, 4] = False
    assert len(backproject(depth, mask, np.eye(3), T)) == 20 - 3 - 1
    assert len(backproject(depth, mask, np.eye(3), T, min_depth=0.0, max_depth=30.0)) == 20 - 1 - 1
    with pytest.raises(ValueError, match="mask shape"):
        backproject(depth, mask[:2], np.eye(3), T)


def test_round_trip_project_recovers_pixels_and_depth():
    rng = np.random.default_rng(0)
    T = camera([2.0, 1.1, -4.0], 37.0)
    depth = rng.uniform(0.5, 6.0, size=(224, 224)).astype(np.float32)
    mask = rng.random((224, 224)) < 0.1
    pts = backproject(depth, mask, INTR.K, T)
    uv, z, in_view = project(pts, INTR.K, world_to_camera(T), 224, 224)
    rows, cols = np.nonzero(mask)
    assert in_view.all()
    assert np.allclose(uv, np.stack([cols, rows], axis=1), atol=1e-6)
    assert np.array_equal(np.rint(uv).astype(int), np.stack([cols, rows], axis=1))
    assert np.allclose(z, depth[rows, cols], atol=1e-5)
    assert np.allclose(world_to_camera(T), np.linalg.inv(T))


def test_points_behind_or_outside_are_not_in_view():
    T = camera([0, 0, 0], 0)  # looks along -z
    pts = np.array([[0, 0, -2.0], [0, 0, 2.0], [10.0, 0, -1.0], [0, 0, 0]])
    _, z, in_view = project(pts, INTR.K, world_to_camera(T), 224, 224)
    assert in_view.tolist() == [True, False, False, False]
    assert z[0] == pytest.approx(2.0) and z[1] == pytest.approx(-2.0)


def test_median_depth_view_filter():
    depth = np.full((10, 10), 5.0, np.float32)
    depth[:, :6] = 3.0
    mask = np.zeros((10, 10), bool)
    assert np.isnan(median_masked_depth(depth, mask))
    assert not keep_view(depth, mask)
    mask[:, 4:8] = True  # half at 3 m, half at 5 m -> median 4.0 -> kept (limit is inclusive)
    assert median_masked_depth(depth, mask) == pytest.approx(4.0)
    assert keep_view(depth, mask)
    mask[:, 4] = False  # now mostly 5 m
    assert not keep_view(depth, mask)
    assert keep_view(depth, mask, GeometryConfig(max_median_depth=6.0))


def test_voxel_firsts_keeps_the_first_point_of_each_cube_in_order():
    pts = np.array([[0.01, 0.0, 0.0], [0.02, 0.0, 0.0], [0.3, 0.0, 0.0]])
    assert voxel_firsts(pts, 0.1).tolist() == [0, 2]


def test_voxel_downsample_keeps_one_centroid_per_voxel():
    pts = np.array([[0.01, 0.01, 0.01], [0.03, 0.03, 0.03], [0.51, 0.0, 0.0], [0.52, 0.0, 0.0], [-0.2, 0, 0]])
    out = voxel_downsample(pts, 0.1)
    assert np.allclose(out, [[0.02, 0.02, 0.02], [0.515, 0.0, 0.0], [-0.2, 0.0, 0.0]])
    assert voxel_downsample(pts, 0.0) is not None and len(voxel_downsample(pts, 0.0)) == 5


def test_backprojected_render_of_a_tilted_wall_lands_on_the_wall_plane():
    """One pixel convention end to end: the renderer's depth + Intrinsics.from_hfov + backproject."""
    import trimesh

    from navbench.render.camera import CameraConfig, intrinsics
    from navbench.render.renderer import Renderer
    from navbench.scene.asset import SceneAsset

    # A wall plane through (0, 1, -2.5), turned 30 deg about y, seen from the origin at height 1.
    normal = np.array([np.sin(np.radians(30)), 0.0, np.cos(np.radians(30))])
    wall = trimesh.creation.box(extents=[8.0, 6.0, 0.1])
    wall.apply_transform(camera_pose([0.0, 1.0, -2.5 - 0.05 / np.cos(np.radians(30))],
                                     Rotation.from_euler("y", 30, degrees=True).as_quat()))
    wall.visual.vertex_colors = np.tile([200, 100, 50, 255], (len(wall.vertices), 1))
    asset = SceneAsset("wall", Path("wall.glb"), wall, np.full(len(wall.faces), -1, np.int32))
    cam = CameraConfig(width=64, height=48, hfov_deg=79.0)
    intr = Intrinsics.from_hfov(cam.width, cam.height, cam.hfov_deg)
    assert np.allclose(intr.K, intrinsics(cam))  # one convention: the renderer's
    position, rotation = np.array([0.0, 1.0, 0.0]), Rotation.from_euler("y", 10, degrees=True).as_quat()
    with Renderer(asset, cam) as renderer:
        depth = renderer.render(position, rotation, rgb=False, depth=True).depth
    assert (depth > 0).all()
    pts = backproject(depth, None, intr.K, camera_pose(position, rotation))
    # Signed distance of every point to the wall's front plane (through (0, 1, -2.5), normal towards us).
    dist = (pts - np.array([0.0, 1.0, -2.5])) @ normal
    assert np.abs(dist).max() < 0.01
    # Mixing in the other convention (principal point at W/2, H/2: half a pixel off) misses the plane.
    K_half = intr.K.copy()
    K_half[:2, 2] += 0.5
    off = (backproject(depth, None, K_half, camera_pose(position, rotation)) - np.array([0.0, 1.0, -2.5])) @ normal
    assert np.abs(off).max() > 0.01
