"""NavGrid: construction from meshes, geodesic accuracy against analytic shortest paths, snapping,
islands, motion with collisions, persistence and input validation."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from navbench.scene.asset import SceneError
from navbench.scene.navigability import NavGrid, NavGridConfig

R = 0.18  # default agent radius
CS = 0.05  # default cell size


def box(lo, hi) -> trimesh.Trimesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    b = trimesh.creation.box(hi - lo)
    b.apply_translation((lo + hi) / 2)
    return b


def floor(nx: float, nz: float) -> trimesh.Trimesh:
    return box((0, -0.1, 0), (nx, 0, nz))


def wall_x(x: float, z0: float, z1: float, t: float = 0.1) -> trimesh.Trimesh:
    """A 2.5 m wall of thickness t centred on x, spanning z in [z0, z1]."""
    return box((x - t / 2, 0, z0), (x + t / 2, 2.5, z1))


def scene(*parts) -> trimesh.Trimesh:
    return trimesh.util.concatenate(list(parts))


def P(x, z):
    return np.array([x, 0.0, z])


@pytest.fixture(scope="module")
def open_grid() -> NavGrid:
    return NavGrid.from_mesh(floor(4, 4))


@pytest.fixture(scope="module")
def wall_grid() -> NavGrid:
    # 6 x 6 m room split by a wall at x = 3 from z = 0 to z = 4; the way round is the gap z in [4, 6].
    return NavGrid.from_mesh(scene(floor(6, 6), wall_x(3.0, 0.0, 4.0)))


def around_wall_end(a, b, wall_x0: float, wall_x1: float, end_z: float, r: float) -> float:
    """Shortest path from a to b (both below end_z, on either side of a wall [x0, x1] x (-inf, end_z])
    in the free space inflated by r: tangent to the circle of radius r at the near corner, arc to the
    top of that circle, straight across the wall's end, arc and tangent down on the other side."""
    total = wall_x1 - wall_x0
    for p, cx in ((a, wall_x0), (b, wall_x1)):
        v = np.array([p[0] - cx, p[2] - end_z])
        d = np.linalg.norm(v)
        tangent = math.sqrt(d * d - r * r)
        # angle from the corner->p direction round the outside to straight up (+z), minus the part
        # covered by the tangent line
        arc = math.acos(v[1] / d) - math.acos(r / d)
        total += tangent + r * arc
    return total


# ---------------------------------------------------------------------------- construction


def test_open_floor_grid_matches_the_eroded_floor(open_grid):
    g = open_grid
    assert g.floor_height == pytest.approx(0.0, abs=1e-6)
    assert g.cell_size == CS
    assert g.free.shape == g.navigable.shape
    assert g.is_navigable(P(2, 2))
    assert g.is_navigable(P(R + 0.05, 2))
    assert not g.is_navigable(P(R - 0.08, 2))  # within the agent radius of the floor's edge
    assert not g.is_navigable(P(-1, 2))  # off the floor
    # The grid's boundary (outermost navigable centres) lies on the radius contour, so the area of
    # the navigable cells reaches half a cell further: ~ the floor eroded by r - cs/2 (rounded
    # corners shave off (4 - pi) r'^2).
    r_cells = R - CS / 2
    area = g.navigable.sum() * CS**2
    assert area == pytest.approx((4 - 2 * r_cells) ** 2 - (4 - math.pi) * r_cells**2, rel=0.02)
    # world <-> grid round trip
    ij = g.world_to_grid(np.array([[1.0, 0, 1.0], [2.3, 5.0, 3.1]]))
    back = g.grid_to_world(ij)
    assert np.allclose(back[:, [0, 2]], [[1.0, 1.0], [2.3, 3.1]], atol=CS / 2 + 1e-9)
    assert np.allclose(back[:, 1], g.floor_height)


