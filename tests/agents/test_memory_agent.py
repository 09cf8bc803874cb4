"""The memory agent's decision rules on scripted situations (no renderer, no localiser, no network)."""

import numpy as np
import pytest

from navbench.agents.base import episode_seed
from navbench.agents.memory_agent import MemoryAgent, MemoryAgentConfig, Recovery
from navbench.env.config import MOVE_FORWARD, STOP, TURN_LEFT, TURN_RIGHT, EnvConfig
from navbench.episodes.types import Episode
from navbench.localize.fusion import GoalCandidate

ENV = EnvConfig()
H = W = 224


class ScriptedPolicy:
    def __init__(self, action):
        self.action, self.hidden_resets, self.calls, self.last_goal, self.seeds = action, 0, 0, None, []

    def reset(self, i=None, seed=None):
        self.seeds.append(seed)

    def reset_hidden(self, i=None):
        self.hidden_resets += 1

    def act(self, depth, pointgoal):
        self.calls += 1
        self.last_goal = pointgoal[0].copy()
        return np.array([self.action])


def wall_depth(metres):
    """Normalised depth image of a fronto-parallel wall ``metres`` in front of the camera."""
    return np.full((H, W, 1), (metres - ENV.min_depth) / (ENV.max_depth - ENV.min_depth), np.float32)


def obs_at(depth, forward=0.0, right=0.0, compass=0.0):
    return {"depth": depth, "gps": np.array([forward, right], np.float32),
            "compass": np.array([compass], np.float32)}


def plane_points(z, y=0.88, half=0.3, n=11):
    """A square patch of points at world depth z (the agent starts at the origin facing -z)."""
    xs, ys = np.meshgrid(np.linspace(-half, half, n), np.linspace(y - half, y + half, n))
    return np.stack([xs.ravel(), ys.ravel(), np.full(xs.size, z)], axis=1)


EPISODE = Episode("0", "houses/val/house_008.glb", [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], object_category="chair")


def make_agent(candidates, action=MOVE_FORWARD, **cfg):
    policy = ScriptedPolicy(action)
    agent = MemoryAgent(lambda ep: candidates, policy, MemoryAgentConfig(**cfg), ENV)
    agent.reset(EPISODE)
    return agent, policy


def cand(points):
    return GoalCandidate(centre=points.mean(axis=0), points=points, keyframe_ids=(0,), score=1.0)


def test_visibility_on_synthetic_depth():
    agent, _ = make_agent([cand(plane_points(-2.0))])
    depth = agent.depth_metres(obs_at(wall_depth(2.0)))
    on_wall = plane_points(-2.0)
    behind = plane_points(-3.0)      # hidden behind the wall: depth disagrees by 1 m
    just_off = plane_points(-2.2)    # within the 0.3 m tolerance
    vis, n = agent.visibility(on_wall, depth, np.zeros(3), 0.0)
    assert n == len(on_wall) and len(vis) == len(on_wall)
    vis, n = agent.visibility(behind, depth, np.zeros(3), 0.0)
    assert n == len(behind) and len(vis) == 0
    assert len(agent.visibility(just_off, depth, np.zeros(3), 0.0)[0]) == len(just_off)
    # turned 180 deg the points are behind the camera: none in view
    assert agent.visibility(on_wall, depth, np.zeros(3), np.pi)[1] == 0


def test_each_episode_reseeds_the_policy_from_the_run_seed_and_the_episode():
    # a policy that draws its actions (navbench run --agent memory --decoding sample) then draws the same
    # actions for an episode whichever worker, slot or order it runs in
    policy = ScriptedPolicy(MOVE_FORWARD)
    agent = MemoryAgent(lambda ep: [cand(plane_points(-6.0))], policy, MemoryAgentConfig(), ENV, seed=3)
    other = Episode("1", EPISODE.scene_id, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], object_category="chair")
    for ep in (EPISODE, other, EPISODE):
        agent.reset(ep)
    assert policy.seeds == [episode_seed(3, EPISODE), episode_seed(3, other), episode_seed(3, EPISODE)]
    assert episode_seed(3, EPISODE) != episode_seed(3, other) != episode_seed(4, other)


def test_stops_when_close_and_visible():
    pts = plane_points(-0.7)
    agent, policy = make_agent([cand(pts)], action=TURN_LEFT)
    assert agent.act(obs_at(wall_depth(0.7))) == STOP
    assert policy.calls == 0
    assert agent.episode_log()["events"][-1]["event"] == "stop"


def test_stop_test_counts_the_cloud_in_view_even_when_the_goal_point_is_not():
    # The goal is the target's nearest point, here beside the camera's field of view (85 deg to the
    # right); the rest of the target is in plain view. The STOP test is the share of in-view points
    # confirmed visible, not whether the goal point itself is in the image.
    side = np.array([[0.6, 0.88, -0.05]])
    agent, policy = make_agent([cand(np.vstack([plane_points(-0.7), side]))], action=TURN_LEFT)
    np.testing.assert_allclose(agent.goal, side[0])
    assert agent.act(obs_at(wall_depth(0.7))) == STOP
    assert policy.calls == 0


def test_close_but_hidden_does_not_stop_and_stop_override_is_bounded():
    pts = plane_points(-0.85)
    agent, policy = make_agent([cand(pts)], action=STOP)
    hidden = wall_depth(0.5)  # something 0.35 m in front of the target hides it
    actions = [agent.act(obs_at(hidden)) for _ in range(7)]
    assert actions[:5] == [MOVE_FORWARD] * 5 and actions[5] == STOP
    assert sum(e["event"] == "stop_override" for e in agent.episode_log()["events"]) == 5


