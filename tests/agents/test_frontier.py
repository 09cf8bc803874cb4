"""Occupancy mapping, frontiers and the frontier agent's decisions in an analytic box world (no renderer)."""

import math

import numpy as np
import pytest

from navbench.agents.base import fov_stop_radius, nearest_to_height
from navbench.agents.frontier import FrontierAgent, FrontierAgentConfig
from navbench.agents.occupancy import FREE, OCCUPIED, OccupancyConfig, OccupancyMap, trace_path
from navbench.env.config import MOVE_FORWARD, STOP, TURN_LEFT, TURN_RIGHT, EnvConfig
from navbench.env.sensors import compass, gps
from navbench.episodes.types import Episode
from navbench.render.camera import CameraConfig, intrinsics
from navbench.scene.pose import heading_vector, quat_from_yaw

ENV = EnvConfig(width=96, height=96)  # small images keep the tests fast; the geometry is the same
K = intrinsics(CameraConfig(width=ENV.width, height=ENV.height, hfov_deg=ENV.hfov_deg))


class BoxWorld:
    """An empty rectangular room (vertical walls, floor y=0, ceiling 2.5 m) with an analytic depth camera
    and Habitat's discrete motion (no sliding: a blocked forward step does not move)."""

    def __init__(self, xmin, xmax, zmin, zmax, start=(0.0, 0.0), yaw=0.0):
        self.bounds = (xmin, xmax, zmin, zmax)
        self.start = np.array([start[0], 0.0, start[1]])
        self.start_yaw = yaw
        self.pos, self.yaw = self.start.copy(), yaw
        v, u = np.mgrid[0:ENV.height, 0:ENV.width].astype(np.float64)
        self.ray_cam = np.stack([(u - K[0, 2]) / K[0, 0], -(v - K[1, 2]) / K[1, 1], -np.ones_like(u)], -1)

    def episode(self):
        return Episode("0", "box.glb", self.start.tolist(), quat_from_yaw(self.start_yaw).tolist(),
                       object_category="chair")

    def depth(self):
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        rc = self.ray_cam
        d = np.stack([c * rc[..., 0] + s * rc[..., 2], rc[..., 1], -s * rc[..., 0] + c * rc[..., 2]], -1)
        o = self.pos + np.array([0.0, ENV.agent_height, 0.0])
        xmin, xmax, zmin, zmax = self.bounds
        with np.errstate(divide="ignore", invalid="ignore"):
            ts = [np.where(d[..., 0] > 0, (xmax - o[0]) / d[..., 0], np.inf),
                  np.where(d[..., 0] < 0, (xmin - o[0]) / d[..., 0], np.inf),
                  np.where(d[..., 2] > 0, (zmax - o[2]) / d[..., 2], np.inf),
                  np.where(d[..., 2] < 0, (zmin - o[2]) / d[..., 2], np.inf),
                  np.where(d[..., 1] < 0, -o[1] / d[..., 1], np.inf),
                  np.where(d[..., 1] > 0, (2.5 - o[1]) / d[..., 1], np.inf)]
        t = np.min(ts, axis=0)  # camera-frame z of every ray is -1, so t is the z-depth
        t = np.clip(t, ENV.min_depth, ENV.max_depth)
        return ((t - ENV.min_depth) / (ENV.max_depth - ENV.min_depth)).astype(np.float32)[..., None]

    def obs(self):
        return {"depth": self.depth(), "gps": gps(self.pos, self.start, self.start_yaw),
                "compass": compass(self.yaw, self.start_yaw)}

    def step(self, action):
        if action == MOVE_FORWARD:
            p = self.pos + 0.25 * heading_vector(self.yaw)
            xmin, xmax, zmin, zmax = self.bounds
            r = ENV.agent_radius
            if xmin + r <= p[0] <= xmax - r and zmin + r <= p[2] <= zmax - r:
                self.pos = p
        elif action == TURN_LEFT:
            self.yaw += math.radians(30)
        elif action == TURN_RIGHT:
            self.yaw -= math.radians(30)


