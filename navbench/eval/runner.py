"""Run an agent over an episode dataset and record Habitat's metrics, one JSON line per episode.

    navbench run --split val_unseen --agent oracle --out runs/oracle_val_unseen

Writes ``OUT/episodes.jsonl`` (appended and synced as each episode finishes, so a killed run loses at
most the episodes in flight), ``OUT/config.json`` (everything needed to rerun), ``OUT/provenance.json``
(versions, checksums, the protocol: :mod:`navbench.eval.provenance`) and ``OUT/summary.json`` (means with
95% intervals: :mod:`navbench.eval.stats`).
``OUT/.lock`` keeps a second run out while one runs. ``resume=True`` keeps the episodes already in
``episodes.jsonl`` (each once) and reruns failed ones; it refuses a run directory whose config differs
in anything that changes results, and a record of an episode the dataset does not have.

An episode whose agent or env raises, whose agent returns an action outside the action space, or
whose agent call takes longer than the step limit is recorded with ``failed: true``, a one-line
``failure_reason`` and a failure's metrics, and the run goes on; so is an episode whose worker process
died ``retries + 1`` times (see :mod:`navbench.eval.pool`). A bad episode or scene in the dataset
(EpisodeError, SceneError) is bad input and ends the run.

Parallelism: ``workers`` processes (or a Ray cluster's actors, :mod:`navbench.eval.ray_backend`), each
with its own env (and renderer) and agent, one episode per task; batched agents (``pointnav``, and
``memory``/``frontier`` through :mod:`navbench.agents.lockstep`) step ``envs_per_worker`` episodes per
worker in lockstep with one policy forward pass for all of them. Every episode's outcome depends only on
the episode and the seed, never on which worker or slot ran it or in what order, so the same seed gives
the same records and summary to the last digit (``elapsed_s`` and the localiser's ``log.query_ms`` are
the records' only wall-clock fields).
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import sys
import time
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from navbench import __version__
from navbench.agents.base import Agent, BatchAgent, episode_log, slot_agent
from navbench.env.base import NavEnv
from navbench.env.config import EnvConfig
from navbench.env.objectnav import ObjectNavEnv
from navbench.env.pointnav import PointNavEnv
from navbench.eval.provenance import config_protocol, protocol_id, write_provenance
from navbench.eval.stats import add_intervals
from navbench.eval.trace import Trace
from navbench.episodes.io import episode_keys, load_dataset
from navbench.episodes.types import Episode, EpisodeDataset, EpisodeError
from navbench.eval.rundir import RecordFile, RunError, RunLock, make_run_dir, read_records, write_atomic
from navbench.metrics import aggregate
from navbench.safeio import read_input
from navbench.policy.workers import share_cores
from navbench.scene.asset import SceneError

__all__ = ["RunConfig", "RunError", "read_records", "run", "select_episodes", "summarize"]


@dataclass
class RunConfig:
    task: str  # "pointnav" | "objectnav"
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
    workers: int = 1
    env: dict[str, Any] = field(default_factory=dict)  # EnvConfig overrides
    agent_options: dict[str, Any] = field(default_factory=dict)  # e.g. {"checkpoint": ...}
    label: str = ""  # the row name in tables (default: the agent's name)
    # Episodes each worker steps at once with one batched policy forward pass (agents with act_batch,
    # e.g. pointnav; others run one episode at a time). Outcomes do not depend on it.
    envs_per_worker: int = 1
    # "I/N": this run is shard I (1-based) of N, the I-th of N contiguous blocks of the selected episodes
    # in file order (see select_episodes); None: all of them.
    shard: str | None = None

    def env_config(self, sensors: tuple[str, ...]) -> EnvConfig:
        base = EnvConfig(success_distance=self.success_distance, **self.env)
        # Render only what the agent reads: the oracle needs no images, a PointNav policy only depth.
        return dataclasses.replace(base, rgb="rgb" in sensors, depth="depth" in sensors,
                                   semantic="semantic" in sensors)


# Keys that may differ between a run and its resumption without changing any episode's result.
_RESUME_FREE_KEYS = ("limit", "workers", "envs_per_worker", "navbench_version")
_CHUNK_PER_SLOT = 4  # a batched worker's task: this many episodes per slot

AgentFactory = Callable[[RunConfig], Agent]


# ----------------------------------------------------------------------------------------- episodes
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


_DATASET: dict[tuple, EpisodeDataset] = {}


def run_dataset(path: str | Path, limit: int | None = None, per_scene: int | None = None,
                shard: str | None = None) -> EpisodeDataset:
    """The run's episode file, parsed once per process (the driver and an in-process worker share it);
    read again when the file changed. With a selection (see :func:`select_episodes`) the file is
    streamed and the dataset holds only the episodes selected. Callers must not modify it."""
    st = Path(path).stat()
    key = (str(Path(path).resolve()), st.st_mtime_ns, st.st_size, limit, per_scene, shard)
    if key not in _DATASET:
        select = None if limit is None and per_scene is None and shard is None else \
            selector(limit, per_scene, shard)
        dataset = load_dataset(path, select)
        _DATASET.clear()
        _DATASET[key] = dataset
    return _DATASET[key]


def make_env(cfg: RunConfig, dataset: EpisodeDataset, sensors: tuple[str, ...]) -> NavEnv:
    env_cls = ObjectNavEnv if cfg.task == "objectnav" else PointNavEnv
    env = env_cls(dataset, scene_dir=cfg.scene_dir, config=cfg.env_config(sensors))
    env.reset(seed=cfg.seed)  # seeds the env's generator; episodes are then given explicitly
    return env


class EpisodeFailure(Exception):
    """An agent call misbehaved (wrong action, too slow): the episode is recorded as failed with this reason."""


def failure_reason(exc: BaseException) -> str:
    """One line for a failed episode's record: ``"ValueError: <the message's first line>"``."""
    if isinstance(exc, EpisodeFailure):
        return str(exc)
    first = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    return f"{type(exc).__name__}: {first}" if first else type(exc).__name__