def test_stop_radius_grows_for_goals_the_camera_cannot_see_from_close():
    # A picture high on a wall (1.88-1.92 m; camera at 0.88 m, vertical half-FOV 39.5 deg) is out of view
    # closer than ~1.21 m, so the 0.9 m radius alone could never see it pass the visibility test.
    high = plane_points(-1.3, y=1.9, half=0.02, n=3)
    agent, _ = make_agent([cand(high)], action=TURN_LEFT)
    assert agent.fov_distance() == pytest.approx(1.0 / np.tan(np.radians(39.5)), abs=0.01)
    assert agent.stop_radius() == pytest.approx(agent.fov_distance() + 0.15)
    assert agent.act(obs_at(wall_depth(1.3))) == STOP
    # the same distance to a goal at camera height keeps the 0.9 m radius
    agent, _ = make_agent([cand(plane_points(-1.3, half=0.02, n=3))], action=TURN_LEFT)
    assert agent.stop_radius() == pytest.approx(0.9)
    assert agent.act(obs_at(wall_depth(1.3))) == TURN_LEFT


def test_stop_radius_follows_the_target_point_nearest_camera_height_not_the_goal():
    # A tall target (0.1-1.9 m, a fridge): whichever of its points is the goal, part of it stays in view
    # down to 0 m, so the radius stays 0.9 m even when the goal is its top edge.
    tall = plane_points(-1.3, y=1.0, half=0.9, n=7)
    agent, _ = make_agent([cand(tall)], action=TURN_LEFT)
    agent.goal = tall[np.argmax(tall[:, 1])]
    assert agent.goal[1] == pytest.approx(1.9)
    assert agent.stop_radius() == pytest.approx(0.9)
    assert agent.act(obs_at(wall_depth(1.3))) == TURN_LEFT
    # a picture whose lower edge is 1.5 m: the radius comes from that edge, not from its top
    picture = plane_points(-1.3, y=1.7, half=0.2, n=5)
    agent, _ = make_agent([cand(picture)], action=TURN_LEFT)
    assert agent.stop_radius() == pytest.approx((1.5 - 0.88) / np.tan(np.radians(39.5)) + 0.15, abs=0.01)


def test_recent_sighting_stands_in_while_the_target_is_below_the_view():
    rug = plane_points(-1.6, y=0.02, half=0.05, n=3)  # floor-level: out of view closer than ~1.04 m
    agent, policy = make_agent([cand(rug)], action=MOVE_FORWARD)
    assert agent.act(obs_at(wall_depth(1.6))) == MOVE_FORWARD  # seen, but still too far
    # 0.9 m on, nothing of the rug is in view; its sighting a step ago stands: STOP
    assert agent.act(obs_at(wall_depth(1.6), forward=0.9)) == STOP
    assert agent.episode_log()["events"][-1]["event"] == "stop"
    # never seen: the same position does not stop (the policy's action goes through)
    agent, policy = make_agent([cand(rug)], action=MOVE_FORWARD)
    assert agent.act(obs_at(wall_depth(1.6), forward=0.9)) == MOVE_FORWARD
    # seen too long ago: no longer stands in
    agent, policy = make_agent([cand(rug)], action=TURN_LEFT, visibility_memory=3)
    agent.act(obs_at(wall_depth(1.6)))
    for _ in range(4):
        agent.act(obs_at(wall_depth(1.6), compass=np.pi))  # turned away
    assert agent.act(obs_at(wall_depth(1.6), forward=0.9)) == TURN_LEFT


def test_ablation_without_visibility_stop_stops_on_distance():
    agent, _ = make_agent([cand(plane_points(-0.85))], action=TURN_LEFT, visibility_stop=False)
    assert agent.act(obs_at(wall_depth(0.5))) == STOP