def test_floor_level_ignores_ceiling_slab_and_furniture_tops():
    mesh = scene(floor(5, 5), box((0, 2.5, 0), (5, 2.6, 5)), box((1, 0, 1), (2, 0.75, 2)))
    g = NavGrid.from_mesh(mesh)
    assert g.floor_height == pytest.approx(0.0, abs=1e-6)
    assert not g.is_navigable(P(1.5, 1.5))  # under / inside the table-height box
    assert g.is_navigable(P(3.5, 3.5))


def test_low_step_is_climbable_but_tall_solid_interior_is_not():
    mesh = scene(floor(5, 5), box((0.5, 0, 0.5), (2.0, 0.15, 2.0)),  # 15 cm platform: climbable
                 box((2.8, 0, 2.8), (4.3, 2.0, 4.3)))  # closed wardrobe taller than the agent
    g = NavGrid.from_mesh(mesh, NavGridConfig(largest_island=False))
    assert g.is_navigable(P(1.25, 1.25))
    assert g.same_island(P(1.25, 1.25), P(4.5, 1.0))
    # its outline alone would leave a 1.5 m free square inside; the up-ray test closes it
    assert not g.is_navigable(P(3.55, 3.55))
    assert not g.free[tuple(g.world_to_grid(P(3.55, 3.55)))]


def test_explicit_floor_height_selects_the_upper_level():
    # a mezzanine slab at 1.5 m over half the room, with open air above it
    mesh = scene(floor(6, 6), box((0, 1.4, 0), (3, 1.5, 6)))
    g = NavGrid.from_mesh(mesh, NavGridConfig(floor_height=1.5))
    assert g.floor_height == 1.5
    assert g.is_navigable(P(1.5, 3))
    assert not g.is_navigable(P(4.5, 3))
    assert g.snap_point(P(1.5, 3))[1] == 1.5


def test_mesh_without_walkable_floor_raises_scene_error():
    walls = scene(wall_x(0, 0, 4), wall_x(4, 0, 4))  # 10 cm wall tops are too narrow to stand on
    with pytest.raises(SceneError, match="wide enough|walkable"):
        NavGrid.from_mesh(walls)
    quad = trimesh.Trimesh(vertices=[[0, 0, 0], [3, 0, 0], [3, 2, 0], [0, 2, 0]], faces=[[0, 1, 2], [0, 2, 3]])
    with pytest.raises(SceneError, match="no walkable floor"):
        NavGrid.from_mesh(quad)


def test_bad_config_raises_value_error():
    with pytest.raises(ValueError, match="cell_size"):
        NavGridConfig(cell_size=0.0)
    with pytest.raises(ValueError, match="max_climb"):
        NavGridConfig(max_climb=1.0)


# ---------------------------------------------------------------------------- geodesics


def test_open_floor_geodesic_is_the_straight_line(open_grid):
    a, b = P(0.9, 1.0), P(3.1, 2.7)
    exact = math.hypot(2.2, 1.7)
    d = open_grid.geodesic_distance(a, b)
    assert d == pytest.approx(exact, rel=0.01)
    assert open_grid.euclidean_distance(a, b) == pytest.approx(exact)
    assert open_grid.geodesic_distance(b, b) == pytest.approx(0.0, abs=1e-6)
    # near the goal the exact straight-line distance is used, not the interpolated cone
    assert open_grid.geodesic_distance(b + [0.03, 0, 0.04], b) == pytest.approx(0.05, abs=1e-6)


def test_geodesic_around_a_wall_end_matches_the_analytic_path(wall_grid):
    a, b = P(1.5, 1.5), P(4.5, 1.5)
    exact = around_wall_end(a, b, 2.95, 3.05, 4.0, R)
    assert exact > 6.0  # far longer than the straight 3 m through the wall
    d = wall_grid.geodesic_distance(a, b)
    assert d == pytest.approx(exact, rel=0.02)
    # asymmetric start and goal
    a2, b2 = P(0.8, 3.0), P(5.2, 0.7)
    assert wall_grid.geodesic_distance(a2, b2) == pytest.approx(around_wall_end(a2, b2, 2.95, 3.05, 4.0, R), rel=0.02)
    # the field is symmetric in start and goal
    assert wall_grid.geodesic_distance(b, a) == pytest.approx(d, rel=0.01)


