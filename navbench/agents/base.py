"""The agent protocol (Habitat's): ``reset(episode)`` once per episode, then ``act(observations)`` per step.

An agent may also expose ``sensors`` (which rendered observations it needs, so the evaluator can skip
rendering the rest) and ``episode_log()`` (decisions to record in ``episodes.jsonl``).
"""

from __future__ import annotations

import math
from typing import Any, Protocol, runtime_checkable

import numpy as np

from navbench.episodes.types import Episode
from navbench.env.sensors import world_pose
from navbench.scene.pose import yaw_from_quat


@runtime_checkable
class Agent(Protocol):
    sensors: tuple[str, ...]  # subset of ("rgb", "depth", "semantic")

    def reset(self, episode: Episode) -> None: ...

    def act(self, observations: dict[str, np.ndarray]) -> int: ...


def episode_log(agent: Agent) -> dict[str, Any]:
    log = getattr(agent, "episode_log", None)
    return log() if callable(log) else {}


class PoseTracker:
    """World pose from the episode's start pose plus GPS+compass, the way Habitat agents know it."""

    def reset(self, episode: Episode) -> None:
        self.start_position = np.asarray(episode.start_position, np.float64)
        self.start_yaw = yaw_from_quat(np.asarray(episode.start_rotation, np.float64))

    def __call__(self, observations: dict[str, np.ndarray]) -> tuple[np.ndarray, float]:
        return world_pose(observations["gps"], observations["compass"], self.start_position, self.start_yaw)


def xz_dist(a: np.ndarray, b: np.ndarray) -> float:
    """Distance in the floor plane (navigation thresholds are all measured in xz)."""
    return math.hypot(float(a[0] - b[0]), float(a[2] - b[2]))


def xz_dists(points: np.ndarray, p: np.ndarray) -> np.ndarray:
    return np.hypot(points[:, 0] - p[0], points[:, 2] - p[2])


def log_value(v: Any) -> Any:
    """A decision-log value as compact JSON: floats and arrays rounded to millimetres."""
    if isinstance(v, (float, np.floating)):
        return round(float(v), 3)
    if isinstance(v, np.ndarray):
        return [round(float(x), 3) for x in v.ravel()]
    return v