class Clock:
    """Times agent calls against the step limit. ``busy`` (a shared value when in a worker) holds when the
    current call began, so the driver can kill a worker whose call never returns."""

    def __init__(self, limit: float | None = None, busy=None) -> None:
        self.limit, self.busy = limit, busy

    def call(self, fn: Callable[..., Any], *args: Any) -> Any:
        t0 = time.monotonic()
        if self.busy is not None:
            self.busy.value = t0
        try:
            result = fn(*args)
        finally:
            if self.busy is not None:
                self.busy.value = 0.0
        dt = time.monotonic() - t0
        if self.limit is not None and dt > self.limit:
            raise EpisodeFailure(step_timeout_reason(dt, self.limit))
        return result


def step_timeout_reason(seconds: float, limit: float) -> str:
    return f"step took {seconds:.1f} s (limit {limit:g} s)"


class Tracker:
    """Hears where each slot's episode is (a worker forwards it to the driver, which records a worker's
    death or a killed call as those episodes' failures); the default hears nothing."""

    def begin(self, slot: int, record: dict[str, Any], d0: float) -> None:
        """Before the env's reset; ``d0`` is the episode file's distance until :meth:`started` tells the env's."""

    def started(self, slot: int, d0: float) -> None:
        pass

    def step(self, slot: int, info: dict[str, Any]) -> None:
        pass


_NO_TRACKER = Tracker()


def _action(env: NavEnv, action: Any) -> int:
    n = env.action_space.n
    try:
        ok = int(action) == action and 0 <= int(action) < n
    except (TypeError, ValueError):
        ok = False
    if not ok:
        shown = action.item() if hasattr(action, "item") and getattr(action, "size", 1) == 1 else action
        raise EpisodeFailure(f"invalid action {shown!r} (expected 0-{n - 1})")
    return int(action)


def _base_record(episode: Episode, cfg: RunConfig) -> dict[str, Any]:
    return {"episode_id": episode.episode_id, "scene_id": episode.scene_id, "split": cfg.split, "task": cfg.task,
            "agent": cfg.agent, "object_category": episode.object_category}


