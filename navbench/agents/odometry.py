"""Pose without GPS+compass: dead reckoning from the agent's own commanded actions, each forward step's
translation measured from depth.

The pose starts at the episode's start pose, the frame the pre-scan memory and the agent's map are in (the
project's agents take it from the episode, as :class:`~navbench.agents.base.PoseTracker` does). A turn changes
the heading by exactly the configured angle (turns never collide). A forward step may stop short at a wall or,
with sliding, glance along it; its translation is found by aligning the depth frame before the step with the
one after it at the known heading: the earlier frame's points (floor points dropped, they say nothing about a
move along the floor) are moved by each candidate translation in the floor plane and projected into the new
frame, and the candidate whose predicted depths fit the measured ones best (a truncated mean residual, with a
small pull towards the expected move for frames that cannot tell, such as a long corridor) is taken. The expected
move is the commanded step; for a step the frames show stopped short, it is the stop plus the rest of the step
along the wall ahead (the nearest surface across the image's middle rows), as a sliding body moves, since a plain
wall filling the view cannot tell how far the body slid along it.
"""

from __future__ import annotations

import math

import numpy as np

from navbench.env.config import MOVE_FORWARD, TURN_LEFT, TURN_RIGHT, EnvConfig
from navbench.env.sensors import depth_metres
from navbench.episodes.types import Episode
from navbench.render.camera import CameraConfig, intrinsics
from navbench.scene.pose import heading_vector, wrap_angle, yaw_from_quat

STRIDE = 4  # pixels between the earlier frame's sampled points
TRUNCATE = 0.15  # m: a point's depth residual counts at most this (occlusions, points leaving the view)
PRIOR = 0.5  # weight of the squared distance (m^2) from the expected move in a candidate's score
FLOOR_MARGIN = 0.15  # m above the floor below which a point is floor