class GreedyPolicy:
    """Stand-in PointNav policy: face the goal, then go forward; STOP within 0.2 m."""

    def __init__(self, fixed=None):
        self.fixed, self.hidden_resets, self.goals = fixed, 0, []

    def reset(self, i=None, seed=None):
        pass

    def reset_hidden(self, i=None):
        self.hidden_resets += 1

    def act(self, depth, pointgoal):
        rho, theta = (float(v) for v in pointgoal[0])
        self.goals.append((rho, theta))
        if self.fixed is not None:
            return np.array([self.fixed])
        if rho < 0.2:
            return np.array([STOP])
        if abs(theta) > math.radians(16):
            return np.array([TURN_LEFT if theta > 0 else TURN_RIGHT])
        return np.array([MOVE_FORWARD])


def no_detection(obs, pose):
    return np.zeros((0, 3))


def run(world, agent, steps):
    agent.reset(world.episode())
    actions = []
    for _ in range(steps):
        a = agent.act(world.obs())
        actions.append(a)
        if a == STOP:
            break
        world.step(a)
    return actions


# ------------------------------------------------------------------------------------ occupancy


def test_wall_marks_occupied_at_its_distance_and_free_before_it():
    world = BoxWorld(-4.0, 4.0, -2.025, 4.0)  # agent at the origin facing -z; wall mid-cell at z = -2.025
    m = OccupancyMap(OccupancyConfig(cell_size=0.05))
    m.reset(np.zeros(3))
    m.update(world.depth(), K, world.pos, 0.0, ENV.agent_height, ENV.min_depth, ENV.max_depth)
    cell = lambda x, z: tuple(m.to_cell(np.array([x, z])))  # noqa: E731
    assert m.grid[cell(0.0, -0.3)] == FREE
    for x in (-0.8, 0.0, 0.8):  # inside the 79 deg field of view from z = -1 on
        assert m.grid[cell(x, -2.025)] == OCCUPIED
        for z in (-1.0, -1.8):
            assert m.grid[cell(x, z)] == FREE
        assert m.grid[cell(x, -2.5)] == 0  # behind the wall: unknown
    assert m.grid[cell(0.0, 1.0)] == 0  # behind the camera: unknown
    assert m.grid[cell(3.0, -1.0)] == 0  # outside the 79 deg field of view
    occ_z = m.to_world(np.argwhere(m.occupied))[:, 2]
    assert np.all(np.abs(occ_z + 2.025) < 1e-6)  # only the wall (floor and ceiling are outside the band)


def test_clipped_depth_is_free_up_to_max_range_and_zero_depth_is_unknown():
    m = OccupancyMap(OccupancyConfig(cell_size=0.1))
    m.reset(np.zeros(3))
    far = np.ones((ENV.height, ENV.width), np.float32)  # everything beyond 5 m
    m.update(far, K, np.zeros(3), 0.0, ENV.agent_height, ENV.min_depth, ENV.max_depth)
    assert m.grid[tuple(m.to_cell(np.array([0.0, -4.8])))] == FREE
    assert m.grid[tuple(m.to_cell(np.array([0.0, -5.3])))] == 0
    assert not m.occupied.any()
    m2 = OccupancyMap(OccupancyConfig(cell_size=0.1))
    m2.reset(np.zeros(3))
    m2.update(np.zeros_like(far), K, np.zeros(3), 0.0, ENV.agent_height, ENV.min_depth, ENV.max_depth)
    assert m2.free.sum() == pytest.approx(np.pi * 2**2, abs=8)  # only the agent's footprint disk (r = 2 cells)


def hand_made_map():
    """A 2 x 2 m free room walled on three sides, open to unknown space on the +x side."""
    m = OccupancyMap(OccupancyConfig(cell_size=0.1, size=6.0, min_frontier_size=0.3))
    m.reset(np.zeros(3))
    c = m.n // 2
    m.grid[c - 10:c + 10, c - 10:c + 10] = FREE
    m.grid[c - 11, c - 11:c + 10] = OCCUPIED  # top wall
    m.grid[c + 10, c - 11:c + 10] = OCCUPIED  # bottom wall
    m.grid[c - 11:c + 11, c - 11] = OCCUPIED  # left wall
    return m, c


def test_frontier_extraction_on_a_hand_made_grid():
    m, c = hand_made_map()
    mask = m.frontier_mask()
    # the open side's last free column, except the cells next to the walls
    assert set(map(tuple, np.argwhere(mask))) == {(r, c + 9) for r in range(c - 9, c + 9)}
    dist = m.path_distance(m.to_world(np.array([c, c])))
    fs = m.frontiers(dist)
    assert len(fs) == 1 and fs[0].size == 18
    assert fs[0].goal_cell[1] == c + 9 and abs(fs[0].goal_cell[0] - (c - 0.5)) <= 1
    assert fs[0].distance == pytest.approx(0.9, abs=0.06)
    # a 1-cell unknown hole makes a small ring of frontier cells: kept or dropped by the minimum size
    m.grid[c - 3, c - 3] = 0
    assert len(m.frontiers(dist)) == 2
    m.config = OccupancyConfig(cell_size=0.1, size=6.0, min_frontier_size=1.0)
    assert len(m.frontiers(dist)) == 1