def start_distance(episode: Episode) -> float:
    """The start's geodesic distance from the episode file, else the straight line to the nearest goal."""
    d = episode.info.get("geodesic_distance") if isinstance(episode.info, dict) else None
    if isinstance(d, (int, float)) and math.isfinite(d):
        return float(d)
    pts = episode.goal_positions()
    start = np.asarray(episode.start_position, np.float64)
    return float(np.min(np.hypot(pts[:, 0] - start[0], pts[:, 2] - start[2]))) if len(pts) else 0.0


def failed_record(record: dict[str, Any], reason: str, d0: float, distance: float | None, num_steps: int,
                  elapsed: float, info: dict[str, Any] | None = None) -> dict[str, Any]:
    """A failed episode's record: a failure's metrics (success, SPL and SoftSPL 0), the distance to the goal
    when it failed (the start's if unknown) and the steps taken so far."""
    info = info or {}
    record = dict(record)
    record.update(
        success=0.0, spl=0.0, soft_spl=0.0, distance_to_goal=float(d0 if distance is None else distance),
        geodesic_distance=float(d0), path_length=float(info.get("path_length", 0.0)), num_steps=int(num_steps),
        stop_called=bool(info.get("stop_called", False)), collisions=int(info.get("collisions", 0)),
        elapsed_s=round(elapsed, 4), failed=True, failure_reason=reason,
    )
    return record


def _begin(env: NavEnv, episode: Episode, cfg: RunConfig, tracker: Tracker = _NO_TRACKER,
           slot: int = 0) -> tuple[dict[str, Any], dict | None, float, float]:
    """Reset ``env`` to ``episode``: (record so far, first observation or None if skipped, start time, d0).
    A bad episode or scene (EpisodeError, SceneError) is bad input and ends the run; any other error
    raised by the env is raised as an :class:`_EnvFailure` carrying the record so far."""
    t0 = time.perf_counter()
    record = _base_record(episode, cfg)
    tracker.begin(slot, record, start_distance(episode))
    try:
        obs, info = env.reset(options={"episode": episode})
    except (EpisodeError, SceneError) as exc:  # name the dataset file too: the user's way to the culprit
        raise type(exc)(f"{cfg.episodes}: {exc}") from None
    except Exception as exc:
        raise _EnvFailure(failed_record(record, failure_reason(exc), start_distance(episode), None, 0,
                                        time.perf_counter() - t0)) from None
    if not math.isfinite(info["geodesic_distance"]):
        record.update(skipped=True, skip_reason="unreachable: no goal on the start's navigable island",
                      geodesic_distance=None, elapsed_s=round(time.perf_counter() - t0, 4))
        return record, None, t0, math.inf
    tracker.started(slot, float(info["geodesic_distance"]))
    return record, obs, t0, float(info["geodesic_distance"])


class _EnvFailure(Exception):
    def __init__(self, record: dict[str, Any]) -> None:
        super().__init__(record["failure_reason"])
        self.record = record


def _end(record: dict[str, Any], info: dict[str, Any], t0: float, log: dict[str, Any],
         trace: Trace | None = None) -> dict[str, Any]:
    record.update(
        success=info["success"], spl=info["spl"], soft_spl=info["soft_spl"],
        distance_to_goal=info["distance_to_goal"], geodesic_distance=info["geodesic_distance"],
        path_length=info["path_length"], num_steps=info["num_steps"], stop_called=info["stop_called"],
        collisions=info["collisions"], elapsed_s=round(time.perf_counter() - t0, 4),
    )
    if log:
        record["log"] = log
    if trace is not None:
        record["trace"] = trace.record()
    return record


def _fail(record: dict[str, Any], exc: BaseException, d0: float, info: dict[str, Any] | None,
          t0: float) -> dict[str, Any]:
    return failed_record(record, failure_reason(exc), d0, info["distance_to_goal"] if info else None,
                         info["num_steps"] if info else 0, time.perf_counter() - t0, info)