def test_multi_goal_is_the_minimum_over_goals(wall_grid):
    a = P(1.5, 1.5)
    near, far = P(1.5, 3.0), P(4.5, 1.5)
    d_near, d_far = wall_grid.geodesic_distance(a, near), wall_grid.geodesic_distance(a, far)
    assert d_near == pytest.approx(1.5, rel=0.01)
    assert d_far > 6.0
    assert wall_grid.geodesic_distance(a, np.stack([far, near])) == pytest.approx(d_near, rel=1e-6)
    # a goal on the other side of the wall that is closer in a straight line does not win
    assert wall_grid.geodesic_distance(a, np.stack([far, P(3.5, 1.5)])) > 5.0


def test_distance_field_is_cached_per_goal_set(wall_grid):
    goals = np.array([[4.5, 0.0, 1.5], [1.0, 0.0, 5.0]])
    f1 = wall_grid.distance_field(goals)
    assert wall_grid.distance_field(goals.copy()) is f1
    assert wall_grid.distance_field(goals[:1]) is not f1
    assert f1.distance(P(1.0, 4.8)) == pytest.approx(0.2, abs=0.01)
    assert np.isinf(f1.values[~wall_grid.navigable]).all()
    step = f1.descent_direction(P(1.5, 1.5))
    assert step[2] > 0.9  # towards +z: round the wall end or up to the second goal


def test_disconnected_rooms_are_unreachable_not_zero():
    mesh = scene(floor(6, 3), wall_x(2.5, 0, 3))  # full-depth wall: two rooms, the right one larger
    g = NavGrid.from_mesh(mesh, NavGridConfig(largest_island=False))
    left, right = P(1.2, 1.5), P(4.5, 1.5)
    assert g.is_navigable(left) and g.is_navigable(right)
    assert g.island_id(left) != g.island_id(right) and g.island_id(left) > 0
    assert not g.same_island(left, right)
    assert g.same_island(right, P(5.5, 0.5))
    assert g.geodesic_distance(left, right) == math.inf
    assert g.distance_field(right).distance(left) == math.inf
    # largest island only: the small room disappears, its points snap too far (> 1 m) to count
    g1 = NavGrid.from_mesh(mesh)
    assert g1.num_islands == 1 and not g1.is_navigable(left)
    assert g1.island_id(left) == 0
    assert g1.geodesic_distance(right, P(1.0, 1.5)) == math.inf
    assert g1.geodesic_distance(right, P(2.5, 1.5)) < math.inf  # inside the wall, 0.28 m from the room


def test_snapping_of_points_and_goals(wall_grid):
    g = wall_grid
    inside_wall = P(3.02, 2.0)
    s = g.snap_point(inside_wall)
    assert g.is_navigable(s)
    assert s[1] == g.floor_height
    assert s[0] == pytest.approx(3.05 + R, abs=CS)  # nearest side of the wall, beyond the radius
    assert s[2] == pytest.approx(2.0, abs=CS)
    free_point = P(1.234, 2.345)
    assert np.allclose(g.snap_point(free_point), free_point)  # navigable points stay put
    assert np.isnan(g.snap_point(P(3.0, 2.0), max_dist=0.05)).all()
    # an off-grid goal counts as its snapped point, with nothing added for the snap
    a = P(4.5, 2.0)
    assert g.geodesic_distance(a, inside_wall) == pytest.approx(g.geodesic_distance(a, s), abs=1e-6)
    # goals farther than max_goal_snap from the navigable area are ignored
    assert g.geodesic_distance(a, P(20.0, 20.0)) == math.inf
    assert g.geodesic_distance(a, np.stack([P(20.0, 20.0), P(4.5, 3.0)])) == pytest.approx(1.0, rel=0.01)


def test_sampled_points_are_navigable_and_spread(wall_grid):
    rng = np.random.default_rng(0)
    pts = np.array([wall_grid.sample_navigable_point(rng) for _ in range(200)])
    assert all(wall_grid.is_navigable(p) for p in pts)
    assert np.allclose(pts[:, 1], wall_grid.floor_height)
    assert (pts[:, 0] < 3).any() and (pts[:, 0] > 3).any()
    assert len(np.unique(np.round(pts, 6), axis=0)) == 200


