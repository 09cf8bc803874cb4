"""``pointnav``: the learned PointNav policy (habitat's PointNavResNetPolicy layout) as a benchmark agent.

Uses the shipped checkpoint ``policies/pointnav_navbench.pth`` unless another file in habitat's layout
is given (``navbench run --task pointnav --agent pointnav --checkpoint PATH``). Deterministic (argmax).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from navbench.episodes.types import Episode
from navbench.paths import POLICIES_DIR
from navbench.policy.checkpoint import load_checkpoint
from navbench.policy.net import InferenceConfig, PointNavAgentPolicy

DEFAULT_CHECKPOINT = POLICIES_DIR / "pointnav_navbench.pth"


class PointNavAgent:
    sensors: tuple[str, ...] = ("depth",)

    def __init__(self, checkpoint: str | Path | None = None, config: InferenceConfig = InferenceConfig()):
        self.checkpoint = Path(checkpoint) if checkpoint else DEFAULT_CHECKPOINT
        self.policy = PointNavAgentPolicy(load_checkpoint(self.checkpoint), num_envs=1, config=config)

    def reset(self, episode: Episode) -> None:
        self.policy.reset()

    def act(self, observations: dict[str, np.ndarray]) -> int:
        return int(self.policy.act(observations["depth"][None], observations["pointgoal_with_gps_compass"][None])[0])
