"""Route lengths over a keyframe pose graph, on a synthetic two-room walk with ray-cast depth."""

import math

import numpy as np
import pytest

from navbench.localize.fusion import GoalCandidate
from navbench.localize.route import KeyframeRoutes
from navbench.memory.store import Intrinsics
from navbench.render.camera import camera_pose
from navbench.scene.pose import quat_from_yaw

EYE = 0.88
# Two rooms split by a wall along x = 0 with a door at 3 <= z <= 4.5 (xz segments, infinite height).
WALLS = [((0.0, -10.0), (0.0, 3.0)), ((0.0, 4.5), (0.0, 10.0))]
INTR = Intrinsics.from_hfov(32, 24, 79.0)


def cast_depth(pose: np.ndarray) -> np.ndarray:
    """Depth along the optical axis to the nearest wall for every pixel; 0 where no wall is hit."""
    K, R, o = INTR.K, pose[:3, :3], pose[:3, 3]
    v, u = np.mgrid[0:INTR.height, 0:INTR.width]
    d_cam = np.stack([(u - K[0, 2]) / K[0, 0], -(v - K[1, 2]) / K[1, 1], -np.ones_like(u, float)], axis=-1)
    d = d_cam @ R.T  # world direction with unit depth along the optical axis
    depth = np.zeros(u.shape)
    for (x0, z0), (x1, z1) in WALLS:
        ex, ez = x1 - x0, z1 - z0
        den = d[..., 0] * ez - d[..., 2] * ex
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((x0 - o[0]) * ez - (z0 - o[2]) * ex) / den
            s = ((x0 - o[0]) * d[..., 2] - (z0 - o[2]) * d[..., 0]) / den
        hit = np.isfinite(t) & (t > 0) & (s >= 0) & (s <= 1) & ((depth == 0) | (t < depth))
        depth[hit] = t[hit]
    return depth.astype(np.float32)


def pose_at(x: float, z: float, yaw: float) -> np.ndarray:
    return camera_pose(np.array([x, EYE, z]), quat_from_yaw(yaw))


class FakeStore:
    """The three things KeyframeRoutes reads from a KeyframeStore."""

    def __init__(self, poses):
        self._poses = np.stack(poses)
        self._depth = [cast_depth(p) for p in poses]

    def poses(self):
        return self._poses.copy()

    def intrinsics(self, i):
        return INTR

    def depth(self, i):
        return self._depth[i]


def walk():
    """Up room A (x = -1, facing +z), through the door, down room B (x = 1, facing -z), and one
    keyframe far away that nothing joins."""
    poses = [pose_at(-1.0, z, math.pi) for z in np.arange(0.0, 3.76, 0.25)]
    poses += [pose_at(x, 3.75, -math.pi / 2) for x in np.arange(-0.75, 1.01, 0.25)]
    poses += [pose_at(1.0, z, 0.0) for z in np.arange(3.5, -0.01, -0.25)]
    poses.append(pose_at(20.0, 20.0, 0.0))
    return poses


@pytest.fixture(scope="module")
def routes():
    return KeyframeRoutes(FakeStore(walk()), camera_height=EYE)


def candidate(centre, keyframe):
    return GoalCandidate(centre=np.array(centre, float), points=np.zeros((0, 3)), keyframe_ids=(keyframe,), score=1.0)


def test_a_keyframe_sees_points_in_front_of_the_wall_but_not_behind_it():
    r = KeyframeRoutes(FakeStore([pose_at(-1.0, 0.0, -math.pi / 2)]), camera_height=EYE)  # faces the wall (+x)
    assert list(r.sees(np.array([-0.5, EYE, 0.0]))) == [0]
    assert list(r.sees(np.array([1.0, EYE, 0.0]))) == []
    assert list(r.sees(np.array([-2.0, EYE, 0.0]))) == []  # behind the camera


def test_route_goes_round_the_wall_through_the_door(routes):
    poses = walk()
    last_b = len(poses) - 2  # (1, 0) in room B
    at_35 = 14  # (-1, 3.5) in room A
    # 2.5 m in a straight line; the shortest way round by the door's edge (0, 3) is 6.5 m, the walk ~10 m
    behind_wall = candidate([1.5, 0.5, 0.0], last_b)
    ahead = candidate([-1.0, 0.5, 3.7], at_35)  # 3.7 m in a straight line, and a straight walk
    near, far = routes.lengths(np.array([-1.0, 0.0, 0.0]), [behind_wall, ahead])
    assert far == pytest.approx(3.7, abs=0.3)
    assert 6.5 < near < 10.5  # never through the wall; lines of sight cut the walk's corners


