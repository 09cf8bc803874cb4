"""PathFinder over navbench's grid: habitat-sim's return conventions, numbers equal to navbench's own geodesics."""

import math

import numpy as np
import pytest

from navbench.habitat_sim import magnum as mn
from navbench.habitat_sim.config import NavMeshSettings
from navbench.habitat_sim.nav import MultiGoalShortestPath, PathFinder, ShortestPath, nav_grid_config
from navbench.scene.navigability import NavGrid, NavGridConfig


@pytest.fixture(scope="module")
def finder(scene_path):
    from navbench.scene.cache import load_scene_and_navgrid

    _, grid = load_scene_and_navgrid(scene_path, nav_grid_config(NavMeshSettings()))
    pf = PathFinder()
    pf.load_grid(grid)
    pf.seed(3)
    return pf


def _points(pf, n, seed=5):
    """Random navigable points to the 10 micrometres find_path takes them to (as episode files hold them)."""
    pf.seed(seed)
    return [np.round(np.asarray(pf.get_random_navigable_point(), np.float64), 5) for _ in range(n)]


def test_geodesic_distance_is_navbenchs(finder):
    a, b, c = _points(finder, 3)
    path = ShortestPath()
    path.requested_start, path.requested_end = a, b
    assert finder.find_path(path)
    assert path.geodesic_distance == pytest.approx(finder.grid.geodesic_distance(a, b), rel=1e-9)
    multi = MultiGoalShortestPath()
    multi.requested_start = a
    multi.requested_ends = np.array([b, c], np.float32)
    assert finder.find_path(multi)
    singles = []
    for end in (b, c):
        p = ShortestPath()
        p.requested_start, p.requested_end = a, end
        finder.find_path(p)
        singles.append(p.geodesic_distance)
    assert multi.geodesic_distance == pytest.approx(min(singles), abs=1e-4)
    assert multi.closest_end_point_index == int(np.argmin(singles))


def test_unreachable_and_off_mesh_queries(finder):
    a = _points(finder, 1)[0]
    far = a + np.array([500.0, 0.0, 0.0])
    path = ShortestPath()
    path.requested_start, path.requested_end = a, far
    assert not finder.find_path(path)
    assert path.geodesic_distance == math.inf and path.points == []
    multi = MultiGoalShortestPath()
    multi.requested_start, multi.requested_ends = a, np.array([far], np.float32)
    assert not finder.find_path(multi) and multi.closest_end_point_index == -1
    assert np.isnan(np.asarray(finder.snap_point(far))).all()
    assert not finder.is_navigable(far)
    assert finder.is_navigable(a)
    assert not finder.is_navigable(a + np.array([0.0, 0.6, 0.0]))  # more than max_y_delta above the floor
    assert finder.island_radius(far) == 0.0


def test_points_form_a_navigable_polyline_from_start_to_end(finder):
    grid = finder.grid
    for a, b in zip(*[iter(_points(finder, 8, seed=11))] * 2):
        path = ShortestPath()
        path.requested_start, path.requested_end = a, b
        assert finder.find_path(path)
        assert all(isinstance(p, mn.Vector3) for p in path.points)  # habitat-sim's type: a list of Vector3
        pts = [np.asarray(p, np.float64) for p in path.points]
        assert np.allclose(pts[0][[0, 2]], a[[0, 2]]) and np.allclose(pts[-1][[0, 2]], b[[0, 2]], atol=1e-4)
        for p, q in zip(pts, pts[1:]):
            assert not grid._straight(p[0], p[2], q[0], q[2])[2]  # each segment stays on the navigable area
        length = sum(float(np.linalg.norm((q - p)[[0, 2]])) for p, q in zip(pts, pts[1:]))
        assert length >= path.geodesic_distance * 0.97 - 0.05
        assert length <= path.geodesic_distance * 1.05 + 0.1


def test_random_points_are_seeded(finder):
    assert [p.tolist() for p in _points(finder, 3, seed=2)] == [p.tolist() for p in _points(finder, 3, seed=2)]
    assert _points(finder, 1, seed=2)[0].tolist() != _points(finder, 1, seed=4)[0].tolist()
    assert all(finder.is_navigable(p) for p in _points(finder, 5))


