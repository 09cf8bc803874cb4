"""``memory``: the memory-over-maps ObjectNav agent. Localise first, then drive straight there.

At reset the agent asks the localiser (over the scene's cached keyframe memory; no map is built)
for goal candidates for the episode's goal text, sorts them by distance from the start, and drives
to the nearest with the PointNav policy. The distance is the route length over the memory's keyframe
poses where there is one (``route``: :class:`~navbench.localize.route.KeyframeRoutes`, the way the
pre-scan walked), else the straight line (xz). Each step (:meth:`MemoryAgent.act`) it:

1. **looks**: recovers its world pose from the episode's start pose plus GPS+compass (as Habitat
   agents do); projects the target's cloud into the current depth image (a point is *visible* when
   ``|z - depth| < visible_depth_tol``) and, with goal tracking, moves the goal onto the nearest
   visible point when it moved far enough; checks the target with the detector (``verify``) in every
   frame that sees it from near;
2. **arrives**: STOPs within the STOP radius (grown for targets far above or below the camera) when
   enough in-view points are visible (or were in the last ``visibility_memory`` steps while the target
   is out of view because the agent is too close) and the detector's recent checks confirm the target;
   a failed verdict sends the policy to a place the memory saw the target from (a *detour*) and,
   repeated, rejects the target for the next candidate;
3. STOPs **opportunistically** beside another candidate that passes the same tests;
4. **recovers**: plays out a queued recovery manoeuvre, probing other headings while its step is refused;
5. **unsticks**: stuck (little progress in ``stuck_window`` steps) or oscillating, it first follows the
   memory's route to the target (*guidance*, once per target), then **switches** to the next nearest
   candidate, and with none left starts a recovery (turn to the more open side, or back out the way it
   came when stuck again where the last one started);
6. **navigates**: acts with the policy on the goal's polar coordinates (a detour's view position, a
   route's next point, or the goal pulled back by ``goal_standoff`` while the target is in sight); a
   policy STOP on a target that fails the STOP test is overridden.

Every decision is appended to ``episode_log()`` and lands in ``episodes.jsonl``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from navbench.agents.base import episode_seed, fov_leave_distance, log_value, nearest_to_height, xz_dist, xz_dists
from navbench.agents.common import Detector, ObjectNavAgentBase, ObjectNavAgentConfig, StepPolicy, StuckWatch, subsample
from navbench.agents.storeys import Storeys
from navbench.env.config import MOVE_FORWARD, STOP, TURN_LEFT, TURN_RIGHT, EnvConfig
from navbench.env.sensors import pointgoal_polar
from navbench.episodes.goat import SUBTASK_STOP, GoatEpisode
from navbench.episodes.instance_imagenav import InstanceImageEpisode
from navbench.episodes.types import Episode
from navbench.localize.fusion import GoalCandidate
from navbench.localize.geometry import backproject
from navbench.localize.grouping import nearest_distances
from navbench.render.camera import camera_pose
from navbench.scene.layers import LayeredNav
from navbench.scene.navigability import NavGridConfig
from navbench.scene.pose import quat_from_yaw, wrap_angle, yaw_towards


@dataclass(frozen=True)
class MemoryAgentConfig(ObjectNavAgentConfig):
    # Goal tracking: the goal moves to the nearest visible point of the target when that is this far
    # from it (goal_update_near within near_radius of the goal, where the policy needs it precise).
    goal_update_far: float = 0.5
    goal_update_near: float = 0.1
    near_radius: float = 2.0
    visibility_memory: int = 20  # steps a passed visibility test is remembered while nothing is in view
    oscillation_window: int = 8  # this many alternating turns in a row is oscillation
    max_switches: int = 4
    # Recovery (stuck or oscillating with no candidate left, a state the policy does not leave on its
    # own): forget the policy's memory, turn recovery_turns x 30 deg towards the more open half of the
    # depth image, step forward recovery_forward times. Stuck again within stuck_progress of where the
    # last recovery started, the open side is not where the body is free: turn to face opposite the
    # heading of the last step that moved the agent (the way it came is free) instead.
    recovery_turns: int = 3
    recovery_forward: int = 2
    # A recovery step that moves less than probe_min_move was refused: turn once more the same way and
    # try again, up to recovery_probes times (11: every 30 deg heading), then step forward the rest of
    # recovery_forward on the heading that moved. Agents wedged beside furniture have few free headings.
    recovery_probes: int = 11
    probe_min_move: float = 0.1
    # Verification on arrival: frames that see the target from within near_radius are segmented for the
    # goal text by the perception backend's segmenter; a check passes when the detection lies within
    # verify_radius of the target's cloud. A STOP needs a majority of the checks of the last
    # visibility_memory steps, at least verify_min_checks of them while the target is in view (one
    # wrong-object detection must not decide); failing verify_attempts times rejects the target.
    # This catches a localiser's false detection, and a target seen "through" a thin wall.
    verify_attempts: int = 2
    verify_radius: float = 0.5
    verify_min_checks: int = 3
    # While the target was seen lately and the agent is outside the STOP radius, the policy is given the
    # goal pulled this far back towards the agent (xz): a goal on a wall reads to a PointNav policy as
    # "behind the wall", and it turns away to look for a way round.
    goal_standoff: float = 0.6
    # Detours: on a failed check, or a policy STOP beside a target not seen lately (the agent is on the
    # wrong side of a wall), the policy drives to the nearest supporting keyframe's camera position (a
    # navigable place with a line of sight to the target) until within detour_reached of it or the
    # detector confirms the target; each position once, at most max_detours per candidate. Guidance
    # hands the policy the memory's route points one by one, passing those within detour_reached.
    detour_reached: float = 0.5
    max_detours: int = 3
    # ImageNav with image_look_round, under a localiser that searches live views (oracle perception): within
    # image_scan_within of an estimated goal camera (or at the policy's STOP) the agent turns a full circle,
    # searches its views joined to the memory for the goal camera round there, and walks onto the pose found
    # when its score reaches image_accept; below that it tries the estimate's next alternative (at most
    # image_tries places), and with none left goes to the best-scoring pose it found. One place by default: on
    # the first 20 val episodes of each house the alternatives never held the goal where the first place's
    # views scored low, and a wrong place's views often outscored the right one's.
    image_look_round: bool = False
    image_scan_within: float = 0.5
    image_accept: float = 0.9
    image_tries: int = 1
    image_approach_steps: int = 40  # most actions of the walk onto the pose found
    goal_tracking: bool = True  # ablation: off = drive to the candidate's initial goal point
    visibility_stop: bool = True  # ablation: off = STOP on distance alone


@dataclass
class Sighting:
    """What the agent knows of the current target: when it last passed the visibility test, and the
    detector's checks on it."""
    last_pass: int = -10**9  # step of the last passed visibility test
    checks: list[tuple[int, bool]] = field(default_factory=list)  # (step, detector confirmed)
    verify_fails: int = 0  # failed arrival verdicts