# ---------------------------------------------------------------------------- motion


def test_try_step_moves_freely_and_stops_at_the_clearance_boundary(wall_grid):
    g = wall_grid
    start = P(2.0, 2.0)
    new, collided = g.try_step(start, P(2.25, 2.0))
    assert not collided and np.allclose(new, P(2.25, 2.0))
    new, collided = g.try_step(start, P(3.5, 2.0))
    assert collided
    assert new[0] == pytest.approx(2.95 - R, abs=CS)
    assert new[2] == pytest.approx(2.0)
    assert new[1] == g.floor_height
    assert g.is_navigable(new)
    # from the boundary, further pushing does not move the agent
    again, collided = g.try_step(new, new + [0.25, 0, 0])
    assert collided and again[0] == pytest.approx(new[0], abs=1e-3)


def test_try_step_with_sliding_moves_along_the_wall(wall_grid):
    g = wall_grid
    start = P(2.75, 2.0)  # just inside the clearance boundary (x ~ 2.8)
    target = start + 0.25 * np.array([math.sin(math.radians(30)), 0, math.cos(math.radians(30))])
    stuck, c1 = g.try_step(start, target, sliding=False)
    slid, c2 = g.try_step(start, target, sliding=True)
    assert c1 and c2
    assert slid[0] == pytest.approx(stuck[0], abs=CS)  # still at the wall
    assert slid[2] - stuck[2] > 0.05  # but it went on along it, as far as the target's z
    assert slid[2] == pytest.approx(target[2], abs=0.01)
    assert g.is_navigable(slid)


def test_non_finite_inputs_raise_value_error(wall_grid):
    g = wall_grid
    bad = P(float("nan"), 1.0)
    for call in (lambda: g.try_step(bad, P(1, 1)), lambda: g.try_step(P(1, 1), P(1, float("inf"))),
                 lambda: g.geodesic_distance(bad, P(1, 1)), lambda: g.geodesic_distance(P(1, 1), bad),
                 lambda: g.is_navigable(bad), lambda: g.snap_point(bad),
                 lambda: g.distance_field(bad).distance(P(1, 1)),
                 lambda: g.distance_field(P(1, 1)).distance(bad)):
        with pytest.raises(ValueError, match="non-finite"):
            call()
    with pytest.raises(ValueError, match="shape"):
        g.geodesic_distance(np.zeros(2), P(1, 1))


# ---------------------------------------------------------------------------- persistence


def test_save_load_round_trip(wall_grid, tmp_path):
    path = tmp_path / "grid.npz"
    wall_grid.save(path)
    g = NavGrid.load(path)
    assert np.array_equal(g.navigable, wall_grid.navigable)
    assert np.array_equal(g.free, wall_grid.free)
    assert np.allclose(g.origin, wall_grid.origin)
    assert g.config == wall_grid.config and g.floor_height == wall_grid.floor_height
    assert g.storey_top == wall_grid.storey_top
    a, b = P(1.5, 1.5), P(4.5, 1.5)
    assert g.geodesic_distance(a, b) == pytest.approx(wall_grid.geodesic_distance(a, b))
    # the build's wall clearance comes back too: a grid read from the cache slides along walls exactly as the
    # one built (an exact distance transform of `free` would differ from it near walls)
    assert np.array_equal(g._clearance_map(), wall_grid._clearance_map())
    for start, target in ((P(2.5, 1.0), P(3.4, 1.6)), (P(2.6, 3.0), P(3.5, 2.1)), (P(2.7, 3.9), P(3.2, 4.6))):
        assert np.array_equal(g.try_step(start, target, sliding=True)[0], wall_grid.try_step(start, target, True)[0])
    corrupt = tmp_path / "corrupt.npz"
    corrupt.write_bytes(b"not an npz file")
    with pytest.raises(SceneError, match="corrupt.npz"):
        NavGrid.load(corrupt)