def test_try_step_slides_or_stops_at_walls(finder):
    grid = finder.grid
    a = _points(finder, 1)[0]
    collided = 0
    for theta in np.linspace(0.0, 2 * math.pi, 16, endpoint=False):
        target = a + 1.5 * np.array([math.cos(theta), 0.0, math.sin(theta)])
        stop = np.asarray(finder.try_step_no_sliding(a, target), np.float64)
        slide = np.asarray(finder.try_step(a, target), np.float64)
        if finder._locate(target) is None:
            continue
        ref_stop, hit = grid.try_step(a, target, sliding=False)
        ref_slide, _ = grid.try_step(a, target, sliding=True)
        assert np.allclose(stop, ref_stop, atol=1e-5) and np.allclose(slide, ref_slide, atol=1e-5)
        assert finder.is_navigable(stop) and finder.is_navigable(slide)
        collided += hit
    assert collided > 0  # some of the 1.5 m steps run into a wall
    # a target off every island leaves the agent where it was
    assert np.allclose(np.asarray(finder.try_step(a, a + np.array([500.0, 0.0, 0.0]))), a, atol=1e-6)
    assert isinstance(finder.try_step(a, a), mn.Vector3)


def _edge_distance(grid, p):
    """Brute force: xz distance from ``p`` to the nearest non-navigable cell's square (the navigable area is the
    union of its cells' squares)."""
    ii, jj = np.nonzero(~grid.navigable)
    cs = grid.cell_size
    dx = np.maximum(np.abs(grid.origin[0] + jj * cs - p[0]) - cs / 2, 0.0)
    dz = np.maximum(np.abs(grid.origin[1] + ii * cs - p[2]) - cs / 2, 0.0)
    return float(np.hypot(dx, dz).min())


def test_distance_to_closest_obstacle_is_the_distance_to_the_edge_capped(finder):
    for a in _points(finder, 6, seed=8):
        edge = _edge_distance(finder.grid, a)
        assert finder.distance_to_closest_obstacle(a, 2.0) == pytest.approx(min(edge, 2.0), abs=1e-9)
        assert finder.distance_to_closest_obstacle(a, edge / 2) == pytest.approx(edge / 2, abs=1e-9)
    assert finder.distance_to_closest_obstacle(a + np.array([500.0, 0.0, 0.0])) == math.inf
    # from the point itself, not its cell's centre: (1.51, 1.52) is 0.535 m from the block's edge at x = 0.975
    pf = PathFinder()
    pf.load_grid(_block_grid())
    assert pf.distance_to_closest_obstacle([1.51, 0.0, 1.52]) == pytest.approx(0.535, abs=1e-9)


def _block_grid(blocks=((20, 60, 20, 60),), shape=(200, 200)):
    """A 10 x 10 m grid of 5 cm cells at floor 0 whose navigable cells are the row / column ranges ``blocks``
    (the default: one 2 x 2 m block with edges at x, z = 0.975 and 2.975)."""
    nav = np.zeros(shape, bool)
    for i0, i1, j0, j1 in blocks:
        nav[i0:i1, j0:j1] = True
    return NavGrid(nav, nav, (0.0, 0.0), 0.05, 0.0, NavGridConfig(agent_radius=0.1, agent_height=1.5))


def test_snapping_searches_detours_query_box():
    pf = PathFinder()
    pf.load_grid(_block_grid())
    corner = np.array([2.95, 0.0, 2.95])  # the block's last navigable cell centre
    # 1.9 m off the corner in x and in z: 2.69 m away, inside the (2, 4, 2) m half extents of Detour's box
    assert np.allclose(np.asarray(pf.snap_point(corner + [1.9, 0.0, 1.9])), corner)
    assert np.isnan(np.asarray(pf.snap_point(corner + [2.1, 0.0, 0.0]))).all()  # outside the box
    assert np.allclose(np.asarray(pf.snap_point(corner + [0.0, 3.5, 0.0])), corner)
    assert not pf.is_navigable(corner + [0.0, 3.5, 0.0]) and pf.is_navigable(corner + [0.0, 0.4, 0.0])
    assert np.isnan(np.asarray(pf.snap_point(corner + [0.0, 4.5, 0.0]))).all()


