"""``pointnav``: the learned PointNav policy (habitat's PointNavResNetPolicy layout) as a benchmark agent.

Uses the shipped checkpoint ``policies/pointnav_navbench.pth`` unless another file in habitat's layout
is given (``navbench run --task pointnav --checkpoint PATH``). Actions are decoded as its
:class:`~navbench.policy.net.InferenceConfig` says (argmax, sampled, or least-tried: see ``decoding``),
any draws from a generator seeded by the run's seed and the episode, so a run is reproducible.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from navbench.agents.base import episode_seed
from navbench.agents.options import DEFAULT_CHECKPOINT
from navbench.episodes.types import Episode
from navbench.policy.checkpoint import load_checkpoint
from navbench.policy.net import InferenceConfig, PointNavAgentPolicy


class PointNavAgent:
    """Habitat's Agent protocol (``reset``/``act``, one episode) and, with ``num_envs > 1``, the batched
    :class:`navbench.agents.base.BatchAgent` protocol the runner uses to step several episodes with one
    forward pass (``navbench run --envs-per-worker N``)."""

    sensors: tuple[str, ...] = ("depth",)

    def __init__(self, checkpoint: str | Path | None = None, config: InferenceConfig = InferenceConfig(),
                 num_envs: int = 1, seed: int = 0, device: str = "cpu"):
        self.checkpoint = Path(checkpoint) if checkpoint else DEFAULT_CHECKPOINT
        self.num_envs, self.seed = num_envs, seed  # any draws: each episode's from (seed, episode)
        self.policy = PointNavAgentPolicy(load_checkpoint(self.checkpoint), num_envs=num_envs, config=config,
                                          device=device)

    def reset(self, episode: Episode) -> None:
        self.reset_env(0, episode)

    def act(self, observations: dict[str, np.ndarray]) -> int:
        if self.num_envs != 1:
            raise ValueError(f"act() steps one episode; this agent has {self.num_envs} slots: use act_batch")
        return int(self.act_batch([observations])[0])

    def reset_env(self, i: int, episode: Episode) -> None:
        # seeded by the episode, not by the slot or the order episodes arrive in
        self.policy.reset(i, seed=episode_seed(self.seed, episode))

    def act_batch(self, observations: list[dict[str, np.ndarray] | None]) -> np.ndarray:
        # a slot without an episode steps on another slot's frame (its state is reset before it is used)
        filler = next(o for o in observations if o is not None)
        obs = [filler if o is None else o for o in observations]
        return self.policy.act(np.stack([o["depth"] for o in obs]),
                               np.stack([o["pointgoal_with_gps_compass"] for o in obs]))