def test_distance_inside_a_dense_goal_region_is_never_negative():
    """ObjectNav goals are dense view-point regions; inside one the distance is to the nearest goal point."""
    from navbench.scene.navigability import NavGrid

    mesh = trimesh.creation.box(extents=(6.0, 0.1, 6.0))
    mesh.apply_translation((0, -0.05, 0))
    grid = NavGrid.from_mesh(mesh)
    xs, zs = np.meshgrid(np.arange(-1.0, 1.0, 0.05), np.arange(-1.0, 1.0, 0.05))
    goals = np.stack([xs.ravel(), np.zeros(xs.size), zs.ravel()], axis=1)
    field = grid.distance_field(goals)
    assert np.all(field.values[np.isfinite(field.values)] >= 0)
    for p in ([0.0, 0, 0.0], [0.012, 0, -0.013], [0.5, 0, 0.5]):
        nearest = np.min(np.hypot(goals[:, 0] - p[0], goals[:, 2] - p[2]))
        assert field.distance(np.array(p)) == pytest.approx(nearest, abs=0.04)  # within a cell
    # outside the region: the distance to the region's edge
    assert field.distance(np.array([2.0, 0, 0.0])) == pytest.approx(2.0 - 0.95, abs=0.03)


@pytest.mark.parametrize("offset", [0.0, 0.013, 0.025, 0.037])
def test_wall_end_accuracy_holds_at_sub_cell_alignments(offset):
    """The 2% bound must not depend on where the wall falls between grid cells."""
    g = NavGrid.from_mesh(scene(floor(6, 6), wall_x(3.0 + offset, 0.0, 4.0 + offset)))
    for a, b in ((P(1.5, 1.5), P(4.5, 1.5)), (P(0.8, 3.0), P(5.2, 0.7))):
        exact = around_wall_end(a, b, 2.95 + offset, 3.05 + offset, 4.0 + offset, R)
        assert g.geodesic_distance(a, b) == pytest.approx(exact, rel=0.02)


def test_tight_points_are_navigable_cells_beside_the_edge(wall_grid):
    rng = np.random.default_rng(0)
    clearance = wall_grid.navigable_clearance()
    points = [wall_grid.sample_tight_point(rng, 0.1) for _ in range(200)]
    for p in points:
        assert wall_grid.is_navigable(p)
        i, j = wall_grid.world_to_grid(p)
        assert 0 < clearance[i, j] <= 0.1 + 1e-9
    # both sides of the wall and the room's outer edges are drawn, not one cell over and over
    assert len({tuple(np.round(p, 3)) for p in points}) > 100
    assert min(p[0] for p in points) < 1.0 < 5.0 < max(p[0] for p in points)
    # nothing that close to an edge on an impossibly tight request
    assert wall_grid.sample_tight_point(rng, 0.0) is None


@pytest.mark.parametrize(("gap", "passable"), [(0.40, False), (0.44, False), (0.60, True), (0.80, True)])
def test_a_gap_is_passable_only_if_habitats_navmesh_admits_it(gap, passable):
    # A wall across a 6 x 6 m room with one gap: the agent's 0.36 m body fits a 0.40 m gap, but Recast's
    # erosion (ceil(0.18 / 0.05) = 4 voxels from voxels the wall touches) closes gaps under ~0.45 m.
    g = NavGrid.from_mesh(scene(floor(6, 6), wall_x(3.0, 0.0, 2.8), wall_x(3.0, 2.8 + gap, 6.0)))
    d = g.geodesic_distance(P(1.5, 1.5), P(4.5, 1.5))
    assert math.isfinite(d) == passable
    if passable:
        assert d < 5.0  # through the gap
    # Away from the gap the wall's face stays where the exact clearance puts it.
    i, j = g.world_to_grid(P(3.0, 1.0))
    assert np.array_equal(g.navigable[i, :j], g.free[i, :j] & (g._clearance[i, :j] >= R - CS / 2 - 1e-9))