def test_path_distance_goes_around_walls_and_stops_at_unknown():
    m = OccupancyMap(OccupancyConfig(cell_size=0.05, size=8.0, agent_radius=0.0, planning_margin=0.0))
    m.reset(np.zeros(3))
    m.grid[:] = FREE
    src = np.array([-2.0, 0.0, 0.0])
    d_open = m.path_distance(src)
    dst = tuple(m.to_cell(np.array([2.0, 0.0])))
    assert d_open[dst] == pytest.approx(4.0, rel=0.02)
    # a wall at x = 0 from z = -1 to z = 3: the path must pass below it
    wall = m.to_cell(np.array([[0.0, -1.0], [0.0, 3.0]]))
    m.grid[wall[0, 0]:wall[1, 0], wall[0, 1]] = OCCUPIED
    d_wall = m.path_distance(src)
    around = 2 * math.hypot(2.0, 1.0)
    assert d_wall[dst] == pytest.approx(around, rel=0.03)
    path = trace_path(d_wall, dst)
    assert tuple(path[0]) == tuple(m.to_cell(src[[0, 2]])) and tuple(path[-1]) == dst
    assert np.all(m.grid[path[:, 0], path[:, 1]] == FREE)
    # unknown space is not traversable
    m.grid[:, wall[0, 1]] = 0
    assert np.isinf(m.path_distance(src)[dst])


# ---------------------------------------------------------------------------------------- agent


def test_agent_looks_around_then_drives_toward_the_frontier():
    world = BoxWorld(-1.5, 1.5, -12.0, 1.0)  # a long corridor: only its far end stays unexplored
    agent = FrontierAgent(no_detection, GreedyPolicy(), FrontierAgentConfig(), ENV)
    actions = run(world, agent, 40)
    assert actions[:12] == [TURN_LEFT] * 12
    assert STOP not in actions
    assert world.pos[2] < -2.0  # drove down the corridor, toward the unexplored end
    ev = agent.episode_log()["events"]
    chosen = [e for e in ev if e["event"] == "frontier"]
    assert chosen and chosen[0]["goal"][2] < -4.0


def test_closed_room_without_target_ends_with_stop():
    world = BoxWorld(-1.5, 1.5, -1.5, 1.5)
    agent = FrontierAgent(no_detection, GreedyPolicy(), FrontierAgentConfig(), ENV)
    actions = run(world, agent, 60)
    assert actions[-1] == STOP and len(actions) <= 30
    assert agent.episode_log()["stop_reason"] == "no_frontier"


def target_patch(x, z, n=7):
    xs, ys = np.meshgrid(np.linspace(x - 0.2, x + 0.2, n), np.linspace(0.3, 0.9, n))
    return np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, z)], 1)


def seen(target, pose):
    """A detector's answer: the target whenever it is in front of the camera and < 5 m away."""
    pos, yaw = pose
    rel = target[:, [0, 2]].mean(0) - pos[[0, 2]]
    h = heading_vector(yaw)[[0, 2]]
    ahead, side = rel @ h, h[0] * rel[1] - h[1] * rel[0]
    visible = ahead > 0 and np.linalg.norm(rel) < 5.0 and abs(math.atan2(side, ahead)) < math.radians(35)
    return target if visible else np.zeros((0, 3))


