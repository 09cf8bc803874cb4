"""``pointnav``: the learned PointNav policy (habitat's PointNavResNetPolicy layout) as a benchmark agent.

Uses the shipped checkpoint ``policies/pointnav_navbench.pth`` unless another file in habitat's layout
is given (``navbench run --task pointnav --checkpoint PATH``). Actions are decoded as its
:class:`~navbench.policy.net.InferenceConfig` says (argmax, sampled, or least-tried: see ``decoding``),
any draws from a generator seeded by the run's seed and the episode, so a run is reproducible.

Without GPS+compass (Habitat's PointNav challenge configurations give only the static ``pointgoal``, the
goal from the start pose) it dead-reckons: it integrates its own commanded actions, each FORWARD as a full
``forward_step`` and each turn as a full ``turn_angle``, and feeds the policy the goal from that estimate.
Collisions and actuation noise make the estimate drift: it is the baseline a learned odometry improves on.
Depth in another range than the policy was trained on (0.5-5 m; the challenges' 0.1-10 m) is mapped back to it.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from navbench.agents.base import episode_seed
from navbench.agents.options import DEFAULT_CHECKPOINT
from navbench.env.config import MOVE_FORWARD, TURN_LEFT, TURN_RIGHT, EnvConfig
from navbench.env.sensors import from_agent_frame, pointgoal_polar
from navbench.episodes.types import Episode
from navbench.policy.checkpoint import load_checkpoint
from navbench.policy.net import InferenceConfig, PointNavAgentPolicy
from navbench.scene.pose import heading_vector, wrap_angle

TRAINED_DEPTH = (EnvConfig.min_depth, EnvConfig.max_depth)  # the depth range the shipped policies were trained on


class PointNavAgent:
    """Habitat's Agent protocol (``reset``/``act``, one episode) and, with ``num_envs > 1``, the batched
    :class:`navbench.agents.base.BatchAgent` protocol the runner uses to step several episodes with one
    forward pass (``navbench run --envs-per-worker N``)."""

    sensors: tuple[str, ...] = ("depth",)

    def __init__(self, checkpoint: str | Path | None = None, config: InferenceConfig = InferenceConfig(),
                 num_envs: int = 1, seed: int = 0, step: tuple[float, float] = (0.25, 30.0),
                 depth: tuple[float, float, bool] = (TRAINED_DEPTH[0], TRAINED_DEPTH[1], True), device: str = "cpu"):
        self.checkpoint = Path(checkpoint) if checkpoint else DEFAULT_CHECKPOINT
        self.num_envs, self.seed = num_envs, seed  # any draws: each episode's from (seed, episode)
        self.policy = PointNavAgentPolicy(load_checkpoint(self.checkpoint), num_envs=num_envs, config=config,
                                          device=device)
        self.step = step  # (forward metres, turn degrees) of a commanded action, for dead reckoning
        self._reckon: list[DeadReckoning | None] = [None] * num_envs
        self.depth = depth  # the env's (min_depth, max_depth, normalize_depth)

    def _depth(self, d: np.ndarray) -> np.ndarray:
        """The depth observation in the range the policy was trained on (EnvConfig's default, 0.5-5 m)."""
        lo, hi, normalized = self.depth
        if normalized and (lo, hi) == TRAINED_DEPTH:
            return d
        m = d * (hi - lo) + lo if normalized else d
        return np.clip((m - TRAINED_DEPTH[0]) / (TRAINED_DEPTH[1] - TRAINED_DEPTH[0]), 0.0, 1.0).astype(np.float32)

    def reset(self, episode: Episode) -> None:
        self.reset_env(0, episode)

    def act(self, observations: dict[str, np.ndarray]) -> int:
        if self.num_envs != 1:
            raise ValueError(f"act() steps one episode; this agent has {self.num_envs} slots: use act_batch")
        return int(self.act_batch([observations])[0])

    def reset_env(self, i: int, episode: Episode) -> None:
        # seeded by the episode, not by the slot or the order episodes arrive in
        self.policy.reset(i, seed=episode_seed(self.seed, episode))
        self._reckon[i] = None

    def _goal(self, i: int, o: dict[str, np.ndarray]) -> np.ndarray:
        if "pointgoal_with_gps_compass" in o:
            return o["pointgoal_with_gps_compass"]
        if "pointgoal" not in o:
            raise KeyError("the pointnav agent reads pointgoal_with_gps_compass, or pointgoal (dead reckoning)")
        if self._reckon[i] is None:
            self._reckon[i] = DeadReckoning(o["pointgoal"], *self.step)
        reckon = self._reckon[i]
        assert reckon is not None
        return reckon.pointgoal()

    def act_batch(self, observations: list[dict[str, np.ndarray] | None]) -> np.ndarray:
        # a slot without an episode steps on another slot's frame (its state is reset before it is used)
        filler = next(o for o in observations if o is not None)
        obs = [filler if o is None else o for o in observations]
        goals = [self._goal(i, o) for i, o in enumerate(obs)]
        actions = self.policy.act(np.stack([self._depth(o["depth"]) for o in obs]), np.stack(goals))
        for i, o in enumerate(observations):
            reckon = self._reckon[i]
            if o is not None and reckon is not None:
                reckon.advance(int(actions[i]))
        return actions


class DeadReckoning:
    """The goal from an agent's own commanded actions: the static ``pointgoal`` (from the start pose) and a
    pose integrated as if every action moved exactly as commanded.

    >>> r = DeadReckoning(np.array([2.0, 0.0], np.float32), 0.25, 30.0)
    >>> r.advance(1); r.advance(2)  # forward, then left: the goal is 1.75 m away, 30 degrees to the right
    >>> [round(float(v), 3) for v in r.pointgoal()]
    [1.75, -0.524]
    """

    def __init__(self, pointgoal: np.ndarray, forward_step: float, turn_angle_deg: float):
        rho, theta = float(pointgoal[0]), float(pointgoal[1])
        # the goal in the start frame (start at the origin, yaw 0), theta counter-clockwise positive
        self.goal = from_agent_frame(rho * math.cos(theta), -rho * math.sin(theta), 0.0)
        self.position, self.yaw = np.zeros(3), 0.0
        self.forward_step, self.turn = forward_step, math.radians(turn_angle_deg)

    def advance(self, action: int) -> None:
        if action == MOVE_FORWARD:
            self.position = self.position + self.forward_step * heading_vector(self.yaw)
        elif action in (TURN_LEFT, TURN_RIGHT):
            self.yaw = wrap_angle(self.yaw + (self.turn if action == TURN_LEFT else -self.turn))

    def pointgoal(self) -> np.ndarray:
        return pointgoal_polar(self.goal, self.position, self.yaw)
