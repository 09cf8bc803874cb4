"""Pose helpers (Habitat yaw convention) and the greedy geodesic follower on small hand-built layouts."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from navbench.scene.follower import MOVE_FORWARD, STOP, TURN_LEFT, TURN_RIGHT, GreedyFollower
from navbench.scene.navigability import NavGrid
from navbench.scene.pose import (
    heading_vector,
    quat_from_yaw,
    sum_squares,
    vector_length,
    wrap_angle,
    yaw_from_quat,
    yaw_towards,
)

TURN = math.radians(30)


def box(lo, hi) -> trimesh.Trimesh:
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    b = trimesh.creation.box(hi - lo)
    b.apply_translation((lo + hi) / 2)
    return b


def P(x, z):
    return np.array([x, 0.0, z])


@pytest.fixture(scope="module")
def wall_grid() -> NavGrid:
    # 6 x 6 m floor, a 2.5 m wall at x = 3 from z = 0 to z = 4: the way between the halves is z > 4.
    return NavGrid.from_mesh(trimesh.util.concatenate([
        box((0, -0.1, 0), (6, 0, 6)), box((2.95, 0, 0), (3.05, 2.5, 4))]))


@pytest.fixture(scope="module")
def furnished_grid() -> NavGrid:
    parts = [box((0, -0.1, 0), (7, 0, 6)), box((3.45, 0, 0), (3.55, 2.5, 2.2)), box((3.45, 0, 3.1), (3.55, 2.5, 6)),
             box((1.0, 0, 1.0), (2.0, 0.75, 1.6)), box((4.5, 0, 3.5), (5.3, 1.8, 4.1)),
             box((5.5, 0, 1.0), (5.9, 0.45, 1.4))]
    return NavGrid.from_mesh(trimesh.util.concatenate(parts))


def run_episode(grid: NavGrid, start, yaw: float, goals, success: float, max_steps: int = 500, margin: float = 0.0,
                positions: list | None = None):
    """Drive the follower with the no-sliding motion; returns (success, path length, actions, collisions)."""
    follower = GreedyFollower(grid, goals, success, clearance_margin=margin)
    pos, path, actions, collisions = np.asarray(start, float), 0.0, [], 0
    for _ in range(max_steps):
        if positions is not None:
            positions.append(pos)
        a = follower.next_action(pos, quat_from_yaw(yaw))
        actions.append(a)
        if a == STOP:
            return grid.geodesic_distance(pos, goals) < success, path, actions, collisions
        if a == MOVE_FORWARD:
            new, collided = grid.try_step(pos, pos + 0.25 * heading_vector(yaw))
            path += float(np.linalg.norm(new - pos))
            collisions += collided
            pos = new
        else:
            yaw += TURN if a == TURN_LEFT else -TURN
    return False, path, actions, collisions


# ---------------------------------------------------------------------------- pose helpers


@pytest.mark.parametrize("yaw", [0.0, 0.3, -1.2, math.pi / 2, 3.0, -3.1])
def test_quaternion_yaw_round_trip_and_scipy_agreement(yaw):
    q = quat_from_yaw(yaw)
    assert np.linalg.norm(q) == pytest.approx(1.0)
    assert yaw_from_quat(q) == pytest.approx(wrap_angle(yaw), abs=1e-9)
    # scipy stores quaternions as [x, y, z, w] too: the forward (-z) vector must match heading_vector
    assert np.allclose(Rotation.from_quat(q).apply([0, 0, -1]), heading_vector(yaw), atol=1e-9)
    assert yaw_from_quat(-q) == pytest.approx(wrap_angle(yaw), abs=1e-9)  # q and -q: same rotation


def test_habitat_heading_convention():
    assert np.allclose(heading_vector(0.0), [0, 0, -1])
    left = heading_vector(TURN)  # TURN_LEFT: counter-clockwise seen from above, towards -x
    assert left[0] < 0 and left[2] < 0
    assert np.allclose(heading_vector(math.pi / 2), [-1, 0, 0], atol=1e-12)
    assert yaw_towards(P(0, 0), P(-1, 0)) == pytest.approx(math.pi / 2)
    assert yaw_towards(P(0, 0), P(0, -2)) == pytest.approx(0.0)
    # a rotation with pitch keeps the heading of its forward vector
    tilted = (Rotation.from_euler("y", 0.7) * Rotation.from_euler("x", 0.3)).as_quat()
    assert yaw_from_quat(tilted) == pytest.approx(0.7, abs=1e-9)


def test_pose_helpers_reject_bad_values():
    with pytest.raises(ValueError, match="non-finite"):
        yaw_from_quat([0, float("nan"), 0, 1])
    with pytest.raises(ValueError, match="zero norm"):
        yaw_from_quat([0, 0, 0, 0])
    with pytest.raises(ValueError, match="4 values"):
        yaw_from_quat([0, 0, 1])
    with pytest.raises(ValueError, match="finite"):
        quat_from_yaw(float("inf"))


# ---------------------------------------------------------------------------- follower


@pytest.mark.parametrize("success", [0.1, 0.2, 0.25])
def test_follower_goes_round_the_wall_near_optimally(wall_grid, success):
    start, goal = P(1.5, 1.5), P(4.5, 1.5)
    d0 = wall_grid.geodesic_distance(start, goal)
    assert d0 > 6.0
    ok, path, actions, collisions = run_episode(wall_grid, start, 0.0, goal, success)
    assert ok
    assert path >= d0 - success - 0.05  # it cannot have cut through the wall
    assert d0 / max(d0, path) >= 0.92  # SPL
    assert len(actions) < 120
    pairs = list(zip(actions, actions[1:]))
    assert (TURN_LEFT, TURN_RIGHT) not in pairs and (TURN_RIGHT, TURN_LEFT) not in pairs


def test_first_turn_is_towards_the_goal(wall_grid):
    follower = GreedyFollower(wall_grid, P(1.0, 2.0), 0.2)
    # goal at -x: facing -z turn left (counter-clockwise), facing +z turn right, facing -x go
    assert follower.next_action(P(2.5, 2.0), quat_from_yaw(0.0)) == TURN_LEFT
    assert follower.next_action(P(2.5, 2.0), quat_from_yaw(math.pi)) == TURN_RIGHT
    assert follower.next_action(P(2.5, 2.0), quat_from_yaw(math.pi / 2)) == MOVE_FORWARD


def test_turns_ahead_counts_the_turns_left_to_the_planned_heading(wall_grid):
    # Goal straight along -x: facing -x no turn, facing -z a quarter turn (3 x 30 deg), facing +x half
    # a turn (6); the count falls by one per executed turn and is 0 after a FORWARD or STOP.
    goal, at = P(1.0, 2.0), P(2.5, 2.0)
    follower = GreedyFollower(wall_grid, goal, 0.2)
    assert follower.next_action(at, quat_from_yaw(math.pi / 2)) == MOVE_FORWARD and follower.turns_ahead == 0
    assert follower.next_action(at, quat_from_yaw(0.0)) == TURN_LEFT and follower.turns_ahead == 3
    follower = GreedyFollower(wall_grid, goal, 0.2)
    yaw, counts = -math.pi / 2, []
    for _ in range(7):
        action = follower.next_action(at, quat_from_yaw(yaw))
        counts.append(follower.turns_ahead)
        yaw += math.radians(30) if action == TURN_LEFT else -math.radians(30) if action == TURN_RIGHT else 0.0
    assert counts == [6, 5, 4, 3, 2, 1, 0]
    assert follower.next_action(P(1.05, 2.0), quat_from_yaw(0.0)) == STOP and follower.turns_ahead == 0


def test_follower_stops_inside_success_distance_and_when_unreachable(wall_grid):
    goal = P(4.5, 1.5)
    assert GreedyFollower(wall_grid, goal, 0.2).next_action(P(4.6, 1.5), quat_from_yaw(1.0)) == STOP
    assert GreedyFollower(wall_grid, P(40.0, 40.0), 0.2).next_action(P(1.5, 1.5), quat_from_yaw(0.0)) == STOP
    with pytest.raises(ValueError, match="position"):
        GreedyFollower(wall_grid, goal, 0.2).next_action(P(float("nan"), 1.0), quat_from_yaw(0.0))
    with pytest.raises(ValueError, match="success_distance"):
        GreedyFollower(wall_grid, goal, 0.0)


def test_follower_picks_the_geodesically_nearest_of_several_goals(wall_grid):
    start = P(2.5, 1.0)
    # across the wall is 0.9 m in a straight line but ~7 m round; the other goal is 2.5 m away
    goals = np.stack([P(3.4, 1.0), P(2.5, 3.5)])
    ok, path, _, _ = run_episode(wall_grid, start, 0.0, goals, 0.2)
    assert ok
    assert path < 3.0


def test_follower_success_and_spl_on_random_episodes(furnished_grid):
    rng = np.random.default_rng(7)
    results = []
    while len(results) < 24:
        start, goal = furnished_grid.sample_navigable_point(rng), furnished_grid.sample_navigable_point(rng)
        d0 = furnished_grid.geodesic_distance(start, goal)
        if not 1.0 < d0 < math.inf:
            continue
        success = (0.1, 0.2, 0.25)[len(results) % 3]
        ok, path, _, _ = run_episode(furnished_grid, start, rng.uniform(-math.pi, math.pi), goal, success)
        results.append((ok, ok * d0 / max(d0, path)))
    sr, spl = np.mean(results, axis=0)
    assert sr == 1.0
    assert spl >= 0.92


def test_clearance_margin_keeps_away_from_the_wall_end_at_little_cost(wall_grid):
    """Round the end of the wall (z = 4): the plain shortest path grazes it, the margin path keeps room."""
    clearance = wall_grid.navigable_clearance()
    runs = {}
    for margin in (0.0, 0.15):
        positions: list = []
        ok, path, _, collisions = run_episode(wall_grid, P(1.5, 1.0), 0.0, P(4.5, 1.0), 0.2, margin=margin,
                                              positions=positions)
        room = min(clearance[wall_grid._cell(p[0], p[2])] for p in positions)
        runs[margin] = (ok, path, collisions, room)
    assert runs[0.0][0] and runs[0.15][0] and runs[0.15][2] == 0
    assert runs[0.0][3] < 0.08 <= runs[0.15][3]  # closest approach to the navigable boundary
    assert runs[0.15][1] < 1.1 * runs[0.0][1]  # the detour is small


def test_clearance_weighted_field_is_distance_in_the_open_and_slower_near_walls(wall_grid):
    goal = P(1.5, 5.0)
    plain, weighted = wall_grid.distance_field(goal), wall_grid.distance_field(goal, margin=0.15)
    assert weighted is not plain and wall_grid.distance_field(goal, margin=0.15) is weighted  # cached apart
    # open floor, straight line from the goal: travel time at 1 m/s equals the distance
    assert weighted.distance(P(1.5, 3.0)) == pytest.approx(plain.distance(P(1.5, 3.0)), rel=0.02)
    # along the wall's face the agent is slowed: time exceeds distance (speed is never above 1)
    along, along_plain = wall_grid.distance_field(P(2.76, 3.5), margin=0.15), wall_grid.distance_field(P(2.76, 3.5))
    assert along.distance(P(2.76, 0.5)) > along_plain.distance(P(2.76, 0.5)) + 0.1
    finite = np.isfinite(plain.values)
    assert (weighted.values[finite] >= plain.values[finite] - 0.02).all()


def test_vector_length_rounds_each_square_and_sum_as_plain_float_code_does():
    """BLAS ddot (numpy's 1-D norm and ``@``) fuses multiply-adds on some CPUs: ``fma(b, b, a * a)`` rounds once
    where ``a * a + b * b`` rounds twice. These two entries tell them apart; the helpers must give the unfused sum."""
    a, b = 0.1257302210933933, -0.1321048632913019
    fused = float(Fraction(b) * Fraction(b) + Fraction(a * a))
    assert fused != a * a + b * b
    assert sum_squares(np.array([a, b])) == a * a + b * b
    assert vector_length(np.array([a, 0.0, b])) == math.sqrt(a * a + b * b)
    assert vector_length([3.0, 4.0]) == 5.0 and vector_length(np.zeros(3)) == 0.0