def test_goal_update_thresholds_far_and_near():
    # candidate cloud: a patch 4 m ahead; the initial goal is its nearest point (xz) to the start
    pts = plane_points(-4.0)
    agent, policy = make_agent([cand(pts)])
    g0 = agent.goal.copy()
    # far from the goal (> 2 m): visible points whose nearest is < 0.5 m from the goal -> no update
    agent.act(obs_at(wall_depth(4.0)))
    assert np.allclose(agent.goal, g0) and policy.hidden_resets == 0
    # now only the right-hand part of the patch is visible (the rest hidden by a nearer surface)
    depth = wall_depth(4.0)
    depth[:, : W // 2 + 30] = wall_depth(1.0)[:, : W // 2 + 30]
    agent.act(obs_at(depth))
    moved = np.hypot(*(agent.goal - g0)[[0, 2]])
    assert moved == 0.0 or moved >= 0.5  # a far goal moves only by >= 0.5 m
    # near the goal (< 2 m): a 0.1-0.5 m shift is enough
    agent2, policy2 = make_agent([cand(plane_points(-1.5))])
    g1 = agent2.goal.copy()
    depth = wall_depth(1.5)
    depth[:, : W // 2 + 20] = wall_depth(0.6)[:, : W // 2 + 20]  # hide the left and centre
    agent2.act(obs_at(depth))
    moved = np.hypot(*(agent2.goal - g1)[[0, 2]])
    assert 0.1 <= moved < 0.5 and policy2.hidden_resets == 1
    assert agent2.episode_log()["events"][0]["event"] == "goal_update"


def test_goal_out_of_view_is_only_replaced_by_a_nearer_point():
    from navbench.localize.geometry import project, world_to_camera
    from navbench.render.camera import camera_pose
    from navbench.scene.pose import quat_from_yaw

    # a floor-level patch 0.5-2.5 m ahead: its near edge (the initial goal) is below the field of view
    xs, zs = np.meshgrid(np.linspace(-0.3, 0.3, 7), np.linspace(-2.5, -0.5, 21))
    pts = np.stack([xs.ravel(), np.zeros(xs.size), zs.ravel()], axis=1)
    agent, policy = make_agent([cand(pts)])
    g0 = agent.goal.copy()
    # the depth the sensor would measure: the patch's own points where they project, 5 m elsewhere
    uv, z, in_view = project(pts, agent.K, world_to_camera(camera_pose(np.array([0, ENV.agent_height, 0]),
                                                                       quat_from_yaw(0.0))), W, H)
    depth = np.full((H, W), 5.0)
    depth[np.round(uv[in_view, 1]).astype(int), np.round(uv[in_view, 0]).astype(int)] = z[in_view]
    visible, _ = agent.visibility(pts, depth, np.zeros(3), 0.0)
    assert len(visible) > 0 and agent.visibility(g0[None], depth, np.zeros(3), 0.0, check_depth=False)[1] == 0
    agent.act(obs_at(((depth - 0.5) / 4.5).astype(np.float32)[..., None]))
    # the nearest visible point is > 0.5 m beyond the goal, which would move it; the goal is out of
    # view and the visible point farther, so the goal stays
    assert np.min(np.hypot(visible[:, 0] - g0[0], visible[:, 2] - g0[2])) >= 0.5
    assert np.array_equal(agent.goal, g0) and policy.hidden_resets == 0


def test_no_tracking_ablation_keeps_the_goal():
    agent, _ = make_agent([cand(plane_points(-1.5))], goal_tracking=False)
    g = agent.goal.copy()
    depth = wall_depth(1.5)
    depth[:, : W // 2 + 20] = wall_depth(0.6)[:, : W // 2 + 20]
    agent.act(obs_at(depth))
    assert np.array_equal(agent.goal, g)


def test_stuck_switches_to_next_candidate_at_most_max_switches():
    far = [cand(plane_points(-6.0 - 2 * k) + np.array([3.0 * k, 0, 0])) for k in range(7)]
    agent, policy = make_agent(far, action=TURN_LEFT)
    empty = wall_depth(0.5)  # nothing visible; the agent turns in place and never progresses
    for _ in range(400):
        agent.act(obs_at(empty))
    switches = [e for e in agent.episode_log()["events"] if e["event"] == "switch"]
    assert len(switches) == 4 and agent.current == 4
    assert policy.hidden_resets >= 4


def test_route_guidance_follows_the_memorys_route_once_when_stuck_then_drives_to_the_target():
    route = np.array([[2.0, 0.0, 0.0], [2.0, 0.0, -6.0]])  # right, then forward along the far side
    calls = []

    def route_path(position, candidate):
        calls.append(position.copy())
        return route

    policy = ScriptedPolicy(TURN_LEFT)
    agent = MemoryAgent(lambda ep: [cand(plane_points(-6.0))], policy,
                        MemoryAgentConfig(recovery_probes=0), ENV, route_path=route_path)
    agent.reset(EPISODE)
    empty = wall_depth(0.5)  # the target is never in view
    for _ in range(31):
        agent.act(obs_at(empty))
    assert [e["event"] for e in agent.episode_log()["events"]] == ["stuck", "route"]
    assert len(calls) == 1 and np.linalg.norm(policy.last_goal[:1] - 2.0) < 1e-5  # 2 m to the first point
    agent.act(obs_at(empty, right=1.8))  # within detour_reached of it: on to the next, 6 m ahead
    assert policy.last_goal[0] == pytest.approx(np.hypot(0.2, 6.0), abs=1e-4)
    agent.act(obs_at(empty, forward=5.8, right=2.0))  # the last point: back to the target itself
    assert agent.episode_log()["events"][-1]["event"] == "route_end"
    assert policy.last_goal[0] == pytest.approx(np.hypot(2.0, 0.2), abs=1e-4)
    for _ in range(31):  # stuck again on the same target: no second route, the usual recovery
        agent.act(obs_at(empty, forward=5.8, right=2.0))
    assert [e["event"] for e in agent.episode_log()["events"]][-2:] == ["stuck", "recover"] and len(calls) == 1
    # with no route known, stuck means recovery
    agent = MemoryAgent(lambda ep: [cand(plane_points(-6.0))], ScriptedPolicy(TURN_LEFT),
                        MemoryAgentConfig(recovery_probes=0), ENV, route_path=lambda p, c: np.zeros((0, 3)))
    agent.reset(EPISODE)
    for _ in range(31):
        agent.act(obs_at(empty))
    assert [e["event"] for e in agent.episode_log()["events"]] == ["stuck", "recover"]


def test_oscillation_counts_as_stuck():
    class Alternating(ScriptedPolicy):
        def act(self, depth, pointgoal):
            self.calls += 1
            return np.array([2 + self.calls % 2])  # LEFT, RIGHT, LEFT, ...

    far = [cand(plane_points(-6.0)), cand(plane_points(-8.0) + np.array([3.0, 0, 0]))]
    agent = MemoryAgent(lambda ep: far, Alternating(0), MemoryAgentConfig(), ENV)
    agent.reset(EPISODE)
    for _ in range(10):
        agent.act(obs_at(wall_depth(0.5)))
    assert any(e["event"] == "oscillating" for e in agent.episode_log()["events"])
    assert agent.current == 1


def test_opportunistic_stop_on_another_candidate():
    near_other = cand(plane_points(-0.7))
    far_first = cand(plane_points(-5.0) + np.array([4.0, 0, 0]))
    agent, _ = make_agent([far_first, near_other], action=MOVE_FORWARD)
    # candidates are sorted by distance from the start, so force the far one first
    agent.candidates, agent._clouds = [far_first, near_other], [far_first.points, near_other.points]
    agent.current, agent.goal = 0, far_first.points[0]
    assert agent.act(obs_at(wall_depth(0.7))) == STOP
    assert agent.episode_log()["events"][-1]["event"] == "opportunistic_stop"


def test_no_candidates_stops_and_says_so():
    agent, _ = make_agent([])
    assert agent.act(obs_at(wall_depth(2.0))) == STOP
    assert agent.episode_log()["events"][0]["event"] == "no_candidates"


def test_pointgoal_to_goal_is_polar_in_agent_frame():
    agent, policy = make_agent([cand(plane_points(-3.0))])
    agent.act(obs_at(wall_depth(0.5)))
    rho, theta = policy.last_goal
    assert rho == pytest.approx(np.hypot(*agent.goal[[0, 2]]), abs=1e-5)
    assert abs(theta) < 0.2  # the patch is straight ahead


def test_stuck_is_reported_once_per_window_when_no_candidate_is_left():
    agent, _ = make_agent([cand(plane_points(-6.0))], action=TURN_LEFT)
    for _ in range(95):
        agent.act(obs_at(wall_depth(0.5)))
    stuck = [e for e in agent.episode_log()["events"] if e["event"] == "stuck"]
    assert len(stuck) == 3  # steps 31, 61, 91: one per 30-step window


def open_on_the_right():
    d = wall_depth(0.6)
    d[:, 2 * W // 3:] = wall_depth(4.0)[:, 2 * W // 3:]
    return d


def test_recovery_when_stuck_with_no_candidate_left():
    # the fixed manoeuvre (the agent is pinned: with probing on, its refused step would turn on)
    agent, policy = make_agent([cand(plane_points(-6.0))], action=TURN_LEFT, recovery_probes=0)
    actions = [agent.act(obs_at(open_on_the_right())) for _ in range(37)]
    # stuck at step 31 (no progress, no candidate to switch to): turn 90 deg towards the open side,
    # two steps forward, with fresh policy memory; then the policy drives again
    assert actions[:30] == [TURN_LEFT] * 30
    assert actions[30:35] == [TURN_RIGHT] * 3 + [MOVE_FORWARD] * 2
    assert actions[35:] == [TURN_LEFT] * 2
    assert policy.calls == 32 and policy.hidden_resets == 1
    recover = [e for e in agent.episode_log()["events"] if e["event"] == "recover"]
    assert recover == [{"step": 31, "event": "recover", "turn": "right"}]


def test_stuck_again_where_the_last_recovery_started_backs_out_the_way_it_came():
    def run():
        agent, _ = make_agent([cand(plane_points(-6.0))], action=TURN_LEFT, recovery_probes=0)
        # one step to the right (+x, heading -90 deg), then pinned there whatever the agent does
        actions = [agent.act(obs_at(open_on_the_right()))]
        actions += [agent.act(obs_at(open_on_the_right(), right=0.25)) for _ in range(65)]
        return agent, actions

    agent, actions = run()
    assert actions[30:35] == [TURN_RIGHT] * 3 + [MOVE_FORWARD] * 2  # first time: towards the open side
    assert actions[35:60] == [TURN_LEFT] * 25
    # stuck again on the same spot: face +90 deg (back along the last move) and step forward
    assert actions[60:65] == [TURN_LEFT] * 3 + [MOVE_FORWARD] * 2
    recover = [e for e in agent.episode_log()["events"] if e["event"] == "recover"]
    assert recover == [{"step": 31, "event": "recover", "turn": "right"},
                       {"step": 61, "event": "recover", "turn": "back", "turns": 3}]


def drive(agent, steps, free_after_right_turns):
    """Step ``agent`` with a scripted body: a FORWARD moves 0.25 m only once the agent has turned right
    at least ``free_after_right_turns`` times in all (the one free heading), otherwise it is refused."""
    right, moved, actions = 0, 0.0, []
    obs = obs_at(open_on_the_right())
    for _ in range(steps):
        a = agent.act(obs)
        actions.append(a)
        right += a == TURN_RIGHT
        if a == MOVE_FORWARD and right >= free_after_right_turns:
            moved += 0.25
        obs = obs_at(open_on_the_right(), right=moved)
    return actions


def test_a_refused_recovery_step_turns_on_until_a_heading_moves():
    agent, _ = make_agent([cand(plane_points(-6.0))], action=TURN_LEFT)
    actions = drive(agent, 40, free_after_right_turns=5)
    assert actions[:30] == [TURN_LEFT] * 30  # the policy turns in place: stuck at step 31
    # 90 deg towards the open side, FORWARD refused; 30 deg more, refused; 30 deg more, it moves: the
    # rest of the manoeuvre's two FORWARDs follows on that heading, then the policy drives again
    R, F = TURN_RIGHT, MOVE_FORWARD
    assert actions[30:39] == [R, R, R, F, R, F, R, F, F]
    assert actions[39] == TURN_LEFT
    probes = [e for e in agent.episode_log()["events"] if e["event"] == "recover_probe"]
    assert [e["left"] for e in probes] == [10, 9]


def test_probing_is_bounded_and_without_probes_the_manoeuvre_is_fixed():
    R, F = TURN_RIGHT, MOVE_FORWARD
    agent, _ = make_agent([cand(plane_points(-6.0))], action=TURN_LEFT, recovery_probes=2)
    actions = drive(agent, 41, free_after_right_turns=99)  # nothing ever moves
    assert actions[30:39] == [R, R, R, F, R, F, R, F, F] and actions[39:] == [TURN_LEFT] * 2
    agent, _ = make_agent([cand(plane_points(-6.0))], action=TURN_LEFT, recovery_probes=0)
    actions = drive(agent, 37, free_after_right_turns=99)
    assert actions[30:35] == [R, R, R, F, F] and actions[35:] == [TURN_LEFT] * 2


def test_a_probe_is_judged_even_after_a_candidate_switch_cleared_the_position_history():
    agent, _ = make_agent([cand(plane_points(-6.0))], action=TURN_LEFT)
    agent.recovery = Recovery(queue=[MOVE_FORWARD], turn=TURN_RIGHT, probes_left=3)
    assert agent.act(obs_at(open_on_the_right())) == MOVE_FORWARD  # the probe
    agent.watch.restart()  # as _switch does, e.g. on a rejected target earlier in the next call
    assert agent.act(obs_at(open_on_the_right())) == TURN_RIGHT  # refused: the next heading
    assert agent.act(obs_at(open_on_the_right())) == MOVE_FORWARD


def test_stop_still_wins_during_recovery():
    agent, _ = make_agent([cand(plane_points(-0.7))], action=TURN_LEFT)
    agent.recovery = Recovery(queue=[TURN_RIGHT, MOVE_FORWARD])
    assert agent.act(obs_at(wall_depth(0.7))) == STOP  # target within reach and visible: STOP first


class ScriptedDetector:
    """Finds the goal at ``points`` (world) on the frames listed in ``hits`` (1-based calls), else nothing."""
    sensors = ("semantic",)

    def __init__(self, points, hits=None):
        self.points, self.hits, self.calls = points, hits, 0

    def reset(self, episode):
        self.calls = 0

    def __call__(self, observations, pose):
        self.calls += 1
        return self.points if self.hits is None or self.calls in self.hits else np.zeros((0, 3))


def make_verified_agent(candidates, detector, action=TURN_LEFT, **cfg):
    policy = ScriptedPolicy(action)
    agent = MemoryAgent(lambda ep: candidates, policy, MemoryAgentConfig(**cfg), ENV, verify=detector)
    agent.reset(EPISODE)
    return agent, policy


def test_verification_confirms_a_stop_on_the_detected_target():
    pts = plane_points(-0.7)
    agent, _ = make_verified_agent([cand(pts)], ScriptedDetector(pts + 0.1))
    assert agent.sensors == ("depth", "semantic")
    assert [agent.act(obs_at(wall_depth(0.7))) for _ in range(3)] == [TURN_LEFT, TURN_LEFT, STOP]  # 3 checks
    # a detection elsewhere (another object, 2 m away) does not confirm it
    agent, _ = make_verified_agent([cand(pts)], ScriptedDetector(pts + np.array([2.0, 0, 0])))
    assert agent.act(obs_at(wall_depth(0.7))) != STOP
    assert agent.episode_log()["events"][-1]["event"] == "verify_failed"


def test_a_target_failing_verification_is_rejected_for_the_next_candidate():
    false_near = cand(plane_points(-0.7))
    true_far = cand(plane_points(-5.0) + np.array([3.0, 0, 0]))
    detector = ScriptedDetector(true_far.points)  # the goal is only ever found at the far candidate
    agent, policy = make_verified_agent([false_near, true_far], detector, action=STOP)
    first = agent.act(obs_at(wall_depth(0.7)))
    assert first == TURN_LEFT  # the policy's STOP is not taken on an unverified target: look again
    assert agent.act(obs_at(wall_depth(0.7))) != STOP  # second failed check: rejected, switch
    events = [e["event"] for e in agent.episode_log()["events"]]
    assert events.count("verify_failed") == 2
    switch = [e for e in agent.episode_log()["events"] if e["event"] == "switch"]
    assert switch and switch[0]["reason"] == "rejected" and agent.current == 1
    # the rejected candidate is no longer an opportunistic STOP either
    assert agent.act(obs_at(wall_depth(0.7))) != STOP


def test_one_missed_detection_does_not_reject_a_true_target():
    pts = plane_points(-0.7)
    agent, _ = make_verified_agent([cand(pts)], ScriptedDetector(pts, hits={2}), verify_min_checks=1)
    assert agent.act(obs_at(wall_depth(0.7))) != STOP  # missed once
    assert agent.act(obs_at(wall_depth(0.7))) == STOP  # found on the next view: one of two checks
    assert agent.episode_log()["events"][-1]["event"] == "stop"


def test_one_lucky_detection_is_not_enough_to_stop():
    # A detector that fires on a wrong object in one frame (a noise profile's wrong view): with one
    # check needed the agent STOPs on it; with the default three it looks again and the check fails.
    pts = plane_points(-0.7)
    agent, _ = make_verified_agent([cand(pts)], ScriptedDetector(pts, hits={1}), verify_min_checks=1)
    assert agent.act(obs_at(wall_depth(0.7))) == STOP
    agent, _ = make_verified_agent([cand(pts)], ScriptedDetector(pts, hits={1}))
    actions = [agent.act(obs_at(wall_depth(0.7))) for _ in range(3)]
    assert STOP not in actions
    failed = [e["step"] for e in agent.episode_log()["events"] if e["event"] == "verify_failed"]
    assert failed == [3]  # judged once, on the third look (1 of 3 checks)


def test_a_target_out_of_view_stops_on_the_checks_made_while_it_was_seen():
    rug = plane_points(-1.6, y=0.02, half=0.05, n=3)
    detector = ScriptedDetector(rug)
    agent, _ = make_verified_agent([cand(rug)], detector, action=MOVE_FORWARD)
    assert agent.act(obs_at(wall_depth(1.6))) == MOVE_FORWARD  # seen and confirmed from 1.6 m
    assert detector.calls == 1
    assert agent.act(obs_at(wall_depth(1.6), forward=0.9)) == STOP  # below the view now: the check stands
    assert detector.calls == 1 and agent.episode_log()["events"][-1]["event"] == "stop"
    # a detector that never confirmed it: no STOP on the remembered sighting
    agent, _ = make_verified_agent([cand(rug), cand(plane_points(-6.0))], ScriptedDetector(np.zeros((0, 3))),
                                   action=MOVE_FORWARD)
    agent.act(obs_at(wall_depth(1.6)))
    assert agent.act(obs_at(wall_depth(1.6), forward=0.9)) != STOP


def test_with_no_candidate_left_an_unverified_target_is_not_a_stop():
    # e.g. seen through a thin wall: the agent keeps driving to it (the policy may find the way round)
    pts = plane_points(-0.7)
    agent, _ = make_verified_agent([cand(pts)], ScriptedDetector(np.zeros((0, 3))), action=STOP)
    actions = [agent.act(obs_at(wall_depth(0.7))) for _ in range(4)]
    assert STOP not in actions and agent.current == 0
    assert not any(e["event"] == "switch" for e in agent.episode_log()["events"])


def cand_seen_from(points, views):
    return GoalCandidate(centre=points.mean(axis=0), points=points, keyframe_ids=tuple(range(len(views))),
                         score=1.0, view_positions=np.asarray(views, float))


def test_a_failed_check_sends_the_policy_to_the_nearest_view_of_the_target():
    # Seen "through a wall" (the depth test passes, the detector finds nothing): the policy is sent to
    # where the memory saw the target from, failures there do not count, and the detour ends on arrival.
    pts = plane_points(-0.7)
    views = [[3.0, 0.88, 3.0], [1.0, 0.88, 1.5], [0.2, 0.88, 0.2]]  # the last is where the agent stands
    other = cand(plane_points(-6.0))
    agent, policy = make_verified_agent([cand_seen_from(pts, views), other], ScriptedDetector(np.zeros((0, 3))),
                                        action=MOVE_FORWARD)
    assert agent.act(obs_at(wall_depth(0.7))) == MOVE_FORWARD
    detour = [e for e in agent.episode_log()["events"] if e["event"] == "detour"]
    assert detour and detour[0]["reason"] == "verify_failed" and detour[0]["goal"] == [1.0, 0.0, 1.5]
    assert policy.last_goal[0] == pytest.approx(np.hypot(1.0, 1.5))  # the policy drives to the view
    for _ in range(3):  # still beside the wall: no more failures counted, no rejection
        agent.act(obs_at(wall_depth(0.7)))
    assert agent.sighting.verify_fails == 1 and agent.current == 0
    agent.act(obs_at(wall_depth(3.0), forward=-1.4, right=0.9))  # arrived at the view
    assert agent.episode_log()["events"][-1] == {"step": 5, "event": "detour_end", "reason": "reached"}
    # back to the target (seen lately, so the point short of it): 2.28 m away, less the 0.6 m standoff
    assert agent.detour.goal is None and policy.last_goal[0] == pytest.approx(np.hypot(0.9, 2.1) - 0.6, abs=0.02)


def test_a_policy_stop_beside_a_target_not_seen_lately_starts_a_detour():
    # Up against the wall the target is behind: hidden, never seen, the policy STOPs on its point.
    pts = plane_points(-0.85)
    agent, policy = make_agent([cand_seen_from(pts, [[0.0, 0.88, -2.0]])], action=STOP)
    assert agent.act(obs_at(wall_depth(0.5))) == MOVE_FORWARD  # the STOP is overridden
    assert agent.episode_log()["events"][-1]["event"] == "detour"
    agent.act(obs_at(wall_depth(0.5)))
    assert policy.last_goal[0] == pytest.approx(2.0)
    # without views the plain override rule alone
    agent, _ = make_agent([cand(pts)], action=STOP)
    agent.act(obs_at(wall_depth(0.5)))
    assert all(e["event"] != "detour" for e in agent.episode_log()["events"])


def test_goal_is_placed_on_the_measured_surface():
    # The stored cloud sits 0.2 m in front of the wall the sensor sees at 1.8 m (depth noise in the
    # memory): the points pass the 0.3 m visibility test and the goal (within 2 m: updated on a 0.1 m
    # move) lands on the wall itself.
    agent, _ = make_agent([cand(plane_points(-1.6))], action=MOVE_FORWARD)
    depth = agent.depth_metres(obs_at(wall_depth(1.8)))
    snapped, n = agent.visibility(agent._clouds[0], depth, np.zeros(3), 0.0, snap=True)
    assert n == len(snapped) == 121
    assert np.allclose(snapped[:, 2], -1.8, atol=0.02)
    assert agent.act(obs_at(wall_depth(1.8))) == MOVE_FORWARD
    assert agent.goal[2] == pytest.approx(-1.8, abs=0.02)



def test_policy_drives_to_a_point_short_of_a_seen_target_then_to_the_target():
    # A picture on the wall 3 m ahead: while it is seen and the agent is outside the STOP radius, the
    # policy gets the goal pulled goal_standoff back (a point in front of the wall it can reach).
    agent, policy = make_agent([cand(plane_points(-3.0, half=0.05, n=3))], action=MOVE_FORWARD)
    agent.act(obs_at(wall_depth(3.0)))
    assert policy.last_goal[0] == pytest.approx(3.0 - MemoryAgentConfig().goal_standoff, abs=1e-4)
    assert policy.last_goal[1] == pytest.approx(0.0)
    # never seen (hidden behind something nearer): the true goal, wherever it leads the policy
    agent, policy = make_agent([cand(plane_points(-3.0, half=0.05, n=3))], action=MOVE_FORWARD)
    agent.act(obs_at(wall_depth(1.0)))
    assert policy.last_goal[0] == pytest.approx(3.0, abs=1e-4)
    # inside the STOP radius but hidden: the true goal again (no pulled point behind the agent)
    agent, policy = make_agent([cand(plane_points(-0.85, half=0.05, n=3))], action=MOVE_FORWARD)
    agent.sighting.last_pass = 0
    assert agent.act(obs_at(wall_depth(0.5))) == MOVE_FORWARD
    assert policy.last_goal[0] == pytest.approx(0.85, abs=1e-4)


def test_a_policy_stop_far_from_a_visible_target_is_overridden():
    # The STOP test is distance and visibility: a visible target 2 m away is not an arrival.
    agent, _ = make_agent([cand(plane_points(-2.0))], action=STOP)
    assert agent.act(obs_at(wall_depth(2.0))) == MOVE_FORWARD
    assert agent.episode_log()["events"][-1]["event"] == "stop_override"


def test_after_the_overrides_a_stop_on_a_refuted_target_becomes_a_look_around():
    # Hidden up close (the overrides run out) while the detector's recent checks said "not it": no STOP.
    pts = plane_points(-0.85)
    agent, _ = make_verified_agent([cand(pts)], ScriptedDetector(np.zeros((0, 3))), action=STOP)
    agent.sighting.checks = [(0, False), (0, False)]
    hidden = wall_depth(0.5)
    actions = [agent.act(obs_at(hidden)) for _ in range(7)]
    assert actions[:5] == [MOVE_FORWARD] * 5 and actions[5:] == [TURN_LEFT] * 2
    assert agent.episode_log()["events"][-1]["reason"] == "refuted"
    # no checks at all (nothing to refute it): the override bound holds and the STOP goes through
    agent, _ = make_verified_agent([cand(pts)], ScriptedDetector(np.zeros((0, 3))), action=STOP)
    assert [agent.act(obs_at(hidden)) for _ in range(6)][5] == STOP


def test_candidates_are_ordered_by_route_length_then_straight_line():
    near_line = cand(plane_points(-2.0))  # nearest in a straight line, a long route (behind a wall)
    near_route = cand(plane_points(-4.0))
    no_route = cand(plane_points(-3.0))  # route unknown (inf): after the routed ones, by straight line
    routes = {id(near_line): 12.0, id(near_route): 4.5, id(no_route): np.inf}
    calls = []

    def route(position, cands):
        calls.append(np.asarray(position).copy())
        return np.array([routes[id(c)] for c in cands])

    agent = MemoryAgent(lambda ep: [near_line, no_route, near_route], ScriptedPolicy(MOVE_FORWARD),
                        MemoryAgentConfig(), ENV, route=route)
    agent.reset(EPISODE)
    assert [id(c) for c in agent.candidates] == [id(near_route), id(near_line), id(no_route)]
    assert agent.episode_log()["routes"] == [4.5, 12.0, None]
    np.testing.assert_allclose(calls[0], EPISODE.start_position)
    # Without a route the straight line decides, as before.
    agent, _ = make_agent([near_line, no_route, near_route])
    assert [id(c) for c in agent.candidates] == [id(near_line), id(no_route), id(near_route)]


def test_a_switch_reorders_the_untried_candidates_by_route_from_where_the_agent_is():
    a, b, c = (cand(plane_points(-2.0 - k)) for k in range(3))
    from_start = {id(a): 1.0, id(b): 2.0, id(c): 3.0}
    from_elsewhere = {id(a): 9.0, id(b): 8.0, id(c): 1.0}

    def route(position, cands):
        table = from_start if np.allclose(position, 0.0) else from_elsewhere
        return np.array([table[id(x)] for x in cands])

    agent = MemoryAgent(lambda ep: [a, b, c], ScriptedPolicy(TURN_LEFT), MemoryAgentConfig(), ENV, route=route)
    agent.reset(EPISODE)
    assert agent.candidates[0] is a
    empty = wall_depth(0.5)
    for _ in range(40):  # stuck turning in place, 1 m to the right of the start
        agent.act(obs_at(empty, right=1.0))
    assert agent.switches == 1 and agent.candidates[agent.current] is c


def test_on_imagenav_it_drives_to_the_estimated_goal_camera_and_takes_the_policys_stop():
    from navbench.localize.imagegoal import CameraEstimate

    class Localiser:
        def __call__(self, episode, subtask=0):
            raise AssertionError("an ImageNav goal is not an object query")

        def image_goal(self, episode):
            return CameraEstimate(np.array([0.0, 0.88, -3.0]), 0.0, 0.9, [(4, 0.8)])

    episode = Episode("1", "houses/val/house_008.glb", [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0])
    policy = ScriptedPolicy(MOVE_FORWARD)
    agent = MemoryAgent(Localiser(), policy, MemoryAgentConfig(), ENV)
    agent.reset(episode)
    assert agent.act(obs_at(wall_depth(4.0))) == MOVE_FORWARD
    assert policy.last_goal == pytest.approx([3.0, 0.0], abs=1e-6)  # 3 m straight ahead (the floor point)
    assert agent.episode_log()["goal_camera"] == [0.0, 0.88, -3.0] and agent.decision() == ["goal", 0, 0.0, -3.0]
    policy.action = STOP
    assert agent.act(obs_at(wall_depth(4.0), forward=2.9)) == STOP  # no visibility test, no detector: its STOP
    assert agent.episode_log()["events"][-1]["event"] == "stop"


def test_approach_plan_walks_onto_a_point_within_a_few_centimetres():
    from navbench.agents.memory_agent import approach_plan

    rng = np.random.default_rng(0)
    for _ in range(50):
        p, yaw = np.zeros(3), float(rng.uniform(-np.pi, np.pi))
        target = np.array([rng.uniform(-1.5, 1.5), 0.0, rng.uniform(-1.5, 1.5)])
        taken = 0
        while plan := approach_plan(p, yaw, target, 0.25, np.radians(30)):
            for a in plan:
                taken += 1
                if a == MOVE_FORWARD:
                    p = p + 0.25 * np.array([-np.sin(yaw), 0.0, -np.cos(yaw)])
                yaw += np.radians(30) * (a == TURN_LEFT) - np.radians(30) * (a == TURN_RIGHT)
            assert taken < 40
        assert np.hypot(*(p - target)[[0, 2]]) < 0.08


def _walk_before_a_wall(agent, steps: int) -> tuple[int, float, float]:
    """Step ``agent`` (facing a plain wall 2 m ahead, no object in view) until it STOPs or ``steps`` run out,
    moving it as its actions say; its last action and where it stands (x, z)."""
    x, z, yaw = 0.0, 0.0, 0.0
    ids = np.full((H, W, 1), -1, np.int32)
    rgb = np.full((H, W, 3), 200, np.uint8)
    action = STOP
    for _ in range(steps):
        obs = {**obs_at(wall_depth(2.0), forward=-z, right=x, compass=yaw), "semantic": ids, "rgb": rgb}
        action = agent.act(obs)
        if action == STOP:
            break
        if action == MOVE_FORWARD:
            x, z = x - 0.25 * np.sin(yaw), z - 0.25 * np.cos(yaw)
        yaw += np.radians(30) * (action == TURN_LEFT) - np.radians(30) * (action == TURN_RIGHT)
    return action, x, z


def test_on_imagenav_with_look_round_it_searches_its_views_and_tries_the_next_place_when_they_disagree():
    from navbench.localize.imagegoal import CameraEstimate

    class Localiser:
        def __init__(self):
            self.searched = []  # (number of points, camera position) of each search

        def image_goal(self, episode):
            return CameraEstimate(np.array([0.0, 0.88, -1.0]), 0.0, 0.9, [(4, 0.8)],
                                  [(np.array([1.0, 0.88, -1.0]), 0.5, 0.8)], goal=object())

        def refine_image_goal(self, estimate, points, ids, colours, position, yaw):
            self.searched.append((len(points), position.copy()))
            if len(self.searched) == 1:  # the first place's views do not show the goal image
                return CameraEstimate(np.array([0.1, 0.88, -1.1]), 0.0, 0.5, [])
            return CameraEstimate(np.array([1.3, 0.88, -1.2]), 0.5, 0.97, [])

    episode = Episode("1", "houses/val/house_008.glb", [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0])
    localiser = Localiser()
    agent = MemoryAgent(localiser, ScriptedPolicy(STOP), MemoryAgentConfig(image_look_round=True, image_tries=2),
                        ENV)
    agent.reset(episode)
    action, x, z = _walk_before_a_wall(agent, 100)
    assert action == STOP
    events = [e["event"] for e in agent.episode_log()["events"]]
    assert events.count("look_round") == 2 and events.count("image_match") == 2
    # every view of a full circle is searched, round each place's estimated camera
    assert [n for n, _ in localiser.searched] == [12 * (H // 2) * (W // 2)] * 2
    np.testing.assert_allclose(localiser.searched[1][1], [1.0, 0.88, -1.0])
    assert np.hypot(x - 1.3, z + 1.2) < 0.08  # walked onto the second place's pose


def test_on_imagenav_with_look_round_it_walks_onto_the_pose_its_views_give_whatever_their_score():
    from navbench.localize.imagegoal import CameraEstimate

    class Localiser:
        def image_goal(self, episode):
            return CameraEstimate(np.array([0.0, 0.88, -1.0]), 0.0, 0.9, [(4, 0.8)],
                                  [(np.array([1.0, 0.88, -1.0]), 0.5, 0.8)], goal=object())

        def refine_image_goal(self, estimate, points, ids, colours, position, yaw):
            return CameraEstimate(np.array([0.2, 0.88, -0.6]), 0.0, 0.3, [])  # far under image_accept

    episode = Episode("1", "houses/val/house_008.glb", [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0])
    agent = MemoryAgent(Localiser(), ScriptedPolicy(STOP), MemoryAgentConfig(image_look_round=True), ENV)
    agent.reset(episode)
    action, x, z = _walk_before_a_wall(agent, 60)
    assert action == STOP and [e["event"] for e in agent.episode_log()["events"]].count("look_round") == 1
    assert np.hypot(x - 0.2, z + 0.6) < 0.08  # one place by default: no alternative is tried
