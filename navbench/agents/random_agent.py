"""``random``: Habitat's RandomAgent. Uniform over MOVE_FORWARD/TURN_LEFT/TURN_RIGHT; on PointNav it
calls STOP once the point-goal sensor says it is inside the success distance (it never stops on
ObjectNav, which has no such sensor). Seeded per episode, so runs are reproducible."""

from __future__ import annotations

import numpy as np

from navbench.agents.base import episode_seed
from navbench.env.config import MOVE_FORWARD, STOP, TURN_LEFT, TURN_RIGHT
from navbench.episodes.types import Episode


class RandomAgent:
    sensors: tuple[str, ...] = ()

    def __init__(self, success_distance: float, seed: int = 0):
        self.success_distance = success_distance
        self.seed = seed

    def reset(self, episode: Episode) -> None:
        self._rng = np.random.default_rng(episode_seed(self.seed, episode))

    def act(self, observations: dict[str, np.ndarray]) -> int:
        goal = observations.get("pointgoal_with_gps_compass")
        if goal is not None and float(goal[0]) < self.success_distance:
            return STOP
        return int(self._rng.choice([MOVE_FORWARD, TURN_LEFT, TURN_RIGHT]))