def run_episode(env: NavEnv, agent: Agent, episode: Episode, cfg: RunConfig, clock: Clock | None = None,
                tracker: Tracker = _NO_TRACKER) -> dict[str, Any]:
    """One episode's record; an exception raised by the agent or the env, an invalid action or a call
    slower than the step limit ends the episode as failed (see :func:`failed_record`), not the run."""
    clock = clock or Clock()
    try:
        record, obs, t0, d0 = _begin(env, episode, cfg, tracker)
    except _EnvFailure as f:
        return f.record
    if obs is None:
        return record
    info = None
    try:
        clock.call(agent.reset, episode)
        trace = Trace(env, agent)
        while True:
            action = _action(env, clock.call(agent.act, obs))
            obs, _, terminated, truncated, info = env.step(action)
            tracker.step(0, info)
            trace.step(action, env)
            if terminated or truncated:
                break
        log = episode_log(agent)  # a remote agent's log is a request that can fail like a step
    except (EpisodeError, SceneError):
        raise
    except Exception as exc:
        return _fail(record, exc, d0, info, t0)
    return _end(record, info, t0, log, trace)


def run_episodes_batched(envs: list[NavEnv], agent: BatchAgent, episodes: list[Episode], cfg: RunConfig,
                         finish: Callable[[dict[str, Any]], None], clock: Clock | None = None,
                         tracker: Tracker = _NO_TRACKER) -> None:
    """Step ``len(envs)`` episodes in lockstep, one ``agent.act_batch`` per step for all of them; a slot
    whose episode ends takes the next one, in order. Each record goes to ``finish`` as its episode ends.

    Every slot's recurrent state is its own, so an episode's outcome does not depend on which slot or
    batch it ran in (tests/eval/test_runner.py checks the records equal the one-at-a-time run's). A failed
    ``act_batch`` call (an exception, too slow) fails every episode in flight; a failed ``env.step`` or
    invalid action only its slot's.
    """
    clock = clock or Clock()
    queue = list(episodes)
    # per slot: (record so far, start time, d0, last step's info) of its episode, None when idle
    slots: list[tuple[dict[str, Any], float, float, dict | None] | None] = [None] * len(envs)
    traces: list[Trace | None] = [None] * len(envs)
    obs: list[dict | None] = [None] * len(envs)
    failed: list[Exception] = []

    def start(i: int) -> None:
        slots[i] = None
        while queue:
            ep = queue.pop(0)
            try:
                record, first, t0, d0 = _begin(envs[i], ep, cfg, tracker, i)
            except _EnvFailure as f:
                finish(f.record)
                continue
            except (EpisodeError, SceneError) as exc:
                # A bad episode ends the run, but the episodes in flight finish and are recorded first.
                failed.append(exc)
                queue.clear()
                return
            if first is None:
                finish(record)
                continue
            try:
                clock.call(agent.reset_env, i, ep)
            except Exception as exc:
                finish(_fail(record, exc, d0, None, t0))
                continue
            slots[i], obs[i], traces[i] = (record, t0, d0, None), first, Trace(envs[i], slot_agent(agent, i))
            return

    def fail(i: int, exc: Exception) -> None:
        record, t0, d0, info = slots[i]
        finish(_fail(record, exc, d0, info, t0))
        start(i)

    for i in range(len(envs)):
        start(i)
    while any(s is not None for s in slots):
        try:
            actions = clock.call(agent.act_batch, [o if s is not None else None for o, s in zip(obs, slots)])
        except Exception as exc:
            for i in [i for i, s in enumerate(slots) if s is not None]:
                fail(i, exc)
            continue
        for i, env in enumerate(envs):
            if slots[i] is None:
                continue
            try:
                if isinstance(actions[i], Exception):  # this slot's agent raised; the others go on
                    raise actions[i]
                action = _action(env, actions[i])
                obs[i], _, terminated, truncated, info = env.step(action)
                log = episode_log(slot_agent(agent, i)) if terminated or truncated else {}
            except (EpisodeError, SceneError):
                raise
            except Exception as exc:
                fail(i, exc)
                continue
            tracker.step(i, info)
            traces[i].step(action, env)
            record, t0, d0, _ = slots[i]
            slots[i] = (record, t0, d0, info)
            if terminated or truncated:
                finish(_end(record, info, t0, log, traces[i]))
                start(i)
    if failed:
        raise failed[0]


# ------------------------------------------------------------------------------------------ workers
_WORKER: dict[str, Any] = {}


