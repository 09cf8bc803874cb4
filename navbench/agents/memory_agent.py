"""``memory``: the memory-over-maps ObjectNav agent. Localise first, then drive straight there.

At reset the agent asks the localiser (over the scene's cached keyframe memory; no map is built)
for goal candidates for the episode's goal text, sorts them by distance from the start, and drives
to the nearest with the PointNav policy. Each step it:

1. recovers its world pose from the episode's start pose plus GPS+compass (as Habitat agents do);
2. projects up to ``max_projected_points`` of the target's fused cloud into the current depth image;
   a point is *visible* when ``|z - depth| < visible_depth_tol`` (dynamic goal tracking);
3. moves the goal to the nearest visible cloud point (xz) when it moved >= ``goal_update_far``
   (>= ``goal_update_near`` within ``near_radius`` of the goal), resetting the policy's memory; a goal
   that has left the view is only replaced by a nearer point;
4. STOPs when within ``stop_radius`` (xz) of the goal and >= ``visible_fraction`` of in-view points
   are visible, or opportunistically when any other candidate passes the same test. Two additions
   for goals far above or below the camera, which the camera cannot see from within ``stop_radius``
   (a rug on the floor, a picture high on a wall): the radius grows to the xz distance at which the
   goal leaves the vertical field of view plus ``fov_stop_margin``; and while no point of the target
   is in view at all because the agent is too close to see it, the last visibility result from the
   past ``visibility_memory`` steps stands in for the test;
5. otherwise acts with the policy on the goal's polar coordinates; a policy STOP on a target that
   fails the visibility test becomes MOVE_FORWARD (at most ``max_stop_overrides`` times in a row);
6. when stuck (< ``stuck_progress`` m in ``stuck_window`` steps) or oscillating, switches to the
   next nearest candidate (at most ``max_switches`` times).

Every decision is appended to ``episode_log()`` and lands in ``episodes.jsonl``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from navbench.agents.base import PoseTracker, fov_leave_distance, fov_stop_radius, log_value, xz_dist, xz_dists
from navbench.env.config import MOVE_FORWARD, STOP, TURN_LEFT, TURN_RIGHT, EnvConfig
from navbench.env.sensors import depth_metres, pointgoal_polar
from navbench.episodes.types import Episode
from navbench.localize.fusion import GoalCandidate
from navbench.localize.geometry import project, world_to_camera
from navbench.render.renderer import CameraConfig, camera_pose, intrinsics
from navbench.scene.pose import quat_from_yaw


@dataclass(frozen=True)
class MemoryAgentConfig:
    goal_update_far: float = 0.5
    goal_update_near: float = 0.1
    near_radius: float = 2.0
    stop_radius: float = 0.9
    visible_depth_tol: float = 0.3
    visible_fraction: float = 0.05
    max_projected_points: int = 2000
    max_stop_overrides: int = 5
    # Goals the camera cannot see from within stop_radius (module docstring, step 4). The margin is one
    # forward step: approached in 0.25 m steps, a tighter window is stepped over (a picture 1.7 m high
    # is visible from >= 1.0 m only, and its view points lie 0.9-1.0 m from the wall).
    fov_stop_margin: float = 0.25
    visibility_memory: int = 20  # steps a passed visibility test is remembered while nothing is in view
    stuck_window: int = 30
    stuck_progress: float = 0.5
    oscillation_window: int = 8  # this many alternating turns in a row is oscillation
    max_switches: int = 4
    goal_tracking: bool = True  # ablation: off = drive to the candidate's initial goal point
    visibility_stop: bool = True  # ablation: off = STOP on distance alone


class StepPolicy(Protocol):
    """What the agent needs from a PointNav policy (``PointNavAgentPolicy`` with one env)."""

    def reset(self, i: int | None = None) -> None: ...

    def reset_hidden(self, i: int | None = None) -> None: ...

    def act(self, depth: np.ndarray, pointgoal: np.ndarray) -> np.ndarray: ...


class MemoryAgent:
    sensors: tuple[str, ...] = ("rgb", "depth")

    def __init__(self, localize: Callable[[Episode], list[GoalCandidate]], policy: StepPolicy,
                 config: MemoryAgentConfig = MemoryAgentConfig(), env_config: EnvConfig = EnvConfig()):
        self.localize, self.policy, self.config, self.env_config = localize, policy, config, env_config
        cam = CameraConfig(width=env_config.width, height=env_config.height, hfov_deg=env_config.hfov_deg)
        self.K = intrinsics(cam)
        self._tan_half_vfov = float(np.tan(cam.yfov / 2.0))
        self._pose = PoseTracker()

    # ----------------------------------------------------------------------------------- episode
    def reset(self, episode: Episode) -> None:
        self._pose.reset(episode)
        start = np.asarray(episode.start_position, np.float64)
        cands = self.localize(episode)
        self.candidates = sorted(cands, key=lambda c: xz_dist(c.centre, start))
        rng = np.random.default_rng(0)  # deterministic subsample of each cloud
        self._clouds = [c.points[rng.permutation(len(c.points))[:self.config.max_projected_points]]
                        if len(c.points) > self.config.max_projected_points else c.points for c in self.candidates]
        self.current = 0
        self.switches = 0
        self.overrides = 0
        self.step = 0
        self.last_pass = -10**9  # step of the current target's last passed visibility test
        self.positions: list[np.ndarray] = []
        self.turns: list[int] = []
        self.log: dict[str, Any] = {"candidates": [[round(float(v), 3) for v in c.centre] for c in self.candidates],
                                    "events": [], **getattr(self.localize, "last", {})}
        self.goal = self._initial_goal(start) if self.candidates else None
        self.policy.reset()

    def _initial_goal(self, position: np.ndarray) -> np.ndarray:
        cloud = self._clouds[self.current]
        if len(cloud) == 0:
            return np.asarray(self.candidates[self.current].centre, np.float64)
        return cloud[int(np.argmin(xz_dists(cloud, position)))]

    def episode_log(self) -> dict[str, Any]:
        return self.log

    def _event(self, kind: str, **data: Any) -> None:
        self.log["events"].append({"step": self.step, "event": kind,
                                   **{k: log_value(v) for k, v in data.items()}})

    # --------------------------------------------------------------------------------- perception
    def depth_metres(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        c = self.env_config
        return depth_metres(obs["depth"], c.min_depth, c.max_depth, c.normalize_depth)

    def visibility(self, cloud: np.ndarray, depth: np.ndarray, position: np.ndarray, yaw: float,
                   check_depth: bool = True) -> tuple[np.ndarray, int]:
        """Visible cloud points and the number in view (projected inside the image, in front, within
        the sensor's range); ``check_depth=False`` returns every in-view point as visible."""
        if len(cloud) == 0:
            return cloud, 0
        cam_pos = position + np.array([0.0, self.env_config.agent_height, 0.0])
        w2c = world_to_camera(camera_pose(cam_pos, quat_from_yaw(yaw)))
        uv, z, in_view = project(cloud, self.K, w2c, depth.shape[1], depth.shape[0])
        # Depth beyond the sensor range is clipped, so only points the sensor can measure count.
        in_view &= (z > self.env_config.min_depth) & (z < self.env_config.max_depth)
        if not in_view.any():
            return cloud[:0], 0
        if not check_depth:
            return cloud[in_view], int(in_view.sum())
        u = np.clip(np.round(uv[in_view, 0]).astype(int), 0, depth.shape[1] - 1)
        v = np.clip(np.round(uv[in_view, 1]).astype(int), 0, depth.shape[0] - 1)
        ok = np.abs(z[in_view] - depth[v, u]) < self.config.visible_depth_tol
        return cloud[in_view][ok], int(in_view.sum())

    def _passes(self, visible: np.ndarray, in_view: int) -> bool:
        return in_view > 0 and len(visible) / in_view >= self.config.visible_fraction

    def fov_distance(self, point: np.ndarray) -> float:
        """xz distance below which ``point`` is above or below the camera's vertical field of view."""
        return fov_leave_distance(point, self.env_config.agent_height, self._tan_half_vfov)

    def stop_radius(self, goal: np.ndarray) -> float:
        """``stop_radius``, grown for a goal the camera cannot see from within it (module docstring)."""
        cfg = self.config
        return fov_stop_radius(goal, cfg.stop_radius, cfg.fov_stop_margin, self.env_config.agent_height,
                               self._tan_half_vfov)

    # -------------------------------------------------------------------------------------- act
    def act(self, observations: dict[str, np.ndarray]) -> int:
        cfg = self.config
        self.step += 1
        position, yaw = self._pose(observations)
        self.positions.append(position)
        if self.goal is None:
            self._event("no_candidates")
            return STOP
        depth = self.depth_metres(observations)
        visible, in_view = self.visibility(self._clouds[self.current], depth, position, yaw)

        if cfg.goal_tracking and len(visible):
            nearest = visible[int(np.argmin(xz_dists(visible, position)))]
            moved = xz_dist(nearest, self.goal)
            near = xz_dist(position, self.goal) < cfg.near_radius
            # A goal that has left the view (e.g. below the camera's field of view once the agent is
            # close to a low object) can be neither confirmed nor refuted: keep it unless the new point
            # is nearer. Replacing it by the nearest point still in view would move the goal away as
            # the agent approaches, so it could never come within stop_radius of a rug.
            in_view = self.visibility(self.goal[None], depth, position, yaw, check_depth=False)[1] > 0
            closer = xz_dist(nearest, position) < xz_dist(self.goal, position)
            if moved >= (cfg.goal_update_near if near else cfg.goal_update_far) and (in_view or closer):
                self.goal = nearest
                self.policy.reset_hidden()
                self._event("goal_update", goal=nearest, moved=moved)

        dist = xz_dist(position, self.goal)
        visible_ok = self._passes(visible, in_view)
        if visible_ok:
            self.last_pass = self.step
        elif in_view == 0 and dist < self.fov_distance(self.goal) and \
                self.step - self.last_pass <= cfg.visibility_memory:
            visible_ok = True  # too close to see the target at all: its recent sighting stands
        if dist < self.stop_radius(self.goal) and (visible_ok or not cfg.visibility_stop):
            self._event("stop", candidate=self.current, distance=dist)
            return STOP
        for j, cloud in enumerate(self._clouds):  # opportunistic: another candidate right here
            if j == self.current or not len(cloud):
                continue
            if np.min(xz_dists(cloud, position)) < cfg.stop_radius:
                vis_j, n_j = self.visibility(cloud, depth, position, yaw)
                if self._passes(vis_j, n_j):
                    self._event("opportunistic_stop", candidate=j)
                    return STOP

        if self._stuck_or_oscillating() and self.switches < cfg.max_switches and \
                self.current + 1 < len(self.candidates):
            self._switch(position)

        action = int(self.policy.act(observations["depth"][None],
                                     pointgoal_polar(self.goal, position, yaw)[None])[0])
        if action == STOP:
            if self.overrides < cfg.max_stop_overrides and (cfg.visibility_stop and not visible_ok):
                self.overrides += 1
                self._event("stop_override", distance=dist)
                action = MOVE_FORWARD
        else:
            self.overrides = 0
        if action in (TURN_LEFT, TURN_RIGHT):
            self.turns.append(action)
        elif action == MOVE_FORWARD:
            self.turns.clear()
        return action

    def _stuck_or_oscillating(self) -> bool:
        cfg = self.config
        if len(self.positions) > cfg.stuck_window:
            progress = xz_dist(self.positions[-1], self.positions[-1 - cfg.stuck_window])
            if progress < cfg.stuck_progress:
                self._event("stuck", progress=progress)
                # start a fresh window: one event per stuck period, not one per step
                self.positions = self.positions[-1:]
                return True
        t = self.turns[-cfg.oscillation_window:]
        if len(t) == cfg.oscillation_window and all(a != b for a, b in zip(t, t[1:])):
            self._event("oscillating")
            self.turns.clear()
            return True
        return False

    def _switch(self, position: np.ndarray) -> None:
        """Next nearest remaining candidate (from here), fresh policy memory and history."""
        remaining = list(range(self.current + 1, len(self.candidates)))
        # Re-sort the untried candidates by distance from where the agent now is.
        remaining.sort(key=lambda j: xz_dist(self.candidates[j].centre, position))
        nxt = remaining[0]
        order = list(range(self.current + 1)) + remaining
        self.candidates = [self.candidates[j] for j in order]
        self._clouds = [self._clouds[j] for j in order]
        self.current += 1
        self.switches += 1
        self.last_pass = -10**9
        self.goal = self._initial_goal(position)
        self.positions.clear()
        self.turns.clear()
        self.policy.reset_hidden()
        self._event("switch", to=self.current, from_index=nxt, goal=self.goal)

