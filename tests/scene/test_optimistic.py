"""The optimistic expert's map: which cells a depth frame covers, and geodesics where unseen = free."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from navbench.scene.navigability import NavGrid
from navbench.scene.optimistic import SeenMask, optimistic_field


def box(lo, hi) -> trimesh.Trimesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    b = trimesh.creation.box(hi - lo)
    b.apply_translation((lo + hi) / 2)
    return b


@pytest.fixture(scope="module")
def wall_grid() -> NavGrid:
    # 6 x 6 m floor, a wall at x = 3 from z = 0 to z = 4: the way between the halves is z > 4.
    return NavGrid.from_mesh(trimesh.util.concatenate([
        box((0, -0.1, 0), (6, 0, 6)), box((2.95, 0, 0), (3.05, 2.5, 4))]))


def _cell(grid, x, z):
    return grid._cell(x, z)


def test_a_depth_frame_covers_the_cells_in_front_up_to_the_measured_depth(wall_grid):
    mask = SeenMask(wall_grid, hfov_deg=79.0, min_depth=0.5, max_depth=5.0)
    depth = np.full((64, 64, 1), (2.0 - 0.5) / 4.5, np.float32)  # a surface 2 m ahead everywhere
    new = mask.update(depth, np.array([1.5, 0.0, 5.5]), yaw=0.0)  # facing -z
    seen = mask.seen
    assert new.sum() == seen.sum() > 0
    assert seen[_cell(wall_grid, 1.5, 4.0)]  # 1.5 m ahead
    assert seen[_cell(wall_grid, 1.5, 3.6)]  # 1.9 m: within the margin of the surface
    assert not seen[_cell(wall_grid, 1.5, 2.5)]  # 3 m ahead: behind the surface
    assert not seen[_cell(wall_grid, 1.5, 5.9)]  # behind the camera
    assert not seen[_cell(wall_grid, 0.2, 4.8)]  # 61 deg to the left: outside the 79 deg field of view
    assert not mask.update(depth, np.array([1.5, 0.0, 5.5]), yaw=0.0).any()  # nothing new the second time
    # turning left by 90 deg (counter-clockwise seen from above) looks towards -x
    mask.update(depth, np.array([3.0, 0.0, 5.5]), yaw=math.pi / 2)
    assert mask.seen[_cell(wall_grid, 1.5, 5.5)]


def test_unseen_walls_are_passable_and_seen_ones_are_not(wall_grid):
    start, goal = np.array([1.5, 0.0, 2.0]), np.array([4.5, 0.0, 2.0])
    blind = optimistic_field(wall_grid, goal, np.zeros(wall_grid.navigable.shape, bool))
    assert blind.distance(start) == pytest.approx(3.0, abs=0.1)  # straight through the unseen wall
    everything = optimistic_field(wall_grid, goal, np.ones(wall_grid.navigable.shape, bool))
    true = wall_grid.geodesic_distance(start, goal)
    assert true > 5.0  # around the wall end
    assert everything.distance(start) == pytest.approx(true, rel=0.03)
