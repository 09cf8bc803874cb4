"""Rollout collection shared by the DAgger and PPO trainers.

    navbench train dagger --init runs/pointnav/encoder.pth --workers 2    # collects through this module
    navbench train ppo --init runs/pointnav/dagger.pth --workers 2

What both trainers need from their envs lives here: the training envs and their seeds (:func:`make_envs`),
tight starts (:func:`reset_maybe_tight`), the geodesic expert (:func:`make_expert`), per-env episode
bookkeeping (:class:`EnvSlots`), and collection either in this process or split over rollout worker processes
(:class:`Collection`). A trainer's collector (``navbench.policy.train.Collector``,
``navbench.policy.ppo.Rollout``) only decides what to record and which action to take.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np
import torch

from navbench.env.config import SUCCESS_DISTANCE, EnvConfig
from navbench.env.pointnav import PointNavEnv
from navbench.episodes.io import load_dataset
from navbench.paths import split_file
from navbench.policy.workers import WorkerError, WorkerPool
from navbench.scene.follower import GreedyFollower
from navbench.scene.pose import quat_from_yaw


def make_envs(n: int, split: str, seed: int, first: int = 0) -> list[PointNavEnv]:
    """Envs ``first .. first + n - 1`` of a training run: env ``i`` is seeded with ``seed * 1000 + i``, so a
    run split over workers draws the same episode streams as one process with all the envs."""
    ds = load_dataset(split_file("pointnav", split))
    cfg = EnvConfig(rgb=False, depth=True, success_distance=SUCCESS_DISTANCE["pointnav"])
    envs = [PointNavEnv(ds, config=cfg) for _ in range(n)]
    for i, env in enumerate(envs):
        env.reset(seed=seed * 1000 + first + i)
    return envs


def worker_shares(num_envs: int, workers: int) -> list[tuple[int, int]]:
    """(first env, env count) of each rollout worker: ``num_envs`` split as evenly as it goes."""
    if workers < 1 or workers > num_envs:
        raise ValueError(f"workers must be between 1 and num_envs ({num_envs}), got {workers}")
    counts = [num_envs // workers + (w < num_envs % workers) for w in range(workers)]
    return [(sum(counts[:w]), counts[w]) for w in range(workers)]


# A tight start is a navigable cell this close to the grid's edge: at most this much room between the body and an
# obstacle (the grid is already eroded by the agent's radius).
TIGHT_CLEARANCE = 0.1
TIGHT_MIN_DISTANCE = 1.0  # metres of geodesic distance to the goal, so the episode is not over at once


def reset_maybe_tight(env: PointNavEnv, rng: np.random.Generator, p: float) -> dict:
    """``env.reset()`` (the env's own seeded draw), and with probability ``p`` the same episode again from a
    tight start: a random navigable cell within ``TIGHT_CLEARANCE`` of an obstacle, at least
    ``TIGHT_MIN_DISTANCE`` from the goal on its island, facing a random heading. Returns the first observation.

    Why: uniform starts rarely put the agent wedged beside furniture, where a policy that presses FORWARD against
    what its depth camera cannot see (nearer than its minimum depth) fails most; DAgger's expert then labels every
    step of the way out.
    """
    obs, _ = env.reset()
    if p <= 0 or rng.random() >= p:
        return obs
    field = env.navgrid.distance_field(env.goal_points)
    for _ in range(20):
        start = env.navgrid.sample_tight_point(rng, TIGHT_CLEARANCE)
        if start is None:
            break
        if TIGHT_MIN_DISTANCE <= field.distance(start) < np.inf:
            ep = dataclasses.replace(env.episode, episode_id=f"{env.episode.episode_id}-tight",
                                     start_position=[float(v) for v in start],
                                     start_rotation=[float(v) for v in quat_from_yaw(rng.uniform(-np.pi, np.pi))])
            return env.reset(options={"episode": ep})[0]
    return obs  # no tight cell reaches the goal: keep the episode as drawn


def make_expert(env: PointNavEnv, success_distance: float, margin: float) -> GreedyFollower:
    """The geodesic expert of ``env``'s current episode: the shortest path, keeping ``margin`` of extra clearance
    where it can, saying STOP within ``success_distance`` of the goal."""
    return GreedyFollower(env.navgrid, env.goal_points, success_distance, clearance_margin=margin)


class EnvSlots:
    """``envs`` with their current observations, restarted as their episodes end.

    A restart draws the env's next episode (a tight start with probability ``tight_starts``, drawn from ``rng``)
    and, with ``expert=(success_distance, margin)``, builds that episode's geodesic expert. ``step`` also says
    whether the action was a refused FORWARD (the env counts it as a collision).
    """

    def __init__(self, envs: list[PointNavEnv], rng: np.random.Generator, tight_starts: float,
                 expert: tuple[float, float] | None = None):
        self.envs, self.rng, self.tight_starts, self.expert = envs, rng, tight_starts, expert
        n = len(envs)
        self.obs: list[dict] = [{}] * n
        self.experts: list[GreedyFollower | None] = [None] * n
        self.collisions = [0] * n  # the env's collision count so far this episode
        for i in range(n):
            self.restart(i)

    def __len__(self) -> int:
        return len(self.envs)

    def restart(self, i: int) -> dict:
        env = self.envs[i]
        self.obs[i] = reset_maybe_tight(env, self.rng, self.tight_starts)
        self.collisions[i] = 0
        if self.expert is not None:
            self.experts[i] = make_expert(env, *self.expert)
        return self.obs[i]

    def label(self, i: int) -> int:
        """The expert's action where env ``i``'s agent stands."""
        env = self.envs[i]
        return int(self.experts[i].next_action(env.agent_position, env.agent_rotation))

    def step(self, i: int, action: int) -> tuple[bool, bool, dict, bool]:
        """(terminated, truncated, info, blocked): ``blocked`` when this FORWARD did not move the agent."""
        self.obs[i], _, term, trunc, info = self.envs[i].step(action)
        blocked = info["collisions"] > self.collisions[i]
        self.collisions[i] = info["collisions"]
        return term, trunc, info, blocked

    def snapshot(self) -> dict:
        """Every env's episode in progress, the start draws' random stream and the experts' plans."""
        experts = [None if e is None else {"plan_xz": e._plan_xz, "plan_yaw": e._plan_yaw, "yaw0": e._yaw0,
                                           "turns_ahead": e.turns_ahead} for e in self.experts]
        return {"envs": [env.snapshot() for env in self.envs], "rng": self.rng.bit_generator.state,
                "collisions": list(self.collisions), "experts": experts}

    def restore(self, snap: dict) -> None:
        """Continue from :meth:`snapshot`'s state (the envs must step the same datasets)."""
        if len(snap["envs"]) != len(self.envs):
            raise ValueError(f"a snapshot of {len(snap['envs'])} envs cannot continue {len(self.envs)}")
        for i, (env, s) in enumerate(zip(self.envs, snap["envs"])):
            self.obs[i] = env.restore(s)
            e = snap["experts"][i]
            if self.expert is not None and e is not None:
                f = self.experts[i] = make_expert(env, *self.expert)
                f._plan_xz = None if e["plan_xz"] is None else tuple(e["plan_xz"])
                f._plan_yaw, f._yaw0, f.turns_ahead = e["plan_yaw"], e["yaw0"], e["turns_ahead"]
        self.collisions = list(snap["collisions"])
        self.rng.bit_generator.state = snap["rng"]

    def close(self) -> None:
        for env in self.envs:
            env.close()


class RolloutCollector(Protocol):
    """What :class:`Collection` drives: ``policy`` acts, ``collect(*args)`` steps the envs."""

    policy: torch.nn.Module

    def collect(self, *args: Any) -> Any: ...


class CollectorWorker:
    """A rollout worker's object: its share of the envs and its own collector, built by
    ``cls.for_worker(cfg, envs, rng_seed)``, whose policy ``collect`` refreshes with the trainer's weights."""

    def __init__(self, cls: type, cfg: Any, first: int, num_envs: int, env_seed: int, rng_seed: list[int]):
        self.collector = cls.for_worker(cfg, make_envs(num_envs, cfg.train_split, env_seed, first), rng_seed)

    def collect(self, weights: dict[str, torch.Tensor], args: tuple) -> Any:
        policy = self.collector.policy
        policy.load_state_dict({**policy.state_dict(), **weights})
        return self.collector.collect(*args)

    def snapshot(self) -> dict:
        return self.collector.snapshot()

    def restore(self, snap: dict) -> None:
        self.collector.restore(snap)

    def close(self) -> None:
        for env in self.collector.envs:
            env.close()


class Collection:
    """Collection for a trainer: its collector in this process (``local``), or one per rollout worker.

    ``collect(policy, *args)`` returns what the collector's ``collect(*args)`` returns; over workers, each worker
    first receives ``policy``'s weights (the frozen visual encoder's only once), collects with
    ``cls.worker_args(args, workers)``, and the answers are joined by ``cls.merge`` in worker order, so a seed
    gives the same data whatever the timing.
    """

    def __init__(self, local: RolloutCollector | None = None, pool: WorkerPool | None = None, cls: type | None = None):
        self.local, self.pool, self.cls = local, pool, cls
        self._encoder_sent = False

    @classmethod
    def in_workers(cls, collector_cls: type, cfg: Any, env_seed: int, rng_seeds: Sequence[list[int]],
                   first_env: int = 0) -> Collection:
        """``cfg.workers`` processes, worker ``w`` stepping its share of ``cfg.num_envs`` envs (seeded from
        ``env_seed`` as in one process, numbered from ``first_env``) with random streams from ``rng_seeds[w]``."""
        shares = worker_shares(cfg.num_envs, cfg.workers)
        pool = WorkerPool(CollectorWorker, [(collector_cls, cfg, first_env + first, n, env_seed, rng_seeds[w])
                                            for w, (first, n) in enumerate(shares)],
                          threads=max(1, cfg.threads // cfg.workers))
        return cls(pool=pool, cls=collector_cls)

    def collect(self, policy: torch.nn.Module, *args: Any) -> Any:
        if self.local is not None:
            return self.local.collect(*args)
        weights = {k: v.cpu() for k, v in policy.state_dict().items()  # the workers' policies are on the CPU
                   if not self._encoder_sent or not k.startswith("net.visual_encoder.")}
        self._encoder_sent = True
        share = self.cls.worker_args(args, len(self.pool))
        return self.cls.merge(self.pool.call("collect", [(weights, share)] * len(self.pool)))

    def snapshot(self) -> list[dict]:
        """Each collector's state (one per worker, or the local one's), for an exact resume."""
        if self.local is not None:
            return [self.local.snapshot()]  # type: ignore[attr-defined]
        return self.pool.call("snapshot")

    def restore(self, snaps: list[dict]) -> None:
        if self.local is not None:
            if len(snaps) != 1:
                raise ValueError(f"a snapshot of {len(snaps)} rollout workers cannot continue in one process")
            self.local.restore(snaps[0])  # type: ignore[attr-defined]
            return
        if len(snaps) != len(self.pool):
            raise ValueError(f"a snapshot of {len(snaps)} rollout workers cannot continue in {len(self.pool)}")
        self.pool.call("restore", [(s,) for s in snaps])

    def close(self) -> None:
        if self.pool is not None:
            try:
                self.pool.call("close")
            except (WorkerError, OSError):  # a worker already gone (killed): the pool still ends the others
                pass
            self.pool.close()
        else:
            for env in self.local.envs:
                env.close()
