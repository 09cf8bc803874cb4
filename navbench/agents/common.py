"""What the two ObjectNav agents (``memory`` and ``frontier``) share.

Both drive with an injected PointNav policy (:class:`StepPolicy`), see the goal with an injected
detector (:class:`Detector`), know their pose from the episode's start plus GPS+compass, judge a
target by the same visibility test against the live depth image, grow the STOP radius for targets
far above or below the camera, detect when they stop making progress, and log their decisions.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from navbench.agents.base import PoseTracker, episode_seed, fov_stop_radius, log_value, nearest_to_height, xz_dist
from navbench.env.config import MOVE_FORWARD, TURN_LEFT, TURN_RIGHT, EnvConfig
from navbench.env.sensors import depth_metres
from navbench.episodes.types import Episode
from navbench.localize.geometry import project, world_to_camera
from navbench.render.camera import CameraConfig, camera_pose, intrinsics
from navbench.scene.pose import quat_from_yaw


class StepPolicy(Protocol):
    """What the agents need from a PointNav policy (``PointNavAgentPolicy`` with one env)."""

    def reset(self, i: int | None = None, seed: int | list[int] | None = None) -> None: ...

    def reset_hidden(self, i: int | None = None) -> None: ...

    def act(self, depth: np.ndarray, pointgoal: np.ndarray) -> np.ndarray: ...


# detect(observations, (world position, yaw)) -> (N, 3) world points of the goal object in this frame
Detect = Callable[[dict[str, np.ndarray], tuple[np.ndarray, float]], np.ndarray]


class Detector(Protocol):
    """The goal text segmented in the current frame, as (N, 3) world points (``LiveDetector``): ``reset``
    hands it the episode (its scene and goal text; on GOAT-Bench the active subtask, passed only after the
    first), ``sensors`` names the image it segments."""

    sensors: tuple[str, ...]

    def reset(self, episode: Episode, subtask: int = 0) -> None: ...

    def __call__(self, observations: dict[str, np.ndarray], pose: tuple[np.ndarray, float]) -> np.ndarray: ...


def reset_detector(detector: Detect | Detector, episode: Episode, subtask: int = 0) -> None:
    """Hand ``episode`` (a GOAT-Bench episode's ``subtask`` after the first) to a detector that takes it (a plain
    function needs none)."""
    reset = getattr(detector, "reset", None)
    if callable(reset):
        reset(episode, subtask=subtask) if subtask else reset(episode)


@dataclass(frozen=True)
class ObjectNavAgentConfig:
    """Settings both ObjectNav agents have."""

    stop_radius: float = 0.9  # m (xz) from the target within which the agent may STOP
    # A target point is visible when its depth in the camera is within this of the measured depth, and a
    # target passes the visibility test when this share of its points in view are visible.
    visible_depth_tol: float = 0.3
    visible_fraction: float = 0.05
    max_projected_points: int = 2000  # a target's cloud is subsampled to this many points for the test
    max_stop_overrides: int = 5  # consecutive STOPs the agent refuses before it lets one stand (or looks again)
    # For targets the camera cannot see from within stop_radius (a rug, a picture high on a wall) the
    # radius grows to where the target's point nearest the camera height leaves the view, plus this.
    fov_stop_margin: float = 0.15
    stuck_window: int = 30  # steps; less than stuck_progress m of progress over them is being stuck
    stuck_progress: float = 0.5


def subsample(points: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """At most ``n`` of ``points``, drawn with ``rng`` (all of them, in order, when there are no more)."""
    return points[rng.permutation(len(points))[:n]] if len(points) > n else points


class StuckWatch:
    """Progress over the last ``window`` positions and, with ``oscillation_window``, back-and-forth turning."""

    def __init__(self, window: int, min_progress: float, oscillation_window: int = 0):
        self.window, self.min_progress, self.oscillation_window = window, min_progress, oscillation_window
        self.positions: list[np.ndarray] = []
        self.turns: list[int] = []  # turns since the last FORWARD

    def add(self, position: np.ndarray) -> None:
        self.positions.append(position)

    def restart(self, position: np.ndarray | None = None) -> None:
        """Forget the positions (keeping ``position`` as the first of a new window)."""
        self.positions = [] if position is None else [position]

    def stuck(self) -> float | None:
        """The progress (m) over the last window when it is too little, starting a fresh window (one report
        per stuck period, not one per step); None when the agent is moving on."""
        if len(self.positions) > self.window:
            progress = xz_dist(self.positions[-1], self.positions[-1 - self.window])
            if progress < self.min_progress:
                self.positions = self.positions[-1:]
                return progress
        return None

    def taken(self, action: int) -> None:
        """Count a turn; a FORWARD ends a run of turns."""
        if action in (TURN_LEFT, TURN_RIGHT):
            self.turns.append(action)
        elif action == MOVE_FORWARD:
            self.turns.clear()

    def oscillating(self) -> bool:
        """``oscillation_window`` alternating turns in a row (then counting starts afresh)."""
        t = self.turns[-self.oscillation_window:]
        if self.oscillation_window and len(t) == self.oscillation_window and all(a != b for a, b in zip(t, t[1:])):
            self.turns.clear()
            return True
        return False


class ObjectNavAgentBase:
    """Pose, camera, depth, the visibility test, the STOP radius and the decision log of an ObjectNav agent."""

    def __init__(self, policy: StepPolicy, config: ObjectNavAgentConfig, env_config: EnvConfig, seed: int):
        self.policy, self.config, self.env_config = policy, config, env_config
        self.seed = seed  # for a policy that draws its actions: each episode draws from (seed, episode)
        cam = CameraConfig(width=env_config.width, height=env_config.height, hfov_deg=env_config.hfov_deg)
        self.K = intrinsics(cam)
        self._tan_half_vfov = float(np.tan(cam.yfov / 2.0))
        self._pose = PoseTracker()
        self.step = 0
        self.log: dict[str, Any] = {"events": []}

    def _begin(self, episode: Episode, log: dict[str, Any]) -> None:
        """Start an episode: pose, step count, the policy (reseeded from the run's seed and the episode), and
        the decision log (``log``, with an empty ``events`` list)."""
        self._pose.reset(episode)
        self.policy.reset(seed=episode_seed(self.seed, episode))
        self.step = 0
        self.log = log

    def episode_log(self) -> dict[str, Any]:
        return self.log

    def _event(self, kind: str, **data: Any) -> None:
        self.log["events"].append({"step": self.step, "event": kind, **{k: log_value(v) for k, v in data.items()}})

    def depth_metres(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        c = self.env_config
        return depth_metres(obs["depth"], c.min_depth, c.max_depth, c.normalize_depth)

    def visibility(self, cloud: np.ndarray, depth: np.ndarray, position: np.ndarray, yaw: float,
                   check_depth: bool = True, snap: bool = False) -> tuple[np.ndarray, int]:
        """Visible cloud points and the number in view (projected inside the image, in front, within
        the sensor's range); ``check_depth=False`` returns every in-view point as visible.

        ``snap=True`` returns each visible point moved along its camera ray onto the surface the depth
        sensor measures now (at most ``visible_depth_tol`` away): a goal is then placed on the live
        surface, not on a stored point that depth noise put in front of it.
        """
        if len(cloud) == 0:
            return cloud, 0
        c = self.env_config
        cam_pos = position + np.array([0.0, c.agent_height, 0.0])
        w2c = world_to_camera(camera_pose(cam_pos, quat_from_yaw(yaw)))
        uv, z, in_view = project(cloud, self.K, w2c, depth.shape[1], depth.shape[0])
        # Depth beyond the sensor range is clipped, so only points the sensor can measure count.
        in_view &= (z > c.min_depth) & (z < c.max_depth)
        if not in_view.any():
            return cloud[:0], 0
        if not check_depth:
            return cloud[in_view], int(in_view.sum())
        u = np.clip(np.round(uv[in_view, 0]).astype(int), 0, depth.shape[1] - 1)
        v = np.clip(np.round(uv[in_view, 1]).astype(int), 0, depth.shape[0] - 1)
        measured = depth[v, u]
        ok = np.abs(z[in_view] - measured) < self.config.visible_depth_tol
        visible = cloud[in_view][ok]
        if snap and len(visible):
            scale = (measured[ok] / z[in_view][ok])[:, None]  # planar depth: scale along the ray
            visible = cam_pos + (visible - cam_pos) * scale
        return visible, int(in_view.sum())

    def passes(self, visible: np.ndarray, in_view: int) -> bool:
        """The visibility test: enough of the target's in-view points are visible."""
        return in_view > 0 and len(visible) / in_view >= self.config.visible_fraction

    def stop_radius_for(self, points: np.ndarray, floor: float = 0.0) -> float:
        """``stop_radius``, grown for a target (``points``) the camera cannot see from within it (the camera
        ``agent_height`` above ``floor``, the height of the surface the agent stands on)."""
        cfg, h = self.config, floor + self.env_config.agent_height
        return fov_stop_radius(nearest_to_height(points, h), cfg.stop_radius, cfg.fov_stop_margin, h,
                               self._tan_half_vfov)
