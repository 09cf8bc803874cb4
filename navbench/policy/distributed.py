"""Decentralised distributed training (DD-PPO's scheme) on ``torch.distributed`` for the DAgger and PPO trainers.

    navbench train ppo --init runs/pointnav/dagger.pth --resume                    # one process, as always
    torchrun --standalone --nproc-per-node 2 -m navbench train ppo --init ... --resume
    torchrun --nnodes 2 --nproc-per-node 4 --rdzv-backend c10d --rdzv-endpoint HOST:29400 \\
        -m navbench train --config configs/pointnav/v2.toml --resume               # on every machine
    srun python -m navbench train ppo ...                                          # under SLURM (docs/rl.md)

Every rank steps its own envs (env ``i`` of rank ``r`` seeded ``base + r * num_envs + i``), computes its own
update from its own rollout, and the gradients are averaged across ranks inside the backward pass
(``DistributedDataParallel`` around the training forward only; acting never synchronises). Rank and world size
come from torchrun's variables (``RANK``, ``WORLD_SIZE``, ``LOCAL_RANK``, ``MASTER_ADDR``/``MASTER_PORT``) or
SLURM's (``SLURM_PROCID``, ``SLURM_NTASKS``, ``SLURM_LOCALID``, the first host of ``SLURM_JOB_NODELIST``);
without either the trainer runs as one process and this module does nothing. gloo on CPU, NCCL on CUDA.

Preemption (DD-PPO's "sync fraction"): a rank whose envs are slow ends its rollout early once
``preempt_fraction`` of the ranks have finished theirs, provided it has collected ``preempt_min_share`` of its
steps; a shared counter in the process group's store says how many have finished.

SIGTERM and SIGUSR1 (SLURM's warning before a time limit, ``--signal=USR1@90``) make every rank finish its
current update, save the resume state and exit; ``--resume`` (implied on a torchrun restart) continues from it.
"""

from __future__ import annotations

import datetime
import os
import re
import signal
import socket
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
import torch.distributed as dist

DEFAULT_PORT = 29500


@dataclass(frozen=True)
class DistInfo:
    """Where this process stands in the run: ``world_size`` 1 means a plain single-process run."""

    rank: int = 0
    world_size: int = 1
    local_rank: int = 0
    backend: str = ""

    @property
    def distributed(self) -> bool:
        return self.world_size > 1

    @property
    def is_main(self) -> bool:
        return self.rank == 0


def first_slurm_host(nodelist: str) -> str:
    """The first host of a SLURM node list (``node[03-05,09],gpu1`` -> ``node03``), what ``scontrol show
    hostnames | head -n 1`` prints."""
    m = re.match(r"([^,\[]+)(?:\[([^\]]+)\])?", nodelist.strip())
    if not m:
        raise ValueError(f"SLURM_JOB_NODELIST {nodelist!r}: no host name in it")
    prefix, ranges = m.group(1), m.group(2)
    if not ranges:
        return prefix
    return prefix + ranges.split(",")[0].split("-")[0]


def launch_env(environ: dict[str, str] | None = None) -> dict[str, str]:
    """The ``torch.distributed`` variables this process was launched with: torchrun's as they are, SLURM's
    translated (``MASTER_PORT`` offset by the job id, so two jobs on one node do not collide); empty when
    neither launched it with more than one process."""
    env = dict(os.environ if environ is None else environ)
    if int(env.get("WORLD_SIZE", "1")) > 1 and "RANK" in env:
        return {k: env[k] for k in ("RANK", "WORLD_SIZE", "LOCAL_RANK", "MASTER_ADDR", "MASTER_PORT") if k in env}
    if int(env.get("SLURM_NTASKS", "1")) > 1 and "SLURM_PROCID" in env:
        job = int(env.get("SLURM_JOB_ID", "0") or 0)
        return {"RANK": env["SLURM_PROCID"], "WORLD_SIZE": env["SLURM_NTASKS"],
                "LOCAL_RANK": env.get("SLURM_LOCALID", "0"),
                "MASTER_ADDR": env.get("MASTER_ADDR") or first_slurm_host(env.get("SLURM_JOB_NODELIST", "127.0.0.1")),
                "MASTER_PORT": env.get("MASTER_PORT") or str(DEFAULT_PORT + job % 1000)}
    return {}


_INFO = DistInfo()