def task_size(n: int, workers: int, envs_per_worker: int) -> int:
    """Episodes per pool task: one for one-episode workers; for batched ones, chunks of at most
    ``_CHUNK_PER_SLOT`` episodes per slot (a worker's slots stay busy between refills), as many per worker
    (the workers finish together rather than one running a last chunk alone)."""
    if envs_per_worker <= 1:
        return 1
    per_worker = max(1, math.ceil(n / (workers * envs_per_worker * _CHUNK_PER_SLOT)))  # chunks per worker
    return max(1, math.ceil(n / (workers * per_worker)))


def _worker_init(cfg: RunConfig, make_agent: AgentFactory, single_thread: bool) -> None:
    if single_thread:
        share_cores(1)
    dataset = run_dataset(cfg.episodes, cfg.limit, cfg.per_scene, cfg.shard)
    agent = make_agent(cfg)
    sensors = tuple(getattr(agent, "sensors", ("rgb", "depth")))
    n_envs = agent.num_envs if isinstance(agent, BatchAgent) else 1
    _WORKER.update(cfg=cfg, dataset=dataset, agent=agent,
                   envs=[make_env(cfg, dataset, sensors) for _ in range(n_envs)],
                   by_key={(e.scene_id, e.episode_id): e for e in dataset.episodes})


def _worker_close() -> None:
    """This process's agent's ``close()``, if it has one, once its episodes are done (a remote agent ends
    its session on the server)."""
    close = getattr(_WORKER.get("agent"), "close", None)
    if callable(close):
        try:
            close()
        except Exception as exc:  # the records are written; a failing close() is reported, not raised
            warnings.warn(f"agent close() raised {failure_reason(exc)}", RuntimeWarning, stacklevel=2)


def _run_keys(keys: list[tuple[str, str]], finish: Callable[[dict[str, Any]], None], clock: Clock | None = None,
              tracker: Tracker = _NO_TRACKER) -> None:
    """Run episodes with this process's agent and envs, handing each record to ``finish`` as it ends."""
    w = _WORKER
    episodes = [w["by_key"][k] for k in keys]
    if isinstance(w["agent"], BatchAgent):
        run_episodes_batched(w["envs"], w["agent"], episodes, w["cfg"], finish, clock, tracker)
    else:
        for ep in episodes:
            finish(run_episode(w["envs"][0], w["agent"], ep, w["cfg"], clock, tracker))