def test_heads_to_detected_target_and_stops_close_when_visible():
    world = BoxWorld(-3.0, 3.0, -6.0, 1.0)
    target = target_patch(1.0, -6.0)  # on the far wall

    agent = FrontierAgent(lambda obs, pose: seen(target, pose), GreedyPolicy(), FrontierAgentConfig(), ENV)
    actions = run(world, agent, 120)
    assert actions[-1] == STOP
    log = agent.episode_log()
    assert log["stop_reason"] == "target_visible"
    assert log["first_detection_step"] is not None
    d = np.min(np.hypot(target[:, 0] - world.pos[0], target[:, 2] - world.pos[2]))
    # within the STOP radius. The patch spans 0.3-0.9 m, so it stays in view down to 0 m: the radius is
    # the plain 0.9 m, though the goal (its point nearest the agent) may be its 0.3 m edge, which alone
    # would leave the view at 0.70 m and grow the radius
    radius = fov_stop_radius(nearest_to_height(target, ENV.agent_height), 0.9, 0.15, ENV.agent_height,
                             math.tan(math.radians(79.0) / 2))
    assert radius == pytest.approx(0.9)
    assert d < radius
    # a detector that never fires in the same room: the agent does not stop at the wall
    agent2 = FrontierAgent(no_detection, GreedyPolicy(), FrontierAgentConfig(), ENV)
    world2 = BoxWorld(-3.0, 3.0, -6.0, 1.0)
    run(world2, agent2, 120)
    assert agent2.episode_log()["stop_reason"] != "target_visible"


class SubtaskDetector:
    """Sees the active subtask's target patch as :func:`seen` does; records the subtasks it is reset for."""

    def __init__(self, targets):
        self.targets, self.resets, self.active = targets, [], 0

    def reset(self, episode, query=None, subtask=0):
        self.resets.append(subtask)
        self.active = subtask

    def __call__(self, obs, pose):
        return seen(self.targets[self.active], pose)


def test_on_goat_each_subtask_is_a_new_search_closed_with_subtask_stop():
    from navbench.episodes.goat import SUBTASK_STOP, GoatEpisode, GoatSubtask

    world = BoxWorld(-3.0, 3.0, -6.0, 1.0)
    ep = world.episode()
    goat = GoatEpisode(ep.episode_id, ep.scene_id, ep.start_position, ep.start_rotation,
                       tasks=[GoatSubtask("chair", "object"), GoatSubtask("bed", "object")])
    detect = SubtaskDetector([target_patch(1.0, -6.0), target_patch(-2.0, -6.0)])
    agent = FrontierAgent(detect, GreedyPolicy(), FrontierAgentConfig(), ENV)
    agent.reset(goat)
    actions = []
    for _ in range(400):
        a = agent.act(world.obs())
        actions.append(a)
        if a == STOP or actions.count(SUBTASK_STOP) == 2:
            break
        world.step(a)
    assert STOP not in actions and actions.count(SUBTASK_STOP) == 2
    assert detect.resets == [0, 1]  # taught each subtask's goal
    first = actions.index(SUBTASK_STOP)
    assert actions[first + 1:first + 13] == [TURN_LEFT] * 12  # a new look-around: nothing kept from subtask 0
    assert np.min(np.hypot(*(detect.targets[1][:, [0, 2]] - world.pos[[0, 2]]).T)) < 0.9
    events = [e["event"] for e in agent.episode_log()["events"]]
    assert events.count("subtask_stop") == 2 and events.count("look_around_done") == 2


def test_not_visible_target_does_not_stop_immediately():
    world = BoxWorld(-3.0, 3.0, -6.0, 1.0)
    hidden = target_patch(0.0, -8.0)  # behind the wall: projected depth disagrees with the measured depth
    agent = FrontierAgent(lambda o, p: hidden, GreedyPolicy(), FrontierAgentConfig(stop_radius=3.0), ENV)
    agent.reset(world.episode())
    for _ in range(12):
        agent.act(world.obs())
    world.pos = np.array([0.0, 0.0, -5.5])  # within the stop radius of the hidden target, facing it
    assert agent.act(world.obs()) != STOP
    assert agent.episode_log()["stop_reason"] is None


def test_stuck_frontier_is_blacklisted_and_another_chosen():
    world = BoxWorld(-10.0, 10.0, -10.0, 10.0)  # large: frontiers in every direction
    agent = FrontierAgent(no_detection, GreedyPolicy(fixed=TURN_LEFT), FrontierAgentConfig(), ENV)
    actions = run(world, agent, 12 + 33)
    assert STOP not in actions
    ev = agent.episode_log()["events"]
    stuck = [e for e in ev if e["event"] == "stuck_blacklist"]
    assert len(stuck) == 1
    after = [e for e in ev if e["event"] == "frontier" and e["step"] >= stuck[0]["step"]]
    assert after and math.dist(after[0]["goal"], stuck[0]["frontier"]) > agent.config.blacklist_radius
    assert len(agent.blacklist) == 1 and math.dist(agent.blacklist[0].tolist(), stuck[0]["frontier"]) < 1e-2