def test_random_points_on_an_island_and_near_a_point_are_drawn_there():
    pf = PathFinder()
    pf.load_grid(_block_grid(((20, 120, 20, 120), (160, 164, 160, 164))))  # 5 x 5 m, and 0.2 x 0.2 m
    small = pf.get_island([8.0, 0.0, 8.0])
    assert pf.num_islands == 2 and small >= 0 and pf.get_island([3.0, 0.0, 3.0]) == 1 - small
    pf.seed(0)
    for _ in range(20):  # every draw on the small island, whatever max_tries
        p = np.asarray(pf.get_random_navigable_point(max_tries=1, island_index=small), np.float64)
        assert pf.get_island(p) == small and pf.is_navigable(p)
    assert np.isnan(np.asarray(pf.get_random_navigable_point(max_tries=0))).all()
    with pytest.raises(ValueError, match="island_index 2"):
        pf.get_random_navigable_point(island_index=2)
    centre = np.array([3.0, 0.0, 3.0])
    for _ in range(20):  # a 0.3 m circle in a 25 m^2 island: drawn where the circle is, not over the island
        p = np.asarray(pf.get_random_navigable_point_near(centre, 0.3), np.float64)
        assert pf.is_navigable(p) and np.hypot(p[0] - centre[0], p[2] - centre[2]) < 0.3
    assert np.isnan(np.asarray(pf.get_random_navigable_point_near([9.5, 0.0, 0.5], 0.3))).all()
    assert pf.island_radius(small) == pytest.approx(pf.island_radius([8.0, 0.0, 8.0]))
    assert pf.island_radius(small) == pytest.approx(math.hypot(0.075, 0.075) + 0.05 / math.sqrt(2))
    assert pf.island_area(small) == pytest.approx(16 * 0.05 ** 2)
    assert pf.navigable_area == pytest.approx((100 * 100 + 16) * 0.05 ** 2)


def test_bounds_are_the_scene_meshs_box(scene_path):
    from navbench.scene.cache import load_scene_and_navgrid

    asset, grid = load_scene_and_navgrid(scene_path, nav_grid_config(NavMeshSettings()))
    pf = PathFinder()
    pf.load_grid(grid, NavMeshSettings(), asset)
    lo, hi = pf.get_bounds()
    assert np.allclose([list(lo), list(hi)], asset.mesh.bounds, atol=1e-6)  # built navmeshes report this


def test_topdown_view_matches_is_navigable(finder):
    lo, hi = (np.asarray(v, np.float64) for v in finder.get_bounds())
    height = float(lo[1])
    view = finder.get_topdown_view(0.1, height)
    assert view.dtype == bool and view.shape == (int((hi[2] - lo[2]) / 0.1), int((hi[0] - lo[0]) / 0.1))
    assert view.any()
    rng = np.random.default_rng(0)
    for h, w in zip(rng.integers(view.shape[0], size=30), rng.integers(view.shape[1], size=30)):
        x, z = np.float32(lo[0] + w * np.float32(0.1)), np.float32(lo[2] + h * np.float32(0.1))
        assert view[h, w] == finder.is_navigable([x, height, z])
    assert not finder.get_topdown_view(0.1, height + 3.0).any()  # another storey's height


def test_island_radius_covers_the_island_and_points_near_stay_near(finder):
    pts = _points(finder, 12, seed=21)
    radius = finder.island_radius(pts[0])
    same = [p for p in pts if finder.get_island(p) == finder.get_island(pts[0])]
    assert len(same) >= 2 and finder.num_islands >= 1
    # a circle of that radius contains the island: no two of its points are farther apart than its diameter
    assert max(np.linalg.norm((p - q)[[0, 2]]) for p in same for q in same) <= 2 * radius
    finder.seed(1)
    near = [np.asarray(finder.get_random_navigable_point_near(pts[0], 1.5), np.float64) for _ in range(5)]
    for p in near:
        assert np.isnan(p).all() or (finder.is_navigable(p) and np.linalg.norm((p - pts[0])[[0, 2]]) <= 1.5)
    assert any(np.isfinite(p).all() for p in near)