def test_the_route_path_goes_through_the_door_along_the_walk(routes):
    behind_wall = candidate([1.5, 0.5, 0.0], len(walk()) - 2)
    start = np.array([-1.0, 0.3, 0.0])
    path = routes.path(start, behind_wall)
    assert len(path) >= 2 and np.all(path[:, 1] == 0.3)  # keyframe positions on the start's floor
    assert path[-1, 0] == pytest.approx(1.0) and path[-1, 2] == pytest.approx(0.0)  # ends where it was seen
    # every leg stays on one side of the wall or crosses it in the door (3 <= z <= 4.5)
    legs = np.concatenate([start[None], path])
    for a, b in zip(legs, legs[1:]):
        if np.sign(a[0]) != np.sign(b[0]) and a[0] != 0 and b[0] != 0:
            z = a[2] + (b[2] - a[2]) * (0 - a[0]) / (b[0] - a[0])
            assert 3.0 <= z <= 4.5
    # between keyframes it keeps to the walk (no line-of-sight shortcuts, which can pass over a table)
    steps = np.linalg.norm(np.diff(path[:, [0, 2]], axis=0), axis=1)
    assert np.all(steps <= routes.config.max_step + 1e-9)
    walked = np.sum(np.linalg.norm(np.diff(legs[:, [0, 2]], axis=0), axis=1)) + 0.5  # + the exit leg
    assert routes.lengths(start, [behind_wall])[0] <= walked + 1e-9 < 10.5
    assert routes.path(np.array([-5.0, 0.0, -8.0]), behind_wall).shape == (0, 3)  # no keyframe saw it


def test_unreachable_candidates_and_unseen_points_get_inf(routes):
    isolated = candidate([20.0, 0.5, 19.0], len(walk()) - 1)
    reachable = candidate([-1.0, 0.5, 1.0], 4)
    lengths = routes.lengths(np.array([-1.0, 0.0, 0.0]), [isolated, reachable])
    assert lengths[0] == np.inf and np.isfinite(lengths[1])
    # A point no keyframe saw and none is near: no route at all.
    assert np.all(routes.lengths(np.array([-5.0, 0.0, -8.0]), [reachable]) == np.inf)


def test_a_real_prescan_walk_is_one_connected_route_never_shorter_than_the_straight_line(oracle_memory):
    store = oracle_memory.store
    routes = KeyframeRoutes(store, oracle_memory.config.camera_height)
    positions = store.positions()
    start = positions[0] - np.array([0.0, oracle_memory.config.camera_height, 0.0])  # the walk's floor point
    ks = range(0, len(store), 7)
    cands = [candidate(positions[k] + np.array([0.5, -0.4, 0.0]), k) for k in ks]
    lengths = routes.lengths(start, cands)
    straight = np.linalg.norm(np.stack([c.centre for c in cands])[:, [0, 2]] - start[[0, 2]], axis=1)
    assert np.all(np.isfinite(lengths))
    assert np.all(lengths >= straight - 1e-6)


def test_a_pair_joined_several_ways_counts_its_length_once():
    # Consecutive on the walk and within link_radius (two reasons to join), neither seeing the other.
    r = KeyframeRoutes(FakeStore([pose_at(0.0, 0.0, 0.0), pose_at(0.3, 0.0, 0.0)]), camera_height=EYE)
    edges, weights = r.graph()
    assert edges.tolist() == [[0, 1]] and weights == pytest.approx([0.3])
    assert r.lengths(np.array([0.0, 0.0, 0.0]), [candidate([0.3, 0.5, -1.0], 1)]) == pytest.approx([1.3])


def test_routes_join_storeys_only_where_the_walk_climbed_between_them():
    """Room A's walk on the ground floor and the same walk 3 m above it (the storey over it, cameras right above
    the ground floor's; the fake depth has no floors, so every camera sees every other): first as two walks a
    cut in the scan separates, then joined by a flight of stairs the walk climbs (0.15 m a 0.25 m step)."""
    up = 3.0

    def at(x, y, z, yaw=math.pi):
        return camera_pose(np.array([x, EYE + y, z]), quat_from_yaw(yaw))

    zs = np.arange(0.0, 3.76, 0.25)
    cut = [at(-1.0, 0.0, z) for z in zs] + [at(-1.0, up, z) for z in zs]
    r = KeyframeRoutes(FakeStore(cut), camera_height=EYE)
    upstairs = candidate([-1.0, up + 0.5, 3.75], len(cut) - 1)
    downstairs = candidate([-1.0, 0.5, 3.75], len(zs) - 1)
    start = np.array([-1.0, 0.0, 0.0])
    assert r.lengths(start, [downstairs])[0] == pytest.approx(3.75)
    assert np.isinf(r.lengths(start, [upstairs])[0])  # right above, but nothing walked there from here
    assert len(r.path(start, upstairs)) == 0
    # the walk: up A and back, over to x = -3, up a flight of 20 steps to z = 5, over to x = -1 and down A upstairs
    walk2 = [at(-1.0, 0.0, z) for z in zs] + [at(-1.0, 0.0, z) for z in zs[::-1]]
    walk2 += [at(x, 0.0, 0.0) for x in (-1.5, -2.0, -2.5, -3.0)]
    walk2 += [at(-3.0, 0.15 * k, 0.25 * k) for k in range(1, 21)]
    walk2 += [at(x, up, 5.0) for x in (-2.5, -2.0, -1.5)]
    walk2 += [at(-1.0, up, z) for z in np.arange(5.0, -0.01, -0.25)]
    r2 = KeyframeRoutes(FakeStore(walk2), camera_height=EYE)
    above = candidate([-1.0, up + 0.5, 0.0], len(walk2) - 1)
    # by the stairs: out to x = -3 and back (4 m) and up the flight (5 m, less a shortcut in sight at either end)
    assert 9.0 < r2.lengths(start, [above])[0] <= 2.0 + 5.0 + 2.0 + 5.0
    path = r2.path(start, above)
    assert any(np.isclose(p[0], -3.0) for p in path)