# -------------------------------------------------------------------------------------------- files
def comparable(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Copies of ``records`` without their wall-clock fields (``elapsed_s``, ``log.query_ms``), sorted by
    (scene, episode): what two runs of the same config must agree on however they were run."""
    out = []
    for r in records:
        r = {k: v for k, v in r.items() if k != "elapsed_s"}
        if isinstance(r.get("log"), dict):
            r["log"] = {k: v for k, v in r["log"].items() if k != "query_ms"}
        out.append(r)
    return sorted(out, key=lambda r: (r["scene_id"], r["episode_id"]))


def summarize(records: list[dict[str, Any]], cfg: RunConfig, complete: bool,
              extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """The run's summary: metric means over scored episodes (failed ones count as failures) and the
    failed episodes with their reasons."""
    by = "object_category" if cfg.task == "objectnav" else None
    summary = aggregate(records, by=by)
    add_intervals(summary, records, by)  # ci95 of each mean: the two-stage bootstrap of navbench.eval.stats
    failed = sorted((r for r in records if r.get("failed")), key=lambda r: (str(r["scene_id"]), str(r["episode_id"])))
    summary.update(task=cfg.task, split=cfg.split, agent=cfg.label or cfg.agent, success_distance=cfg.success_distance,
                   seed=cfg.seed, protocol_id=protocol_id(config_protocol(cfg)), complete=complete,
                   num_failed=len(failed),
                   failed_episodes=[{"scene_id": r["scene_id"], "episode_id": r["episode_id"],
                                     "failure_reason": r.get("failure_reason", "")} for r in failed])
    if cfg.shard:
        summary["shard"] = cfg.shard
    if extra:
        summary.update(extra)
    return summary


def config_json(cfg: RunConfig) -> dict[str, Any]:
    """What config.json records: the RunConfig (its shard only when set) and navbench's version."""
    out = dict(dataclasses.asdict(cfg), navbench_version=__version__)
    if out.get("shard") is None:
        out.pop("shard", None)
    return out


def config_diff(old: dict[str, Any], new: dict[str, Any], free: tuple[str, ...]) -> list[str]:
    return sorted(k for k in set(old) | set(new) if k not in free and old.get(k) != new.get(k))


def _check_resume(out: Path, cfg_json: dict[str, Any], has_records: bool) -> None:
    old_path = out / "config.json"
    if not old_path.is_file():
        if has_records:
            raise RunError(f"{old_path}: missing, so the records in {out / 'episodes.jsonl'} cannot be checked "
                           f"against this run's config (restore it, or use another --out)")
        return
    try:
        old = json.loads(read_input(old_path, gunzip=False))
        if not isinstance(old, dict):
            raise ValueError
    except ValueError:
        raise RunError(f"{old_path}: not a valid config (corrupt JSON); cannot --resume") from None
    diff = config_diff(old, cfg_json, _RESUME_FREE_KEYS)
    if diff:
        raise RunError(f"{old_path}: cannot --resume, the run's config differs in {', '.join(diff)} "
                       f"(use another --out, or --overwrite to start over)")


def _repair(records: list[dict[str, Any]], jsonl: Path, dataset: EpisodeDataset, dataset_file: str,
            notes: list[str]) -> list[dict[str, Any]]:
    """The records a resumed run keeps: each episode once (the first record), none of a failed episode
    (rerun), and an error naming a record of an episode the dataset does not have."""
    known: set[tuple[str, str]] | Any = {(e.scene_id, e.episode_id) for e in dataset.episodes}
    everything: set[tuple[str, str]] | None = None  # every episode of the file, read when needed
    kept: dict[tuple[str, str], dict[str, Any]] = {}
    dups = reruns = 0
    for i, r in enumerate(records):
        try:
            key = (r["scene_id"], r["episode_id"])
        except (KeyError, TypeError):
            raise RunError(f"{jsonl}: record {i + 1} has no scene_id/episode_id") from None
        if key not in known and everything is None:  # records beyond this run's selection (e.g. --limit)
            everything = episode_keys(dataset_file)
        if key not in known and key not in (everything or ()):
            raise RunError(f"{jsonl}: record {i + 1} is of episode {key[1]!r} ({key[0]}), which is not in "
                           f"{dataset_file}: records of another run? (use another --out)")
        if key in kept:
            dups += 1
            continue
        kept[key] = r
    if dups:
        notes.append(f"{jsonl}: {dups} duplicated record(s) kept once")
    out = []
    for r in kept.values():
        if r.get("failed"):
            reruns += 1
        else:
            out.append(r)
    if reruns:
        notes.append(f"{jsonl}: rerunning {reruns} failed episode(s)")
    return out


# ---------------------------------------------------------------------------------------------- run
def _note_stderr(msg: str) -> None:
    print(f"navbench: {msg}", file=sys.stderr, flush=True)


def run(cfg: RunConfig, make_agent: AgentFactory, out: Path, resume: bool = False,
        progress: Callable[[dict[str, Any], int, int], None] | None = None, *, overwrite: bool = False,
        retries: int = 2, step_timeout: float | None = None, fail_fast: bool = False,
        note: Callable[[str], None] = _note_stderr, backend: str = "local", address: str | None = None
        ) -> dict[str, Any]:
    """Run ``cfg``'s episodes into ``out`` and return the summary.

    ``resume`` keeps the records already there (each episode once; failed episodes are rerun); without it
    (or ``overwrite``) a directory that already holds a run is refused. An episode whose agent or env
    fails is recorded as failed (``failed``, ``failure_reason``) and the run goes on, unless
    ``fail_fast``: then the first failure raises RunError (finished records kept). A worker process that
    dies is replaced and its episodes retried ``retries`` times; an agent call slower than
    ``step_timeout`` seconds fails its episode (with workers, a call that never returns is killed).
    ``backend="ray"`` runs the episodes on the Ray cluster at ``address`` (see
    :mod:`navbench.eval.ray_backend`); the backend is not part of the config, so a run may resume on either.
    """
    if step_timeout is not None and step_timeout <= 0:
        raise RunError(f"--step-timeout must be positive, got {step_timeout:g}")
    if retries < 0:
        raise RunError(f"--retries must be 0 or more, got {retries}")
    if backend not in ("local", "ray"):
        raise RunError(f"backend {backend!r}: choose local or ray")
    if address is not None and backend != "ray":
        raise RunError("--address applies to --backend ray only")
    if backend == "ray":  # before the run directory is touched: a missing extra is a one-line error
        from navbench.eval.ray_backend import require_ray
        require_ray()
    out = Path(out)
    make_run_dir(out)
    lock = RunLock(out, note)
    try:
        return _run_locked(cfg, make_agent, out, resume, progress, overwrite, retries, step_timeout, fail_fast, note,
                           backend, address)
    finally:
        lock.release()


def _run_locked(cfg, make_agent, out, resume, progress, overwrite, retries, step_timeout, fail_fast, note,
                backend="local", address=None):
    cfg_json = config_json(cfg)
    jsonl = out / "episodes.jsonl"
    notes: list[str] = []
    old = read_records(jsonl, notes) if (resume or not overwrite) else []
    if not resume and not overwrite and (old or (out / "config.json").is_file()):
        raise RunError(f"{out} already holds a run ({len(old)} records): --resume to continue it, --overwrite to "
                       f"replace it, or another --out")
    dataset = run_dataset(cfg.episodes, cfg.limit, cfg.per_scene, cfg.shard)
    if resume:
        _check_resume(out, cfg_json, bool(old))
        records = _repair(old, jsonl, dataset, cfg.episodes, notes)
    else:
        records = []
    for n in notes:
        note(n)
    write_atomic(out / "config.json", json.dumps(cfg_json, indent=1) + "\n")
    write_provenance(out, cfg, select_episodes(dataset, cfg.limit, cfg.per_scene, cfg.shard), resume)
    # Rewrite the kept records whole (atomically) so a torn line or a duplicate does not stay in the file.
    write_atomic(jsonl, "".join(json.dumps(r) + "\n" for r in records))

    episodes = dataset.episodes  # the selection
    done = {(r["scene_id"], r["episode_id"]) for r in records}
    todo = [(e.scene_id, e.episode_id) for e in episodes if (e.scene_id, e.episode_id) not in done]
    todo.sort()  # group by scene so each worker loads a scene once
    wanted = {(e.scene_id, e.episode_id) for e in episodes}
    total = len(episodes)

    complete = False
    fh = RecordFile(jsonl)
    try:
        recorded = [total - len(todo)]  # episodes of this selection already in the file

        def finish(rec):
            if rec.get("failed") and fail_fast:
                raise RunError(f"{cfg.episodes}: episode {rec['episode_id']} ({rec['scene_id']}) failed: "
                               f"{rec['failure_reason']}")
            fh.append(rec)
            records.append(rec)
            recorded[0] += 1
            if progress:
                progress(rec, recorded[0], total)

        size = task_size(len(todo), cfg.workers, cfg.envs_per_worker)
        # No more env slots than a worker can fill (a one-episode run builds one env and one agent).
        wcfg = dataclasses.replace(cfg, envs_per_worker=max(1, min(cfg.envs_per_worker, size)))
        if backend == "ray":
            from navbench.eval.ray_backend import run_ray
            run_ray(wcfg, make_agent, todo, finish, address=address, retries=retries, step_timeout=step_timeout)
        # In this process when one worker (or one episode) will do, unless a hung agent call must be killable.
        elif (cfg.workers <= 1 or len(todo) <= 1) and step_timeout is None or not todo:
            _worker_init(wcfg, make_agent, single_thread=False)
            try:
                _run_keys(todo, finish, Clock(step_timeout))
            finally:
                _worker_close()
        else:
            from navbench.eval.pool import run_pool
            run_pool(wcfg, make_agent, [todo[i:i + size] for i in range(0, len(todo), size)], finish,
                     workers=cfg.workers, n_slots=wcfg.envs_per_worker, retries=retries, step_timeout=step_timeout)
        complete = True
    finally:
        fh.close()
        kept = [r for r in records if (r["scene_id"], r["episode_id"]) in wanted]
        summary = summarize(kept, cfg, complete)
        try:
            write_atomic(out / "summary.json", json.dumps(summary, indent=1) + "\n")
        except RunError:
            if complete:
                raise
    return summary
