"""``frontier``: a zero-shot frontier-exploration ObjectNav baseline in the VLFM family.

The agent builds an online occupancy map (:mod:`navbench.agents.occupancy`) from its own depth and
pose (start pose + GPS/compass), and never sees the scene mesh or the navigability grid. Per episode:

1. **Look around**: ``initial_turns`` TURN_LEFTs (360 deg) to seed the map.
2. **Explore**: drive to the nearest frontier cluster by path distance over the known-free map
   (VLFM's frontier midpoint: the reachable cluster cell nearest its centroid). The target is
   re-chosen when it is reached (``frontier_reached``; one that survives being reached is
   blacklisted), stops being a frontier, or every ``replan_every`` steps (a nearer cluster must win
   by ``switch_margin`` m, so the agent does not dither between two equally near frontiers).
3. **Detect** the target in every frame with the injected ``detect(observations, (position, yaw))``,
   accumulating the world points (voxel-downsampled) across frames.
4. **Approach** once anything was detected: the goal is the point nearest the agent (xz) of the
   cluster of target points nearest the agent, reached over the map (or, while the map has no path
   there yet, via the frontier minimising path distance + straight-line distance on to it); STOP
   within ``stop_radius`` (xz) when the target passes the visibility test both ObjectNav agents use
   (:mod:`navbench.agents.common`: a point is visible when ``|z - depth| < visible_depth_tol``; pass
   when >= ``visible_fraction`` of in-view points are). As for the memory agent, the radius grows for
   targets far above or below the camera.
5. **STOP** when no reachable frontier remains and nothing was detected.

On a GOAT-Bench episode every STOP is a SUBTASK_STOP, and the next subtask starts as a new search from the
agent's pose: a new map, a look-around, the detector taught the subtask's goal (category, description, or the
goal image's caption). It keeps nothing between subtasks: the baseline that re-explores for every goal.

Locomotion is the injected PointNav policy (the same ``StepPolicy`` as the memory agent). As in
VLFM the policy does the local control; unlike VLFM, which hands it the frontier itself, the policy
gets a waypoint ``waypoint_lookahead`` m along the map's geodesic to the target (held until the agent
is within ``waypoint_reached`` of it), so a distant frontier around a corner is reached through the
mapped free space (set ``waypoint_lookahead=0`` for VLFM's direct goal). The recurrent state is reset
whenever the waypoint moves (a new goal for the policy).

A forward step that does not move (odometry) maps an obstacle just ahead: bumps into things too near
or too low for the depth camera then reroute the plan. Stuck handling: < ``stuck_progress`` m in
``stuck_window`` steps blacklists the current frontier (or, when approaching, abandons the current
target cluster) and picks another. Every decision is logged in
``episode_log()``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from navbench.agents.base import episode_seed, xz_dist, xz_dists
from navbench.agents.common import (
    Detect,
    ObjectNavAgentBase,
    ObjectNavAgentConfig,
    StepPolicy,
    StuckWatch,
    reset_detector,
    subsample,
)
from navbench.agents.occupancy import Frontier, OccupancyConfig, OccupancyMap, trace_path
from navbench.env.config import MOVE_FORWARD, STOP, TURN_LEFT, TURN_RIGHT, EnvConfig
from navbench.env.sensors import pointgoal_polar
from navbench.episodes.goat import SUBTASK_STOP, GoatEpisode
from navbench.episodes.types import Episode
from navbench.localize.geometry import voxel_downsample
from navbench.scene.pose import heading_vector


@dataclass(frozen=True)
class FrontierAgentConfig(ObjectNavAgentConfig):
    occupancy: OccupancyConfig = OccupancyConfig()
    initial_turns: int = 12  # 12 x 30 deg: a full look-around before moving
    replan_every: int = 10  # steps between re-choosing the nearest frontier
    switch_margin: float = 1.0  # m; another frontier must be this much nearer to replace the current one
    frontier_reached: float = 0.5  # m (xz); the frontier goal counts as reached within this
    frontier_match: float = 0.5  # m; the current goal still is a frontier if one of its cells is this near
    blacklist_radius: float = 0.75  # m; frontier goals this near a blacklisted one are skipped
    waypoint_lookahead: float = 1.5  # m along the map path; 0 = hand the policy the goal itself (VLFM)
    waypoint_reached: float = 0.5  # m; a waypoint is refreshed once the agent is this near
    target_voxel: float = 0.05  # m; accumulated target points are voxel-downsampled to this
    target_cluster_eps: float = 0.5  # m; target points closer than this belong to one object
    min_target_points: int = 1  # clusters with fewer points are ignored (detector noise)
    sensors: tuple[str, ...] = ("rgb", "depth", "semantic")  # semantic only for the oracle detector


class FrontierAgent(ObjectNavAgentBase):
    config: FrontierAgentConfig

    def __init__(self, detect: Detect, policy: StepPolicy, config: FrontierAgentConfig = FrontierAgentConfig(),
                 env_config: EnvConfig = EnvConfig(), seed: int = 0):
        super().__init__(policy, config, env_config, seed)
        self.detect = detect
        self.sensors: tuple[str, ...] = config.sensors
        self.map = OccupancyMap(config.occupancy)

    # ----------------------------------------------------------------------------------- episode
    def reset(self, episode: Episode) -> None:
        reset_detector(self.detect, episode)  # the episode's scene and goal text
        self._begin(episode, {"events": [], "frontiers_chosen": 0, "first_detection_step": None,
                              "stop_reason": None, "bumps": 0})
        self._episode = episode
        self.subtask = 0  # a GOAT-Bench episode's active subtask
        self._subtasks = len(episode.tasks) if isinstance(episode, GoatEpisode) else 0
        self._position = np.asarray(episode.start_position, np.float64)
        self.last_action: int | None = None
        self._start_goal(self._position)

    def _start_goal(self, position: np.ndarray) -> None:
        """Search for a goal from ``position`` knowing nothing: a new map, a look-around, no detections."""
        self.map.reset(position)
        self.watch = StuckWatch(self.config.stuck_window, self.config.stuck_progress)
        self.mode = "look_around"
        self.look_until = self.step + self.config.initial_turns
        self.frontier: Frontier | None = None
        self.frontier_since = 0
        self.blacklist: list[np.ndarray] = []
        self.target_points = np.zeros((0, 3))
        self.target_blacklist: list[np.ndarray] = []
        self.goal: np.ndarray | None = None  # current target point when approaching
        self.waypoint: np.ndarray | None = None
        self.overrides = 0  # steps within the STOP radius without a visible target

    def decision(self) -> list | None:
        """What the agent drives to now, for the run's trace: [mode, x, z] (dm; no point while looking around)."""
        point = self.goal if self.mode == "approach" else (self.frontier.goal if self.frontier is not None else None)
        if point is None:
            return [self.mode, None, None]
        return [self.mode, round(float(point[0]), 1), round(float(point[2]), 1)]

    # --------------------------------------------------------------------------------- perception
    def _depth_normalised(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        c = self.env_config
        d = obs["depth"][..., 0].astype(np.float64)
        return d if c.normalize_depth else np.clip((d - c.min_depth) / (c.max_depth - c.min_depth), 0.0, 1.0)

    def _add_detections(self, points: np.ndarray) -> None:
        points = np.asarray(points, np.float64).reshape(-1, 3)
        if not len(points):
            return
        for b in self.target_blacklist:  # points of abandoned (unreachable) targets stay abandoned
            points = points[xz_dists(points, b) > self.config.target_cluster_eps]
        if not len(points):
            return
        if self.log["first_detection_step"] is None:
            self.log["first_detection_step"] = self.step
            self._event("detected", points=len(points), centre=points.mean(axis=0))
        self.target_points = voxel_downsample(np.vstack([self.target_points, points]), self.config.target_voxel)

    def target_clusters(self) -> list[np.ndarray]:
        """Accumulated target points grouped into objects (single linkage at ``target_cluster_eps``)."""
        pts = self.target_points
        if not len(pts):
            return []
        pairs = cKDTree(pts).query_pairs(self.config.target_cluster_eps, output_type="ndarray")
        graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(pts), len(pts)))
        n, labels = connected_components(graph, directed=False)
        clusters = [pts[labels == i] for i in range(n)]
        return [c for c in clusters if len(c) >= self.config.min_target_points]

    # -------------------------------------------------------------------------------------- act
    def act(self, observations: dict[str, np.ndarray]) -> int:
        """One step (module docstring); on a GOAT-Bench episode a STOP closes the subtask (SUBTASK_STOP) and the
        next one starts with a fresh search from where the agent stands."""
        action = self._act(observations)
        if action == STOP and self._subtasks:
            action = self._next_subtask()
        self.last_action = action
        return action

    def _next_subtask(self) -> int:
        self._event("subtask_stop", subtask=self.subtask)
        self.subtask += 1
        if self.subtask < self._subtasks:
            self.policy.reset(seed=[*episode_seed(self.seed, self._episode), self.subtask])
            reset_detector(self.detect, self._episode, self.subtask)
            self._start_goal(self._position)
        return SUBTASK_STOP

    def _act(self, observations: dict[str, np.ndarray]) -> int:
        env = self.env_config
        self.step += 1
        position, yaw = self._pose(observations)
        self._position = position
        self.watch.add(position)
        if self.last_action == MOVE_FORWARD and len(self.watch.positions) > 1 and \
                xz_dist(position, self.watch.positions[-2]) < 0.25 * env.forward_step:
            # A forward step that did not move hit something (perhaps too near or too low for the depth camera):
            # the agent knows that from its own odometry, so it maps an obstacle just ahead.
            self.map.mark_occupied(position + (env.agent_radius + 0.05) * heading_vector(yaw))
            self.log["bumps"] += 1
        self.map.update(self._depth_normalised(observations), self.K, position, yaw, env.agent_height,
                        env.min_depth, env.max_depth)
        self._add_detections(self.detect(observations, (position, yaw)))

        if self.mode == "look_around":
            if self.step <= self.look_until:
                return TURN_LEFT
            self.mode = "explore"
            self.watch.restart(position)  # turning in place is not being stuck
            self._event("look_around_done")

        clusters = self.target_clusters()
        if clusters:
            if self.mode != "approach":
                self.mode = "approach"
                self.waypoint = self.frontier = None
                self.watch.restart(position)
                self._event("approach", clusters=len(clusters))
            return self._approach(observations, clusters, position, yaw)
        if self.mode == "approach":  # every target cluster was abandoned: back to exploring
            self.mode = "explore"
            self.frontier = None
        return self._explore(observations, position, yaw)

    # ------------------------------------------------------------------------------------ explore
    def _explore(self, obs: dict[str, np.ndarray], position: np.ndarray, yaw: float) -> int:
        if self.watch.stuck() is not None and self.frontier is not None:
            self._event("stuck_blacklist", frontier=self.frontier.goal)
            self.blacklist.append(self.frontier.goal)
            self.frontier = None
        dist, frontiers = self._reachable_frontiers(position)
        if frontiers:
            self._choose_frontier(frontiers, position)
        if self.frontier is None:
            self._event("stop", reason="no_frontier")
            self.log["stop_reason"] = "no_frontier"
            return STOP
        return self._drive(obs, self.frontier.goal, dist, self.frontier.goal_cell, position, yaw)

    def _reachable_frontiers(self, position: np.ndarray) -> tuple[np.ndarray, list[Frontier]]:
        """Path-distance field and the reachable, non-blacklisted frontiers, nearest first. Planned with the
        clearance margin first; without it (bare agent radius) only when nothing is reachable with it."""
        for inflation in (None, self.map.config.agent_radius):
            dist = self.map.path_distance(position, inflation)
            frontiers = [f for f in self.map.frontiers(dist, self._blacklist_mask()) if np.isfinite(f.distance)]
            if frontiers:
                return dist, frontiers
        return dist, frontiers

    def _blacklist_mask(self) -> np.ndarray | None:
        """Cells within ``blacklist_radius`` of a blacklisted frontier goal: no frontier is taken from them
        (only that part of a long frontier is given up, not the whole cluster)."""
        if not self.blacklist:
            return None
        mask = np.zeros(self.map.grid.shape, np.uint8)
        r = max(1, int(round(self.config.blacklist_radius / self.map.config.cell_size)))
        for b in self.blacklist:
            row, col = self.map.to_cell(b[[0, 2]])
            cv2.circle(mask, (int(col), int(row)), r, 1, -1)
        return mask > 0

    def _choose_frontier(self, frontiers: list[Frontier], position: np.ndarray) -> None:
        cfg = self.config
        nearest = frontiers[0]
        reason = None
        if self.frontier is None:
            reason = "none"
        elif xz_dist(position, self.frontier.goal) < cfg.frontier_reached:
            reason = "reached"
        else:
            same = self._matching(frontiers, self.frontier)
            if same is None:
                reason = "vanished"
            elif self.step - self.frontier_since >= cfg.replan_every:
                self.frontier_since = self.step
                if nearest.distance + cfg.switch_margin < same.distance:
                    reason = "nearer"
                else:
                    self.frontier = same  # keep it, with its fresh distance
            else:
                self.frontier = same
        if reason is None:
            return
        if reason == "reached" and self.frontier is not None:
            # Standing at a frontier normally reveals what lies beyond it; one that survives that cannot be
            # cleared from here (unknown pockets behind furniture, gaps the camera never sees): give it up.
            self.blacklist.append(self.frontier.goal)
            frontiers = [f for f in frontiers if xz_dist(f.goal, self.frontier.goal) >= cfg.blacklist_radius]
            if not frontiers:
                self.frontier = None
                return
            nearest = frontiers[0]
        self.frontier = nearest
        self.frontier_since = self.step
        self.waypoint = None
        self.log["frontiers_chosen"] += 1
        self._event("frontier", reason=reason, goal=nearest.goal, distance=nearest.distance,
                    size=nearest.size, candidates=len(frontiers))

    def _matching(self, frontiers: list[Frontier], current: Frontier) -> Frontier | None:
        """The cluster that still contains a cell near the current goal (frontiers drift as the map grows)."""
        best, best_d = None, self.config.frontier_match
        for f in frontiers:
            d = float(np.min(xz_dists(self.map.to_world(f.cells), current.goal)))
            if d <= best_d:
                best, best_d = f, d
        return best

    # ----------------------------------------------------------------------------------- approach
    def _approach(self, obs: dict[str, np.ndarray], clusters: list[np.ndarray], position: np.ndarray,
                  yaw: float) -> int:
        cfg = self.config
        cluster = min(clusters, key=lambda c: float(np.min(xz_dists(c, position))))
        goal = cluster[int(np.argmin(xz_dists(cluster, position)))]
        if self.goal is None or xz_dist(goal, self.goal) > 0.5:
            self._event("target", goal=goal, points=len(cluster), clusters=len(clusters))
        self.goal = goal
        dist = xz_dist(position, goal)
        if dist >= self.stop_radius_for(cluster):
            self.overrides = 0
        else:
            points = subsample(cluster, cfg.max_projected_points, np.random.default_rng(0))
            visible, in_view = self.visibility(points, self.depth_metres(obs), position, yaw)
            if self.passes(visible, in_view):
                self._event("stop", reason="target_visible", distance=dist, visible=len(visible), in_view=in_view)
                self.log["stop_reason"] = "target_visible"
                return STOP
            self.overrides += 1
            if self.overrides > cfg.max_stop_overrides:
                self._event("stop", reason="near_target_not_visible", distance=dist)
                self.log["stop_reason"] = "near_target_not_visible"
                return STOP
            # Close but not seen: face the target (it may be beside or behind the camera).
            theta = float(pointgoal_polar(goal, position, yaw)[1])
            if abs(theta) > math.radians(self.env_config.hfov_deg) / 4:
                return TURN_LEFT if theta > 0 else TURN_RIGHT
        if self.watch.stuck() is not None:
            self._event("stuck_abandon_target", goal=goal)
            self.target_blacklist.append(goal)
            self.target_points = self.target_points[xz_dists(self.target_points, goal) > cfg.target_cluster_eps]
            self.watch.restart(position)
            self.goal = self.waypoint = None
            self.mode = "explore"
            self.frontier = None
            return self._explore(obs, position, yaw)
        # Plan to the reachable cell nearest the goal within the stop radius (the object itself is an obstacle).
        field = self.map.path_distance(position)
        cells = np.argwhere(np.isfinite(field))
        target_cell = None
        if len(cells):
            near = xz_dists(self.map.to_world(cells), goal) < cfg.stop_radius * 0.8
            if near.any():
                cand = cells[near]
                target_cell = tuple(int(v) for v in cand[int(np.argmin(field[cand[:, 0], cand[:, 1]]))])
        if target_cell is None:
            # No known path to the target yet (seen through a doorway, or across unexplored space): head for
            # the frontier that minimises path distance + straight-line distance on to the target.
            field, frontiers = self._reachable_frontiers(position)
            if frontiers:
                via = min(frontiers, key=lambda f: f.distance + xz_dist(f.goal, goal))
                if self.frontier is None or xz_dist(via.goal, self.frontier.goal) > cfg.frontier_match:
                    self._event("approach_via_frontier", frontier=via.goal, goal=goal)
                    self.waypoint = None
                self.frontier = via
                return self._drive(obs, via.goal, field, via.goal_cell, position, yaw)
        return self._drive(obs, goal, field, target_cell, position, yaw)

    # -------------------------------------------------------------------------------------- drive
    def _drive(self, obs: dict[str, np.ndarray], goal: np.ndarray, field: np.ndarray,
               goal_cell: tuple[int, int] | None, position: np.ndarray, yaw: float) -> int:
        """One policy step toward ``goal`` via a held waypoint on the map path (``goal_cell`` in ``field``)."""
        cfg = self.config
        if self.waypoint is None or xz_dist(position, self.waypoint) < cfg.waypoint_reached or \
                (self.step - self.frontier_since) % cfg.replan_every == 0:
            wp = self._waypoint(goal, field, goal_cell, position)
            if self.waypoint is None or xz_dist(wp, self.waypoint) > 0.1:
                self.policy.reset_hidden()  # a new goal for the policy
            self.waypoint = wp
        pointgoal = pointgoal_polar(self.waypoint, position, yaw)
        action = int(self.policy.act(obs["depth"][None], pointgoal[None])[0])
        if action == STOP:
            # The policy thinks it arrived; only this agent decides when the episode ends.
            self.waypoint = None
            action = MOVE_FORWARD if abs(float(pointgoal[1])) < math.radians(15) else \
                (TURN_LEFT if pointgoal[1] > 0 else TURN_RIGHT)
        return action

    def _waypoint(self, goal: np.ndarray, field: np.ndarray, goal_cell: tuple[int, int] | None,
                  position: np.ndarray) -> np.ndarray:
        cfg = self.config
        if cfg.waypoint_lookahead <= 0 or goal_cell is None:
            return np.asarray(goal, np.float64)
        path = trace_path(field, goal_cell)
        if len(path) < 2:
            return np.asarray(goal, np.float64)
        along = field[path[:, 0], path[:, 1]]
        last = min(int(np.searchsorted(along, cfg.waypoint_lookahead, side="right")), len(path)) - 1
        # The farthest path point within the lookahead that the agent sees in a straight line (over the map
        # inflated by its bare radius): a straight shot at a point round a corner would clip the corner.
        clear = self.map.traversable(self.map.config.agent_radius)
        pts = self.map.to_world(path)
        i = next((j for j in range(last, 0, -1) if self.map.line_of_sight(position, pts[j], clear)), min(last, 1))
        if i == len(path) - 1 and xz_dist(pts[i], goal) < cfg.stop_radius:
            return np.asarray(goal, np.float64)  # the goal is in reach: aim at it (frontier or object point)
        return pts[i]
