"""The agent protocol (Habitat's): ``reset(episode)`` once per episode, then ``act(observations)`` per step.

An agent may also expose ``sensors`` (which rendered observations it needs, so the evaluator can skip
rendering the rest) and ``episode_log()`` (decisions to record in ``episodes.jsonl``).
"""

from __future__ import annotations

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
