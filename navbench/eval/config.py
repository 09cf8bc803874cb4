"""What decides a run's records: :class:`RunConfig` (the task, the episodes, the agent and its options,
the seed) and which episodes a run selects; and apart from it, :class:`Execution`: how the records are
produced (workers, backend, retries, limits), which never changes them.

    >>> select_episodes(EpisodeDataset(), limit=3)
    []
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from navbench.env.config import EnvConfig
from navbench.episodes.types import Episode, EpisodeDataset
from navbench.eval.rundir import RunError

__all__ = ["BACKENDS", "Execution", "RunConfig", "parse_shard", "recorded_paths", "select_episodes", "shard_of"]

BACKENDS = ("local", "ray")


@dataclass
class RunConfig:
    """A run as ``config.json`` records it: everything its records depend on, and the batch width its
    agent is built for (``envs_per_worker``, which records do not depend on, so a run may resume with
    another). Agent factories read it (``agent_options``, ``envs_per_worker``, ``env_config(sensors)``)."""
    task: str  # a task of navbench.tasks.TASKS ("pointnav", "objectnav", "imagenav"...)
    split: str | None  # bundled split name, or None for a user's file
    agent: str
    episodes: str  # dataset file
    scene_dir: str
    success_distance: float
    seed: int = 0
    limit: int | None = None
    # The first per_scene episodes of each scene (file order) before limit applies: a small run that
    # still covers every scene of a split whose file lists its episodes scene by scene.
    per_scene: int | None = None
    env: dict[str, Any] = field(default_factory=dict)  # EnvConfig overrides
    agent_options: dict[str, Any] = field(default_factory=dict)  # e.g. {"checkpoint": ...}
    label: str = ""  # the row name in tables (default: the agent's name)
    # Episodes each worker steps at once with one batched policy forward pass (agents with act_batch,
    # e.g. pointnav; others run one episode at a time). Outcomes do not depend on it.
    envs_per_worker: int = 1
    # "I/N": this run is shard I (1-based) of N, the I-th of N contiguous blocks of the selected episodes
    # in file order (see select_episodes); None: all of them.
    shard: str | None = None
    # Where the agent's torch work runs (resolved: "cpu" or "cuda:N"; records agree with the CPU's up to
    # the last bits of float arithmetic) and the precision of real perception models ("fp32", "bf16",
    # "fp16"). config.json records each only when it is not the default (cpu, fp32).
    device: str = "cpu"
    precision: str = "fp32"
    # The named environment configuration (configs/env/NAME.toml, or a file's stem) ``env`` came from; None:
    # navbench's defaults with the ``env`` overrides.
    env_config_name: str | None = None
    # A Habitat configuration the run's settings were read from (--habitat-config): its file, sha256, each
    # value used by its full key and the keys ignored (navbench.eval.habitat_config); None: none.
    habitat_config: dict[str, Any] | None = None
    # VLN-CE: the gt paths file given with --gt (None: the one beside the episode file, as VLN-CE finds it).
    gt: str | None = None

    def env_config(self, sensors: tuple[str, ...]) -> EnvConfig:
        base = EnvConfig(success_distance=self.success_distance, **self.env)
        # Render only what the agent reads: the oracle needs no images, a PointNav policy only depth.
        return dataclasses.replace(base, rgb="rgb" in sensors, depth="depth" in sensors,
                                   semantic="semantic" in sensors)


@dataclass(frozen=True)
class Execution:
    """How a run's episodes are run; the records are the same whatever these are, so a run may resume
    with others. A setting out of range is a one-line RunError.

    Attributes:
        workers: parallel episode workers (processes, or with ``backend="ray"`` and no ``address`` the
            CPUs of the local Ray instance started for the run).
        backend: ``"local"`` (worker processes) or ``"ray"`` (:mod:`navbench.eval.ray_backend`).
        address: the Ray cluster to join (``backend="ray"`` only).
        retries: times an episode whose worker died is retried on a fresh worker before it is failed.
        step_timeout: seconds an agent call may take before its episode fails (with workers, a call that
            never returns is killed).
        fail_fast: stop at the first failed episode (RunError) instead of recording it and going on.

    >>> Execution(workers=2).backend
    'local'
    """
    workers: int = 1
    backend: str = "local"
    address: str | None = None
    retries: int = 2
    step_timeout: float | None = None
    fail_fast: bool = False

    def __post_init__(self) -> None:
        if self.workers < 1:
            raise RunError(f"--workers must be 1 or more, got {self.workers}")
        if self.step_timeout is not None and not self.step_timeout > 0:
            raise RunError(f"--step-timeout must be positive, got {self.step_timeout:g}")
        if self.retries < 0:
            raise RunError(f"--retries must be 0 or more, got {self.retries}")
        if self.backend not in BACKENDS:
            raise RunError(f"backend {self.backend!r}: choose {' or '.join(BACKENDS)}")
        if self.address is not None and self.backend != "ray":
            raise RunError("--address applies to --backend ray only")


def parse_shard(shard: str | None) -> tuple[int, int] | None:
    """``"I/N"`` as (I, N) with 1 <= I <= N; a ValueError saying what is wrong otherwise."""
    if shard is None:
        return None
    try:
        i, n = (int(x) for x in str(shard).split("/"))
    except ValueError:
        raise RunError(f"--shard {shard!r}: expected I/N, e.g. 2/8") from None
    if not 1 <= i <= n:
        raise RunError(f"--shard {shard!r}: I must be between 1 and N")
    return i, n


def shard_of(episodes: list, shard: str | None) -> list:
    """Shard I of N: the I-th of N contiguous blocks of ``episodes`` (sizes differ by at most one). Blocks
    keep a scene's episodes together (episode files list them scene by scene), so a shard loads few scenes;
    the N shards are disjoint and together hold every episode once."""
    parsed = parse_shard(shard)
    if parsed is None:
        return episodes
    i, n = parsed
    return episodes[(i - 1) * len(episodes) // n: i * len(episodes) // n]


def selector(limit: int | None, per_scene: int | None = None, shard: str | None = None
             ) -> Callable[[Callable[..., Iterator[Any]]], list[Episode]]:
    """The selection of :func:`select_episodes` as a ``select`` for :func:`load_dataset`: it streams the
    file, so only the episodes kept are held (a shard counts the selection in a first, keys-only read)."""
    parsed = parse_shard(shard)

    def select(stream: Callable[..., Iterator[Any]]) -> list[Episode]:
        def chosen(keys: bool = False) -> Iterator[Any]:
            it = stream(keys=keys)
            if per_scene is not None:
                seen: dict[str, int] = {}

                def first_of_scene(item: Any) -> bool:
                    scene = item[0] if keys else item.scene_id
                    seen[scene] = seen.get(scene, 0) + 1
                    return seen[scene] <= per_scene
                it = filter(first_of_scene, it)
            return itertools.islice(it, limit) if limit is not None else it

        if parsed is None:
            return list(chosen())
        i, n = parsed
        total = sum(1 for _ in chosen(keys=True))
        return list(itertools.islice(chosen(), (i - 1) * total // n, i * total // n))
    return select


def select_episodes(dataset: EpisodeDataset, limit: int | None, per_scene: int | None = None,
                    shard: str | None = None) -> list[Episode]:
    """The first ``limit`` episodes in file order (Habitat's convention for partial evaluation), after
    keeping only the first ``per_scene`` episodes of each scene when that is set; then shard ``shard``
    ("I/N") of those."""
    def stream(keys: bool = False) -> Iterator[Any]:
        return ((e.scene_id, e.episode_id) for e in dataset.episodes) if keys else iter(dataset.episodes)
    return selector(limit, per_scene, shard)(stream)


def recorded_paths(cfg: dict[str, Any], where: str | Path = "") -> tuple[str, str]:
    """(episode file, scene dir) of a run's config.json as this machine can open them. A generated benchmark's
    run records them relative to the benchmark's directory (``benchmark`` holds the episode file's sha256):
    they are read in ``benchmark_dir`` when it was recorded and holds them, else in the current directory."""
    episodes, scene_dir = str(cfg.get("episodes") or ""), str(cfg.get("scene_dir") or "")
    bench = cfg.get("benchmark")
    if not isinstance(bench, dict) or Path(episodes).is_absolute():
        return episodes, scene_dir
    bases = [Path(str(cfg["benchmark_dir"]))] if cfg.get("benchmark_dir") else []
    for base in [*bases, Path(".")]:
        if (base / episodes).is_file():
            return str(base / episodes), str(scene_dir if Path(scene_dir).is_absolute() else base / scene_dir)
    places = " or ".join([*(str(b) for b in bases), "the current directory"])
    raise RunError(f"{f'{where}: ' if where else ''}{episodes} (sha256 {str(bench.get('episodes_sha256'))[:12]}...) "
                   f"is named relative to its generated benchmark's directory, not found in {places}: "
                   f"run from the benchmark's directory")