def init(device: str = "cpu", timeout_s: float = 4 * 3600.0) -> DistInfo:
    """Join the process group this process was launched into (once; later calls return the same answer)."""
    global _INFO
    if dist.is_available() and dist.is_initialized():
        return _INFO
    env = launch_env()
    if not env:
        _INFO = DistInfo()
        return _INFO
    os.environ.update(env)
    backend = "nccl" if torch.device(device).type == "cuda" else "gloo"
    rank, world = int(env["RANK"]), int(env["WORLD_SIZE"])
    timeout = datetime.timedelta(seconds=timeout_s)
    # torchrun's agent already serves a store at MASTER_ADDR:MASTER_PORT (it outlives restarts); otherwise rank 0
    # serves one. Each restart keeps its keys apart, so a restarted rank never reads a dead rank's address.
    agent = os.environ.get("TORCHELASTIC_USE_AGENT_STORE", "").lower() == "true"
    store = dist.TCPStore(env["MASTER_ADDR"], int(env["MASTER_PORT"]), world, is_master=not agent and rank == 0,
                          timeout=timeout, wait_for_workers=False)
    attempt = os.environ.get("TORCHELASTIC_RESTART_COUNT", "0")
    dist.init_process_group(backend, store=dist.PrefixStore(f"navbench/attempt_{attempt}", store), rank=rank,
                            world_size=world, timeout=timeout)
    _INFO = DistInfo(dist.get_rank(), dist.get_world_size(), int(env.get("LOCAL_RANK", "0")), backend)
    return _INFO


def rank_device(device: str) -> str:
    """The device this rank trains on: on CUDA in a distributed run, the GPU of its local rank (one per process,
    as torchrun and SLURM lay ranks out on a node); else ``device`` as given."""
    if _INFO.distributed and torch.device(device).type == "cuda":
        return f"cuda:{_INFO.local_rank}"
    return device


def info() -> DistInfo:
    return _INFO


def shutdown() -> None:
    global _INFO
    if dist.is_available() and dist.is_initialized():
        dist.destroy_process_group()
    _INFO = DistInfo()


def restarted() -> bool:
    """Whether torchrun restarted this worker after a failure (its state then has to be resumed)."""
    return int(os.environ.get("TORCHELASTIC_RESTART_COUNT", "0") or 0) > 0


# ------------------------------------------------------------------------------------------- reductions
def all_sum(values: list[float]) -> list[float]:
    """Elementwise sums over the ranks (float64); the values themselves in a single-process run."""
    if not _INFO.distributed:
        return list(values)
    t = torch.tensor(values, dtype=torch.float64)
    dist.all_reduce(t)
    return t.tolist()


def all_min(values: list[float]) -> list[float]:
    if not _INFO.distributed:
        return list(values)
    t = torch.tensor(values, dtype=torch.float64)
    dist.all_reduce(t, op=dist.ReduceOp.MIN)
    return t.tolist()


def all_mean(stats: dict[str, float]) -> dict[str, float]:
    """The mean over the ranks of each statistic (NaN stays NaN only where every rank has NaN)."""
    if not _INFO.distributed or not stats:
        return dict(stats)
    keys = list(stats)  # every rank builds its stats in the same order
    vals = np.array([stats[k] for k in keys], np.float64)
    ok = np.isfinite(vals)
    sums = all_sum([*np.where(ok, vals, 0.0).tolist(), *ok.astype(float).tolist()])
    n = len(keys)
    return {k: (sums[i] / sums[n + i] if sums[n + i] > 0 else float("nan")) for i, k in enumerate(keys)}


def barrier() -> None:
    if _INFO.distributed:
        dist.barrier()


class ForwardFeatures(torch.nn.Module):
    """The policy's training forward (``forward_features``) as a module's ``forward``, what DDP wraps."""

    def __init__(self, policy: torch.nn.Module):
        super().__init__()
        self.policy = policy

    def forward(self, *args: Any) -> Any:
        return self.policy.forward_features(*args)  # type: ignore[operator]


def training_forward(policy: torch.nn.Module) -> Any:
    """``policy.forward_features``, gradient-averaged across ranks in a distributed run (DDP; parameters the
    loss does not reach, such as the critic under imitation, are allowed)."""
    if not _INFO.distributed:
        return policy.forward_features
    from torch.nn.parallel import DistributedDataParallel

    return DistributedDataParallel(ForwardFeatures(policy), find_unused_parameters=True)