@dataclass
class Detour:
    """A detour to a supporting view of the current target."""
    goal: np.ndarray | None = None  # the policy's goal while detouring
    used: list[np.ndarray] = field(default_factory=list)  # view positions already detoured to


@dataclass
class Guidance:
    """Following the memory's route to the current target."""
    waypoints: list[np.ndarray] = field(default_factory=list)  # route positions still to pass
    started: bool = False  # once per target


@dataclass
class Recovery:
    """The recovery manoeuvre: queued actions, and probing headings while a step is refused."""
    queue: list[int] = field(default_factory=list)
    turn: int = TURN_LEFT  # the manoeuvre's turn, repeated while its FORWARD is refused
    probes_left: int = 0
    # where the probing FORWARD was taken from (None: nothing to judge); kept apart from the stuck
    # watch's positions, which a candidate switch clears
    probe_from: np.ndarray | None = None
    started_at: np.ndarray | None = None  # where the last recovery started


@dataclass
class ImageGoalSearch:
    """ImageNav: the places the goal image may have been taken, and what the agent found at those it visited."""
    estimate: object  # the localiser's CameraEstimate
    places: list[tuple[np.ndarray, float]]  # (floor point, yaw) of each place to try, in order
    tried: int = 0  # index of the place being driven to or looked round
    phase: str = "drive"  # drive | scan | approach
    frames: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=list)  # live (points, ids, rgb)
    found: list[tuple[float, np.ndarray, float]] = field(default_factory=list)  # (score, floor point, yaw)
    target: np.ndarray | None = None  # the floor point the agent walks onto
    approach_steps: int = 0
    plan: list[int] = field(default_factory=list)  # the approach's actions still to take


@dataclass
class Frame:
    """One step's view of the current target (:meth:`MemoryAgent._look`)."""
    observations: dict[str, np.ndarray]
    position: np.ndarray
    yaw: float
    depth: np.ndarray  # metres
    dist: float  # xz, to the goal
    seen_now: bool  # the target passes the visibility test in this frame
    at_stop: bool  # inside the STOP radius with the target visible (or visibility_stop off)


# (position, candidates) -> route length to each candidate, inf where unknown (SceneLocalizer.route_lengths)
RouteLengths = Callable[[np.ndarray, Sequence[GoalCandidate]], np.ndarray]
# (position, candidate) -> (K, 3) positions along the route to it, (0, 3) if none (SceneLocalizer.route_path)
RoutePath = Callable[[np.ndarray, GoalCandidate], np.ndarray]
# nav config -> the joined surfaces of the scene when its memory spans storeys, else None (SceneLocalizer.surfaces)
Surfaces = Callable[[NavGridConfig], LayeredNav | None]


def nearest_first(cands: Sequence[GoalCandidate], position: np.ndarray,
                  route: RouteLengths | None) -> tuple[list[int], np.ndarray]:
    """Indices of ``cands`` nearest first from ``position``, and their route lengths: by route length,
    then (no route, inf) the straight line (xz). A straight line through a wall can be a long walk (the
    desk behind the bedroom wall); the pre-scan's walk is a path that exists."""
    route_m = np.full(len(cands), np.inf)
    if route is not None and len(cands) > 1:
        route_m = np.asarray(route(position, cands), np.float64)
    straight = [xz_dist(c.centre, position) for c in cands]
    return sorted(range(len(cands)), key=lambda j: (float(route_m[j]), straight[j])), route_m