class DepthOdometry:
    """``reset(episode)``, then per step ``note(action)`` for the action just taken and ``pose(observations)``
    for the pose after it: (world position (3,), yaw). Needs the depth observation only."""

    def __init__(self, env_config: EnvConfig = EnvConfig()):
        c = env_config
        self.config = c
        self.K = intrinsics(CameraConfig(width=c.width, height=c.height, hfov_deg=c.hfov_deg))
        self.turn = math.radians(c.turn_angle_deg)
        self.forward_step = c.forward_step

    def reset(self, episode: Episode) -> None:
        self.position = np.asarray(episode.start_position, np.float64).copy()
        self.yaw = yaw_from_quat(np.asarray(episode.start_rotation, np.float64))
        self._pending: int | None = None
        self._previous: np.ndarray | None = None  # the last frame's depth (metres)

    def note(self, action: int) -> None:
        """The action the agent has just sent: applied when the next observation arrives."""
        self._pending = int(action)

    def __call__(self, observations: dict[str, np.ndarray]) -> tuple[np.ndarray, float]:
        return self.pose(observations)

    def pose(self, observations: dict[str, np.ndarray]) -> tuple[np.ndarray, float]:
        c = self.config
        depth = depth_metres(observations["depth"], c.min_depth, c.max_depth, c.normalize_depth)
        action, self._pending = self._pending, None
        if action in (TURN_LEFT, TURN_RIGHT):
            self.yaw = wrap_angle(self.yaw + (self.turn if action == TURN_LEFT else -self.turn))
        elif action == MOVE_FORWARD:
            forward, right = (self.forward_step, 0.0) if self._previous is None else \
                self.step_translation(self._previous, depth)
            self.position = self.position + forward * heading_vector(self.yaw) + right * _right_vector(self.yaw)
        self._previous = depth
        return self.position.copy(), self.yaw

    def _points(self, depth: np.ndarray) -> np.ndarray:
        """The frame's sampled points (N, 3) in the camera's axes (x right, y up, z the depth ahead), floor and
        unmeasured pixels dropped."""
        c = self.config
        h, w = depth.shape
        rows, cols = np.mgrid[STRIDE // 2:h:STRIDE, STRIDE // 2:w:STRIDE]
        z = depth[rows, cols]
        x = (cols - self.K[0, 2]) * z / self.K[0, 0]
        y = -(rows - self.K[1, 2]) * z / self.K[1, 1]
        keep = (z > c.min_depth + 1e-3) & (z < c.max_depth - 1e-3) & (y > -(c.agent_height - FLOOR_MARGIN))
        return np.stack([x[keep], y[keep], z[keep]], axis=1)

    def _scores(self, points: np.ndarray, depth: np.ndarray, forward: np.ndarray, right: np.ndarray,
                expected: tuple[float, float]) -> np.ndarray:
        """Each candidate (forward[k], right[k]) move's truncated mean depth residual plus its pull to the
        ``expected`` (forward, right) move."""
        h, w = depth.shape
        z = points[None, :, 2] - forward[:, None]  # (K, N): the points seen from the moved camera
        x = points[None, :, 0] - right[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.rint(self.K[0, 0] * x / z + self.K[0, 2])
            v = np.rint(-self.K[1, 1] * points[None, :, 1] / z + self.K[1, 2])
        ok = (z > 0.05) & (u >= 0) & (u < w) & (v >= 0) & (v < h)
        measured = depth[np.where(ok, v, 0).astype(int), np.where(ok, u, 0).astype(int)]
        residual = np.minimum(np.abs(measured - z), TRUNCATE)
        # Points that leave the view under some candidates are left out for all: counting them would favour
        # the candidates that keep the most points in view, the shorter moves.
        common = ok.all(axis=0)
        residual = residual[:, common].mean(axis=1) if common.sum() >= 20 else np.where(ok, residual, TRUNCATE).mean(1)
        prior = PRIOR * ((forward - expected[0]) ** 2 + (right - expected[1]) ** 2)
        return residual + prior

    def _wall_tangent(self, depth: np.ndarray) -> np.ndarray | None:
        """The unit direction (x right, z ahead) of the nearest surface across the image's middle rows, or None
        when too little of it is measured."""
        c = self.config
        h = depth.shape[0]
        z = np.median(depth[h // 2 - 8:h // 2 + 8], axis=0)
        x = (np.arange(depth.shape[1]) - self.K[0, 2]) * z / self.K[0, 0]
        keep = (z > c.min_depth + 1e-3) & (z < c.max_depth - 1e-3)
        keep &= z < z[keep].min() + 0.5 if keep.any() else keep
        if keep.sum() < 10:
            return None
        pts = np.stack([x[keep], z[keep]], axis=1)
        tangent = np.linalg.svd(pts - pts.mean(axis=0), full_matrices=False)[2][0]
        return tangent if tangent[1] >= 0 else -tangent

    def step_translation(self, before: np.ndarray, after: np.ndarray) -> tuple[float, float]:
        """The forward step's translation (metres forward, metres right of the heading) that best aligns depth
        frame ``before`` with ``after``: a coarse grid over every move a blocked or sliding step can make, then
        a fine one round its best; a step found stopped short is searched again expecting a slide along the wall
        ahead (module docstring)."""
        points = self._points(before)
        s = self.forward_step
        if len(points) < 20:
            return s, 0.0
        best = self._search(points, after, (s, 0.0))
        if best[0] < s - 0.05 and (tangent := self._wall_tangent(after)) is not None:
            slide = (s - best[0]) * float(tangent[1]) * tangent  # the rest of the step along the wall
            best = self._search(points, after, (best[0] + float(slide[1]), float(slide[0])))
        return best

    def _search(self, points: np.ndarray, after: np.ndarray, expected: tuple[float, float]) -> tuple[float, float]:
        s = self.forward_step
        best = expected
        for spacing, f_range, r_range in ((0.025, (-0.05, s + 0.05), (-s, s)), (0.005, None, None)):
            if f_range is None:
                f_range, r_range = (best[0] - 0.025, best[0] + 0.025), (best[1] - 0.025, best[1] + 0.025)
            fs = np.arange(f_range[0], f_range[1] + 1e-9, spacing)
            rs = np.arange(r_range[0], r_range[1] + 1e-9, spacing)
            F, R = (g.ravel() for g in np.meshgrid(fs, rs, indexing="ij"))
            k = int(np.argmin(self._scores(points, after, F, R, expected)))
            best = (float(F[k]), float(R[k]))
        return best


def _right_vector(yaw: float) -> np.ndarray:
    """Unit vector (x, 0, z) to the right of an agent with heading ``yaw``."""
    return np.array([math.cos(yaw), 0.0, -math.sin(yaw)])