# ------------------------------------------------------------------------------------------ preemption
class Preemption:
    """DD-PPO's early end of a rollout: ``should_stop(done, total)`` is True once ``fraction`` of the ranks
    have called ``finished()`` for this rollout and ``done >= min_share * total``. Never in a one-rank run.
    ``rollout`` names the rollout uniquely within the run (e.g. ``<checkpoint name>/<update>``: a recipe's stages
    share the process group's store)."""

    def __init__(self, fraction: float, min_share: float, rollout: str):
        self.fraction, self.min_share = fraction, min_share
        self.store = None
        self.key = ""
        if _INFO.distributed and fraction < 1.0:
            self.store = dist.distributed_c10d._get_default_store()
            attempt = os.environ.get("TORCHELASTIC_RESTART_COUNT", "0")
            self.key = f"navbench/preempt/{attempt}/{rollout}"

    def should_stop(self, done: int, total: int) -> bool:
        if self.store is None or done < max(1.0, self.min_share * total):
            return False
        return self.store.add(self.key, 0) >= self.fraction * _INFO.world_size

    def finished(self) -> None:
        if self.store is not None:
            self.store.add(self.key, 1)


# --------------------------------------------------------------------------------------------- signals
class StopSignals:
    """Notes SIGTERM and SIGUSR1 instead of dying at once, so the loop saves its resume state and exits after
    the update in progress; ``requested()`` agrees across the ranks (any rank signalled stops them all)."""

    SIGNALS = (signal.SIGTERM, signal.SIGUSR1)

    def __init__(self):
        self.signum: int | None = None
        self._old: dict[int, Any] = {}

    def __enter__(self) -> StopSignals:
        try:
            for s in self.SIGNALS:
                self._old[s] = signal.signal(s, self._note)
        except ValueError:  # not the main thread: signals stay as they were
            self._old = {}
        return self

    def _note(self, signum, frame) -> None:
        self.signum = signum

    def requested(self) -> bool:
        return all_sum([1.0 if self.signum is not None else 0.0])[0] > 0

    def __exit__(self, *exc) -> None:
        for s, h in self._old.items():
            signal.signal(s, h)


# ------------------------------------------------------------------------------------------------ RNGs
def rng_state(rng: np.random.Generator) -> dict:
    return rng.bit_generator.state


def set_rng_state(rng: np.random.Generator, state: dict) -> None:
    rng.bit_generator.state = state


def free_port() -> int:
    """A free TCP port on 127.0.0.1 (for loopback runs and tests)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# ------------------------------------------------------------------------------------------ resume state
def rank_seeds(seed: int | list[int], rank: int | None = None) -> int | list[int]:
    """A seed of this rank's own: ``seed`` itself on rank 0 (a one-process run's random streams)."""
    rank = _INFO.rank if rank is None else rank
    if rank == 0:
        return seed
    return [*(seed if isinstance(seed, list) else [seed]), 7777, rank]


def rank_state_path(path, rank: int | None = None):
    """Where rank ``rank`` keeps its own part of the resume state (rank 0: ``path`` itself)."""
    from pathlib import Path

    path, rank = Path(path), _INFO.rank if rank is None else rank
    return path if rank == 0 else path.with_name(f"{path.stem}.rank{rank}{path.suffix}")


def save_resume(path, shared: dict, local: dict) -> None:
    """Rank 0 writes ``shared`` (weights, optimiser, counters) with its ``local`` part (envs in flight, random
    streams); every other rank writes its ``local`` part beside it. Each part names the counter it was saved at."""
    from navbench.policy.checkpoint import save_train_state

    own = {"local": local, "world_size": _INFO.world_size}
    save_train_state(rank_state_path(path), {**shared, **own} if _INFO.is_main else own)
    barrier()


def load_local(path, counter: str, at: int) -> dict | None:
    """This rank's part of the resume state saved at ``counter`` == ``at`` by a run of the same world size,
    else None (the rank then starts its envs afresh)."""
    from navbench.policy.checkpoint import read_train_state

    p = rank_state_path(path)
    if not p.is_file():
        return None
    st = read_train_state(p)
    local = st.get("local")
    if not isinstance(local, dict) or st.get("world_size") != _INFO.world_size or local.get(counter) != at:
        return None
    return local