def approach_plan(position: np.ndarray, yaw: float, target: np.ndarray, step: float, turn: float,
                  most: int = 4, slack: float = 0.02) -> list[int]:
    """The actions of the plan of at most two straight legs (whole ``turn`` angles, then up to ``most`` ``step``s
    forward) that ends nearest ``target`` (xz), the fewest actions among plans ending within ``slack`` of the
    nearest; empty when none ends a centimetre nearer than ``position``. Forward is (-sin yaw, -cos yaw), a left
    turn adds ``turn`` to the yaw."""
    n = round(2 * math.pi / turn)
    turns = np.arange(-(n // 2) + 1, n // 2 + 1)  # signed whole turns from the current heading, left positive
    heading = yaw + turns * turn
    moves = np.arange(most + 1)
    leg = (step * moves[None, :, None] * np.stack([-np.sin(heading), -np.cos(heading)], axis=1)[:, None, :]
           ).reshape(-1, 2)  # (turns * moves, 2): leg i turns turns[i // len(moves)], moves moves[i % len(moves)]
    k = np.repeat(turns, len(moves))
    m = np.tile(moves, len(turns))
    offset = np.asarray(target, np.float64)[[0, 2]] - np.asarray(position, np.float64)[[0, 2]]
    dist = np.linalg.norm(offset - (leg[:, None, :] + leg[None, :, :]), axis=2)
    between = np.abs((k[None, :] - k[:, None] + n // 2) % n - n // 2)  # turns from the first leg's heading
    cost = np.where(m[:, None] > 0, np.abs(k) + m, 0)[:, None] + np.where(
        m[None, :] > 0, np.where(m[:, None] > 0, between, np.abs(k)[None, :]) + m[None, :], 0)
    if dist.min() > float(np.linalg.norm(offset)) - 0.01:
        return []
    i, j = np.unravel_index(np.argmin(np.where(dist <= dist.min() + slack, cost, np.iinfo(np.int64).max)), dist.shape)
    plan: list[int] = []
    heading_k = 0
    for leg_k, leg_m in ((int(k[i]), int(m[i])), (int(k[j]), int(m[j]))):
        if leg_m == 0:
            continue
        d = (leg_k - heading_k + n // 2) % n - n // 2
        plan += [TURN_LEFT if d > 0 else TURN_RIGHT] * abs(d) + [MOVE_FORWARD] * leg_m
        heading_k = leg_k
    return plan


def log_route(metres: float) -> float | None:
    """A candidate's route length for the log (None where the memory knows no route)."""
    return log_value(metres) if np.isfinite(metres) else None


class MemoryAgent(ObjectNavAgentBase):
    """The memory agent (module docstring). ``verify`` is the detector that checks a target before a STOP,
    ``route``/``route_path`` the memory's route lengths and route points; without them (unit tests) the
    agent stops unchecked and orders candidates by straight-line distance. ``surfaces`` gives the scene's
    joined walkable surfaces when the memory spans several storeys: the agent then knows the height of the
    surface it stands on, ranks candidates and routes to them over those surfaces, and drives towards a
    candidate on another storey along the shortest path, over the stairs or ramp (:mod:`navbench.agents.storeys`)."""

    config: MemoryAgentConfig

    def __init__(self, localize: Callable[[Episode], list[GoalCandidate]], policy: StepPolicy,
                 config: MemoryAgentConfig = MemoryAgentConfig(), env_config: EnvConfig = EnvConfig(),
                 verify: Detector | None = None, route: RouteLengths | None = None,
                 route_path: RoutePath | None = None, surfaces: Surfaces | None = None, seed: int = 0):
        super().__init__(policy, config, env_config, seed)
        self.localize, self.verify, self.route, self.route_path = localize, verify, route, route_path
        self.surfaces = surfaces
        self.storeys: Storeys | None = None
        self.point: np.ndarray | None = None  # ImageNav: the estimated goal camera's floor point
        self.floor = 0.0  # height of the surface the agent stands on (the camera is agent_height above it)
        # The policy and the visibility test read depth only; the detector adds the image it segments.
        self.sensors: tuple[str, ...] = ("depth",) + (tuple(verify.sensors) if verify is not None else ())

    # ----------------------------------------------------------------------------------- episode
    def reset(self, episode: Episode) -> None:
        start = np.asarray(episode.start_position, np.float64)
        self._episode = episode
        self.point: np.ndarray | None = None
        self.search: ImageGoalSearch | None = None
        if self._is_imagenav(episode):
            # ImageNav: the goal is where the image was taken; drive there with the policy, then (searching live
            # views) look round and walk onto the goal camera, or take the policy's STOP
            est = self.localize.image_goal(episode)
            self.point = np.array([est.position[0], start[1], est.position[2]])
            self._subtasks, self.goal = 0, self.point
            self._begin(episode, {"goal_camera": [round(float(v), 3) for v in est.position],
                                  "goal_yaw": round(est.yaw, 3), "match": round(est.score, 3),
                                  "keyframes": est.keyframes, "events": [], **getattr(self.localize, "last", {})})
            if self.config.image_look_round and getattr(est, "goal", None) is not None \
                    and hasattr(self.localize, "refine_image_goal"):
                places = [(self.point, est.yaw)] + [(np.array([p[0], start[1], p[2]]), yaw)
                                                    for p, yaw, _ in est.alternatives]
                self.search = ImageGoalSearch(est, places[:self.config.image_tries])
            return
        self.subtask = 0  # a GOAT-Bench episode's active subtask (each answered from the same memory)
        self._subtasks = len(episode.tasks) if isinstance(episode, GoatEpisode) else 0
        found, unjoined = self._localize(start)
        if self._subtasks:
            log = {"subtasks": [{"subtask": 0, **found}], "events": []}
        else:
            log = {"candidates": found.pop("candidates"), "routes": found.pop("routes"), "events": [], **found}
        self._begin(episode, log)
        self._start_target(start, unjoined)

    def _is_imagenav(self, episode: Episode) -> bool:
        """A PointNav-v1 episode without a category, given to a localiser that estimates goal cameras: ImageNav
        (the memory agent reads no point goals)."""
        return (not isinstance(episode, (GoatEpisode, InstanceImageEpisode)) and episode.object_category is None
                and hasattr(self.localize, "image_goal"))

    def _drive_to_point(self, observations: dict[str, np.ndarray]) -> int:
        """ImageNav: the policy's action towards the estimated goal camera's floor point; its STOP taken, or,
        searching live views, the look round there (:meth:`_search_image_goal`)."""
        self.step += 1
        position, yaw = self._pose(observations)
        assert self.point is not None
        if self.search is not None:
            return self._search_image_goal(observations, position, yaw)
        goal = pointgoal_polar(self.point, position, yaw)
        action = int(self.policy.act(observations["depth"][None], goal[None])[0])
        if action == STOP:
            self._event("stop", distance=xz_dist(position, self.point))
        return action

    def _search_image_goal(self, observations: dict[str, np.ndarray], position: np.ndarray, yaw: float) -> int:
        """Drive to the place being tried; within ``image_scan_within`` (or at the policy's STOP) turn a full
        circle keeping each view; search them for the goal camera; accept the pose found or try the next place;
        then walk onto the accepted pose (:meth:`_approach`)."""
        cfg, s = self.config, self.search
        assert s is not None and self.point is not None
        if s.phase == "drive":
            goal = pointgoal_polar(self.point, position, yaw)
            action = int(self.policy.act(observations["depth"][None], goal[None])[0])
            if action != STOP and xz_dist(position, self.point) >= cfg.image_scan_within:
                return action
            s.phase, s.frames = "scan", []
            self._event("look_round", place=s.tried, distance=xz_dist(position, self.point))
        if s.phase == "scan":
            s.frames.append(self._live_view(observations, position, yaw))
            if len(s.frames) < round(360 / self.env_config.turn_angle_deg):
                return TURN_LEFT
            self._judge_place(position)
            if s.phase == "drive":  # on to the next place (the policy is asked once this step)
                return self._search_image_goal(observations, position, yaw)
        return self._approach(observations, position, yaw)

    def _live_view(self, observations: dict[str, np.ndarray], position: np.ndarray, yaw: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """This frame's depth back-projected (every other pixel) with its instance ids and colours."""
        c = self.env_config
        depth = np.where(observations["depth"][..., 0] > 0, self.depth_metres(observations), 0.0)
        mask = np.zeros(depth.shape, bool)
        mask[::2, ::2] = True
        mask &= (depth > c.min_depth) & (depth < c.max_depth)
        cam = camera_pose(position + np.array([0.0, c.agent_height, 0.0]), quat_from_yaw(yaw))
        points = backproject(depth, mask, self.K, cam, min_depth=c.min_depth, max_depth=c.max_depth)
        return points, observations["semantic"][..., 0][mask].astype(np.int32), observations["rgb"][mask][:, :3]

    def _judge_place(self, position: np.ndarray) -> None:
        """Search the look round's views for the goal camera near the place tried; accept the pose, or drive to
        the next place, or (none left) approach the best pose found."""
        cfg, s = self.config, self.search
        assert s is not None
        points, ids, rgb = (np.concatenate(parts) for parts in zip(*s.frames))
        s.frames = []
        place, yaw = s.places[s.tried]
        camera = place + np.array([0.0, self.env_config.agent_height, 0.0])
        found = self.localize.refine_image_goal(s.estimate, points, ids, rgb, camera, yaw)
        floor_point = np.array([found.position[0], position[1], found.position[2]])
        s.found.append((float(found.score), floor_point, float(found.yaw)))
        self._event("image_match", place=s.tried, score=float(found.score), goal=floor_point)
        if found.score >= cfg.image_accept or s.tried + 1 >= len(s.places):
            best = max(range(len(s.found)), key=lambda j: s.found[j][0])
            s.target, s.phase = s.found[best][1], "approach"
            self.point = s.target
            self._event("image_goal", place=best, score=s.found[best][0], goal=s.target)
            return
        s.tried += 1
        self.point = s.places[s.tried][0]
        s.phase = "drive"
        self.policy.reset_hidden()

    def _approach(self, observations: dict[str, np.ndarray], position: np.ndarray, yaw: float) -> int:
        """Walk onto the accepted floor point: the policy while it is far, then plans of at most two straight legs
        (:func:`approach_plan`), each taken whole, until none ends nearer; then STOP."""
        s, c = self.search, self.env_config
        assert s is not None and s.target is not None
        if xz_dist(position, s.target) > 2 * self.config.image_scan_within and s.approach_steps == 0:
            goal = pointgoal_polar(s.target, position, yaw)
            action = int(self.policy.act(observations["depth"][None], goal[None])[0])
            if action != STOP:
                return action
        s.approach_steps += 1
        if not s.plan:  # (re)planned when the last plan is done: a step against a wall may not have moved
            s.plan = approach_plan(position, yaw, s.target, c.forward_step, math.radians(c.turn_angle_deg))
        if not s.plan or s.approach_steps > self.config.image_approach_steps:
            self._event("stop", distance=xz_dist(position, s.target))
            return STOP
        return s.plan.pop(0)

    def _localize(self, position: np.ndarray) -> tuple[dict, int]:
        """Candidates for the active goal, nearest first from ``position``: what the log keeps of them, and how
        many stand on a storey nothing joins to this one."""
        cfg = self.config
        episode = self._episode
        cands = self.localize(episode, self.subtask) if self._subtasks else self.localize(episode)
        nav = self.surfaces(self.env_config.nav_grid_config()) if self.surfaces is not None else None
        self.storeys = None if nav is None else Storeys(nav, position, self.env_config.forward_step,
                                                        self.env_config.turn_angle_deg)
        self.climbing = False
        self.floor = float(position[1]) if self.storeys is None else self.storeys.height
        unjoined = 0
        if self.storeys is not None and cands:
            # Over the joined surfaces a route length is exact: a candidate they do not reach stands on a storey
            # nothing joins to the start's, and is no goal of this episode.
            reach = np.isfinite(self.storeys.lengths(position, cands))
            unjoined = int((~reach).sum())
            cands = [c for c, r in zip(cands, reach) if r]
        order, route = nearest_first(cands, position, self._route())
        self.candidates = [cands[j] for j in order]
        rng = np.random.default_rng(0)  # deterministic subsample of each cloud
        self._clouds = [subsample(c.points, cfg.max_projected_points, rng) for c in self.candidates]
        return ({"candidates": [[round(float(v), 3) for v in c.centre] for c in self.candidates],
                 "routes": [log_route(route[j]) for j in order], **getattr(self.localize, "last", {})}, unjoined)

    def _start_target(self, position: np.ndarray, unjoined: int) -> None:
        """Forget the previous goal's state: drive to the nearest candidate from ``position``."""
        cfg = self.config
        self.current = 0
        self.switches = 0
        self.rejected: set[int] = set()  # id() of candidates that failed verification
        self.overrides = 0  # policy STOPs overridden in a row
        self.move_yaw: float | None = None  # heading of the last step that moved the agent
        self.watch = StuckWatch(cfg.stuck_window, cfg.stuck_progress, cfg.oscillation_window)
        self.recovery = Recovery()
        self._new_target()
        self.goal = self._initial_goal(position) if self.candidates else None
        # no candidate on the agent's surface while the memory holds some elsewhere: look round this storey
        self.tour = self.storeys.tour(position) if self.storeys is not None and unjoined and not self.candidates else []
        if unjoined:
            self._event("unjoined_candidates", count=unjoined, explore=len(self.tour))
        if self.verify is not None:
            episode = self._episode
            if self._subtasks or isinstance(episode, InstanceImageEpisode):  # check for what the localiser asked
                self.verify.reset(episode, getattr(self.localize, "prompt", None))
            else:
                self.verify.reset(episode)

    def _next_subtask(self, position: np.ndarray) -> int:
        """Where the agent would STOP on a GOAT-Bench subtask: SUBTASK_STOP, then the next subtask's goal from
        the same memory, with the per-goal state reset and the policy reseeded."""
        self._event("subtask_stop", subtask=self.subtask)
        self.subtask += 1
        if self.subtask < self._subtasks:
            self.policy.reset(seed=[*episode_seed(self.seed, self._episode), self.subtask])
            found, unjoined = self._localize(position)
            self.log["subtasks"].append({"subtask": self.subtask, "step": self.step, **found})
            self._start_target(position, unjoined)
        return SUBTASK_STOP

    def decision(self) -> list | None:
        """What the agent drives to now, for the run's trace: [mode, candidate, x, z] (dm), mode one of
        goal | detour | route | recover."""
        if self.goal is None:
            return None
        if self.point is not None:
            return ["goal", 0, round(float(self.point[0]), 1), round(float(self.point[2]), 1)]
        if self.recovery.queue or self.recovery.probes_left:
            mode, point = "recover", self.goal
        elif self.detour.goal is not None:
            mode, point = "detour", self.detour.goal
        elif self.guidance.waypoints:
            mode, point = "route", self.guidance.waypoints[0]
        else:
            mode, point = "goal", self.goal
        return [mode, self.current, round(float(point[0]), 1), round(float(point[2]), 1)]

    def _route(self) -> RouteLengths | None:
        return self.storeys.lengths if self.storeys is not None else self.route

    def _new_target(self) -> None:
        """Forget what was known of the previous target."""
        self.sighting, self.detour, self.guidance = Sighting(), Detour(), Guidance()

    def _initial_goal(self, position: np.ndarray) -> np.ndarray:
        cloud = self._clouds[self.current]
        if len(cloud) == 0:
            return np.asarray(self.candidates[self.current].centre, np.float64)
        return cloud[int(np.argmin(xz_dists(cloud, position)))]

    # --------------------------------------------------------------------------------- perception
    def _height_point(self) -> np.ndarray:
        """The current target's point nearest the camera height (the goal point if it has no cloud)."""
        cloud = self._clouds[self.current]
        return nearest_to_height(cloud, self.floor + self.env_config.agent_height) if len(cloud) else self.goal

    def fov_distance(self) -> float:
        """xz distance below which all of the current target is above or below the vertical field of view."""
        return fov_leave_distance(self._height_point(), self.floor + self.env_config.agent_height,
                                  self._tan_half_vfov)

    def stop_radius(self) -> float:
        """The current target's STOP radius (``stop_radius``, grown for targets far above or below the camera)."""
        return self.stop_radius_for(self._height_point()[None], self.floor)

    # -------------------------------------------------------------------------------------- act
    def act(self, observations: dict[str, np.ndarray]) -> int:
        """One step: look, then the first phase with an action decides (module docstring); on a GOAT-Bench
        episode a STOP closes the subtask (SUBTASK_STOP) and the next one starts."""
        if self.point is not None:
            return self._drive_to_point(observations)
        action = self._act(observations)
        if action == STOP and self._subtasks:
            return self._next_subtask(self._position)
        return action

    def _act(self, observations: dict[str, np.ndarray]) -> int:
        self.step += 1
        position, yaw = self._pose(observations)
        if self.storeys is not None:
            position = self.storeys.track(position)
            self.floor = self.storeys.height
        self._position = position
        if self.watch.positions and xz_dist(position, self.watch.positions[-1]) > 0.05:
            self.move_yaw = yaw_towards(self.watch.positions[-1], position)
        self.watch.add(position)
        if self.goal is None and self.tour:
            return self._explore(observations, position, yaw)
        if self.goal is None:
            self._event("no_candidates")
            return STOP
        frame = self._look(observations, position, yaw)
        for phase in (self._arrive, self._opportunistic_stop, self._recover, self._unstick):
            action = phase(frame)
            if action is not None:
                return action
        return self._navigate(frame)

    def _explore(self, observations: dict[str, np.ndarray], position: np.ndarray, yaw: float) -> int:
        """Drive the policy round the points of ``tour`` (passing those within ``detour_reached``, or where
        stuck), round again at its end, never STOPping: the episode ends at the step limit."""
        if xz_dist(position, self.tour[0]) < self.config.detour_reached or self.watch.stuck() is not None:
            self.tour.append(self.tour.pop(0))
            self.watch.restart()
            self.policy.reset_hidden()
            self._event("explore", goal=self.tour[0])
        goal = pointgoal_polar(self.tour[0], position, yaw)
        action = int(self.policy.act(observations["depth"][None], goal[None])[0])
        action = TURN_LEFT if action == STOP else action
        self.watch.taken(action)
        return action

    # ------------------------------------------------------------------------------------- look
    def _look(self, observations: dict[str, np.ndarray], position: np.ndarray, yaw: float) -> Frame:
        """Perceive the current target: track the goal onto it, test its visibility, check it with the
        detector from near, and end a detour that reached its view or confirmed the target."""
        cfg, s = self.config, self.sighting
        depth = self.depth_metres(observations)
        visible, in_view = self.visibility(self._clouds[self.current], depth, position, yaw, snap=True)
        if cfg.goal_tracking and len(visible):
            self._track_goal(visible, depth, position, yaw)
        dist = xz_dist(position, self.goal)
        visible_ok = seen_now = self.passes(visible, in_view)
        if visible_ok:
            s.last_pass = self.step
        elif in_view == 0 and dist < self.fov_distance() and self.step - s.last_pass <= cfg.visibility_memory:
            visible_ok = True  # too close to see the target at all: its recent sighting stands
        # The verdict is the majority of the checks of the last visibility_memory steps: one view's missed
        # or mistaken detection does not decide, and a STOP on a remembered sighting rests on them.
        confirmed_now = False
        if self.verify is not None and seen_now and dist < max(cfg.near_radius, self.stop_radius()):
            confirmed_now = self._detects(observations, position, yaw, self._clouds[self.current])
            s.checks.append((self.step, confirmed_now))
        if self.detour.goal is not None:
            if xz_dist(position, self.detour.goal) < cfg.detour_reached:
                self._end_detour("reached")
            elif confirmed_now or (seen_now and self.verify is None):
                self._end_detour("target_in_view")
        at_stop = dist < self.stop_radius() and (visible_ok or not cfg.visibility_stop)
        return Frame(observations, position, yaw, depth, dist, seen_now, at_stop)

    def _track_goal(self, visible: np.ndarray, depth: np.ndarray, position: np.ndarray, yaw: float) -> None:
        """Move the goal to the nearest visible point of the target when it moved far enough from it."""
        cfg = self.config
        nearest = visible[int(np.argmin(xz_dists(visible, position)))]
        moved = xz_dist(nearest, self.goal)
        near = xz_dist(position, self.goal) < cfg.near_radius
        # A goal that has left the view (below the camera's field of view close to a low object) can be
        # neither confirmed nor refuted: keep it unless the new point is nearer. Replacing it by the
        # nearest point still in view would move it away as the agent approaches a rug.
        goal_in_view = self.visibility(self.goal[None], depth, position, yaw, check_depth=False)[1] > 0
        closer = xz_dist(nearest, position) < xz_dist(self.goal, position)
        if moved >= (cfg.goal_update_near if near else cfg.goal_update_far) and (goal_in_view or closer):
            self.goal = nearest
            self.policy.reset_hidden()
            self._event("goal_update", goal=nearest, moved=moved)

    # ------------------------------------------------------------------------------ arrive / verify
    def _arrive(self, f: Frame) -> int | None:
        """STOP inside the STOP radius when the detector's verdict passes; a failed verdict counts towards
        rejecting the target, except on a detour (the agent is known to be on the wrong side)."""
        if not f.at_stop:
            return None
        verdict = self._verdict(f.seen_now)
        if verdict:
            self._event("stop", candidate=self.current, distance=f.dist)
            return STOP
        if verdict is False and self.detour.goal is None:
            self._verify_failed(f.position, f.dist)
        return None

    def _verify_failed(self, position: np.ndarray, dist: float) -> None:
        s = self.sighting
        s.verify_fails += 1
        self._event("verify_failed", candidate=self.current, distance=dist)
        # The check also fails through a thin wall (points just behind it pass the depth test): look
        # from where the memory saw the target, and judge it there on fresh checks.
        if self._start_detour(position, "verify_failed"):
            s.checks = []
        # With no other candidate the agent keeps driving to this one: the policy may still find the
        # way round to the side the target is seen from.
        if s.verify_fails >= self.config.verify_attempts and self.current + 1 < len(self.candidates):
            self.rejected.add(id(self.candidates[self.current]))
            self._switch(position, reason="rejected")

    def _recent_checks(self) -> list[bool]:
        """The detector's verdicts on the current target over the last ``visibility_memory`` steps."""
        return [ok for step, ok in self.sighting.checks if self.step - step <= self.config.visibility_memory]

    def _verdict(self, seen_now: bool) -> bool | None:
        """The arrival check: True (stop), False (failed), or None (passing so far on fewer than
        ``verify_min_checks`` checks while the target is in view: look again before stopping)."""
        if self.verify is None:
            return True
        recent = self._recent_checks()
        ok = bool(recent) and 2 * sum(recent) >= len(recent)  # a tie stands (no worse than no check)
        if ok and seen_now and len(recent) < self.config.verify_min_checks:
            return None
        return ok

    def _refuted(self) -> bool:
        """Whether most of the recent detector checks on the current target failed (none: not refuted)."""
        recent = self._recent_checks()
        return bool(recent) and 2 * sum(recent) < len(recent)

    def _detects(self, observations: dict[str, np.ndarray], position: np.ndarray, yaw: float,
                 cloud: np.ndarray) -> bool:
        """Whether the detector finds the goal text in this frame within ``verify_radius`` of ``cloud``."""
        if self.verify is None or not len(cloud):
            return True
        found = self.verify(observations, (position, yaw))
        if not len(found):
            return False
        # nearest detected point to the cloud, both subsampled to ~500 points (cheap, and enough)
        r = self.config.verify_radius
        tree = cKDTree(cloud[:: max(1, len(cloud) // 500)])
        return bool(nearest_distances(found[:: max(1, len(found) // 500)], tree, r).min() < r)

    def _opportunistic_stop(self, f: Frame) -> int | None:
        """STOP beside another (unrejected) candidate that passes the visibility test and the detector."""
        for j, cloud in enumerate(self._clouds):
            if j == self.current or not len(cloud) or id(self.candidates[j]) in self.rejected:
                continue
            if np.min(xz_dists(cloud, f.position)) < self.config.stop_radius:
                vis_j, n_j = self.visibility(cloud, f.depth, f.position, f.yaw)
                if self.passes(vis_j, n_j) and self._detects(f.observations, f.position, f.yaw, cloud):
                    self._event("opportunistic_stop", candidate=j)
                    return STOP
        return None

    # ------------------------------------------------------------------------------------ recover
    def _recover(self, f: Frame) -> int | None:
        """The next action of a recovery manoeuvre under way. A probing FORWARD is judged on the next
        call from the GPS: refused, the manoeuvre turns on to the next heading and tries again."""
        r = self.recovery
        if r.probe_from is not None:
            moved = xz_dist(f.position, r.probe_from)
            r.probe_from = None
            if moved < self.config.probe_min_move and r.probes_left > 0:
                r.probes_left -= 1
                r.queue = [r.turn, MOVE_FORWARD] + r.queue
                self._event("recover_probe", left=r.probes_left)
            else:
                r.probes_left = 0  # moved (or out of tries): the rest of the manoeuvre as queued
        if not r.queue:
            return None
        action = r.queue.pop(0)
        if action == MOVE_FORWARD and r.probes_left > 0:
            r.probe_from = f.position
        return action

    def _start_recovery(self, depth: np.ndarray, position: np.ndarray, yaw: float) -> None:
        """Queue a recovery: towards the more open side, or back the way the agent came when stuck again
        where the last recovery started."""
        cfg, r = self.config, self.recovery
        again = r.started_at is not None and xz_dist(position, r.started_at) < cfg.stuck_progress
        r.started_at = position
        self.watch.turns.clear()
        self.policy.reset_hidden()
        if again and self.move_yaw is not None:
            # Turns are exact multiples of the turn angle, so the reverse heading is reachable exactly.
            n = round(wrap_angle(self.move_yaw + math.pi - yaw) / math.radians(self.env_config.turn_angle_deg))
            turn = TURN_LEFT if n > 0 else TURN_RIGHT  # TURN_LEFT raises the yaw
            r.queue = [turn] * abs(n) + [MOVE_FORWARD] * cfg.recovery_forward
            r.turn, r.probes_left = turn, cfg.recovery_probes
            self._event("recover", turn="back", turns=n)
            return
        third = depth.shape[1] // 3
        left, right = float(depth[:, :third].mean()), float(depth[:, -third:].mean())
        turn = TURN_LEFT if left >= right else TURN_RIGHT
        r.queue = [turn] * cfg.recovery_turns + [MOVE_FORWARD] * cfg.recovery_forward
        r.turn, r.probes_left = turn, cfg.recovery_probes
        self._event("recover", turn="left" if turn == TURN_LEFT else "right")

    # ------------------------------------------------------------------------------------ unstick
    def _unstick(self, f: Frame) -> int | None:
        """Stuck or oscillating: follow the memory's route to the target (once per target), else switch
        to the next candidate, else start a recovery (whose first action this returns)."""
        if not self._stuck_or_oscillating():
            return None
        if self.guidance.waypoints:
            # stuck on the way: the route's leg is not one this policy drives; the usual remedies follow
            self.guidance.waypoints = []
            self._event("route_end", reason="stuck")
        if self._start_guidance(f.position):
            return None
        if self.switches < self.config.max_switches and self.current + 1 < len(self.candidates):
            self._switch(f.position)
            return None
        self._start_recovery(f.depth, f.position, f.yaw)
        return self.recovery.queue.pop(0)

    def _stuck_or_oscillating(self) -> bool:
        progress = self.watch.stuck()
        if progress is not None:
            self._event("stuck", progress=progress)
            return True
        if self.watch.oscillating():
            self._event("oscillating")
            return True
        return False

    def _start_guidance(self, position: np.ndarray) -> bool:
        """Follow the memory's route to the current target: the keyframe positions along the pre-scan's
        walk, which leads round the wall a PointNav policy turns about in front of. Once per target."""
        g = self.guidance
        route_path = self.storeys.path if self.storeys is not None else self.route_path
        if route_path is None or g.started or self.detour.goal is not None:
            return False
        g.started = True
        path = np.asarray(route_path(position, self.candidates[self.current]), np.float64).reshape(-1, 3)
        if not len(path):
            return False
        g.waypoints = list(path)
        self.policy.reset_hidden()
        self._event("route", waypoints=len(path),
                    length=float(np.sum(np.linalg.norm(np.diff(np.vstack([position, path])[:, [0, 2]], axis=0),
                                                       axis=1))))
        return True

    def _start_detour(self, position: np.ndarray, reason: str) -> bool:
        """Send the policy to the nearest unused supporting view of the current target (config comment)."""
        cfg, d = self.config, self.detour
        if d.goal is not None or len(d.used) >= cfg.max_detours:
            return False
        views = np.asarray(self.candidates[self.current].view_positions, np.float64).reshape(-1, 3)
        dists = xz_dists(views, position)
        ok = [i for i in np.argsort(dists, kind="stable") if dists[i] >= cfg.detour_reached
              and all(xz_dist(views[i], u) >= cfg.detour_reached for u in d.used)]
        if not ok:
            return False
        x, _, z = views[ok[0]]
        d.goal = np.array([x, position[1], z])  # the camera's floor point
        d.used.append(d.goal)
        self.policy.reset_hidden()
        self._event("detour", goal=d.goal, reason=reason)
        return True

    def _end_detour(self, reason: str) -> None:
        self.detour.goal = None
        self.policy.reset_hidden()
        self._event("detour_end", reason=reason)

    def _switch(self, position: np.ndarray, reason: str = "stuck") -> None:
        """Next nearest remaining candidate (from here), fresh policy memory and history."""
        untried = list(range(self.current + 1, len(self.candidates)))
        # Re-sort the untried candidates by distance from where the agent now is.
        remaining = [untried[k] for k in nearest_first([self.candidates[j] for j in untried], position,
                                                       self._route())[0]]
        nxt = remaining[0]
        order = list(range(self.current + 1)) + remaining
        self.candidates = [self.candidates[j] for j in order]
        self._clouds = [self._clouds[j] for j in order]
        self.current += 1
        self.switches += 1
        self._new_target()
        self.goal = self._initial_goal(position)
        self.watch.restart()
        self.watch.turns.clear()
        self.policy.reset_hidden()
        self._event("switch", to=self.current, from_index=nxt, goal=self.goal, reason=reason)

    # ----------------------------------------------------------------------------------- navigate
    def _navigate(self, f: Frame) -> int:
        """Act with the policy on the goal's polar coordinates; a policy STOP the agent does not take is
        overridden (:meth:`_override_stop`)."""
        climb = self._climb(f)
        if climb is not None:
            self.watch.taken(climb)
            return climb
        goal = pointgoal_polar(self._policy_goal(f.position), f.position, f.yaw)
        action = int(self.policy.act(f.observations["depth"][None], goal[None])[0])
        if action == STOP:
            action = self._override_stop(f)
        else:
            self.overrides = 0
        self.watch.taken(action)
        return action

    def _climb(self, f: Frame) -> int | None:
        """On or at a flight of stairs (or a ramp) to a target on another storey: the follower's next step
        along it (:meth:`Storeys.climb`); the policy takes over, with fresh memory, where the flight ends."""
        if self.storeys is None or self.detour.goal is not None:
            return None
        target = self.candidates[self.current]
        action = self.storeys.climb(f.position, f.yaw, target) if self.storeys.elsewhere(target) else None
        if (action is not None) != self.climbing:
            self.climbing = action is not None
            if not self.climbing:
                self.policy.reset_hidden()
            self._event("climb" if self.climbing else "climb_end")
        return action

    def _override_stop(self, f: Frame) -> int:
        """A policy STOP on a target that fails the STOP test. Inside the STOP radius with the verdict
        pending or failed: turn to look again. Otherwise FORWARD, at most ``max_stop_overrides`` times in
        a row (beside a target not seen lately, the agent is on the wrong side of a wall: detour); after
        that the STOP stands unless the detector's recent checks refute the target (turn to look again)."""
        cfg = self.config
        if f.at_stop:
            self._event("stop_override", distance=f.dist, reason="unverified")
            return TURN_LEFT
        if self.overrides < cfg.max_stop_overrides:
            self.overrides += 1
            self._event("stop_override", distance=f.dist)
            if self.detour.goal is None and not self.guidance.waypoints and \
                    self.step - self.sighting.last_pass > cfg.visibility_memory:
                self._start_detour(f.position, "stop_unseen")
            return MOVE_FORWARD
        if self._refuted():
            self._event("stop_override", distance=f.dist, reason="refuted")
            return TURN_LEFT
        return STOP

    def _policy_goal(self, position: np.ndarray) -> np.ndarray:
        """The point the policy drives to: a detour's view position, else the next point of a route being
        followed (passing the ones within ``detour_reached``), else the goal, pulled back by
        ``goal_standoff`` while the target was seen lately and is beyond the STOP radius."""
        if self.detour.goal is not None:
            return self.detour.goal
        g = self.guidance
        while g.waypoints and xz_dist(position, g.waypoints[0]) < self.config.detour_reached:
            g.waypoints.pop(0)
            if not g.waypoints:  # the last one saw the target: drive to it now, with fresh memory
                self.policy.reset_hidden()
                self._event("route_end", reason="reached")
        if g.waypoints:
            return g.waypoints[0]
        d = xz_dist(position, self.goal)
        seen_recently = self.step - self.sighting.last_pass <= self.config.visibility_memory
        target = self.candidates[self.current]
        if self.storeys is not None and (self.storeys.elsewhere(target)
                                         or not seen_recently and d > self.config.near_radius):
            # along the shortest path over the joined surfaces: to the stairs or ramp on another storey than
            # the target, round the stairwell (a hole a PointNav policy never met) on its storey
            ahead = self.storeys.carrot(position, target)
            if ahead is not None:
                return ahead
        if not seen_recently or d <= self.stop_radius():
            return self.goal
        return position + (self.goal - position) * (max(d - self.config.goal_standoff, 0.0) / d)
