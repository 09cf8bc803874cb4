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
died ``retries + 1`` times (see :mod:`navbench.eval.worker`, :mod:`navbench.eval.pool`). A bad episode or scene
in the dataset
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
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from navbench._version import __version__
from navbench.episodes.io import episode_keys
from navbench.episodes.types import EpisodeDataset
from navbench.eval.config import Execution, RunConfig, parse_shard, select_episodes, shard_of
from navbench.eval.provenance import (
    benchmark_root,
    config_protocol,
    data_path,
    protocol_id,
    sha256,
    write_provenance,
)
from navbench.eval.records import EpisodeRecord, RunSummary, json_ready, summary_text
from navbench.eval.rundir import RecordFile, RunError, RunLock, make_run_dir, read_records, write_atomic
from navbench.eval.stats import add_intervals
from navbench.eval.worker import AgentFactory, Clock, EpisodeWorker, LiveTracker, Tracker, run_dataset, task_size
from navbench.metrics import aggregate
from navbench.safeio import read_input
from navbench.tasks import get_task

__all__ = ["Execution", "RunConfig", "RunError", "comparable", "parse_shard", "read_records", "run", "run_dataset",
           "select_episodes", "shard_of", "summarize"]

# Keys that may differ between a run and its resumption without changing any episode's result (the device:
# beyond float rounding, docs/comparing.md).
_RESUME_FREE_KEYS = ("limit", "workers", "envs_per_worker", "navbench_version", "device", "benchmark_dir")
# RunConfig fields config.json leaves out at these values: a default run's config.json has none of them.
_DEFAULT_OMITTED = {"shard": None, "env_config_name": None, "device": "cpu", "precision": "fp32",
                    "habitat_config": None, "gt": None}


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
              extra: dict[str, Any] | None = None) -> RunSummary:
    """The run's summary: metric means over scored episodes (failed ones count as failures) and the
    failed episodes with their reasons."""
    task = get_task(cfg.task)
    by, keys = task.group_by, task.summary_keys
    summary = aggregate(records, by=by, keys=keys)
    add_intervals(summary, records, by, keys)  # ci95 of each mean: the two-stage bootstrap of navbench.eval.stats
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
    return json_ready(summary)  # null, not NaN, for a figure of no episodes (a run stopped before its first)


def config_json(cfg: RunConfig) -> dict[str, Any]:
    """What config.json records: the RunConfig (its shard, env configuration's name, device and precision only
    when set or not the default) and navbench's version. A run of a generated benchmark records its episode
    file and scene dir relative to the benchmark's directory, with ``benchmark`` (the episode file's sha256;
    provenance.json has the scenes') and ``benchmark_dir`` (that directory as given, when given relative;
    never an absolute path): see :func:`navbench.eval.config.recorded_paths`."""
    out = dict(dataclasses.asdict(cfg), navbench_version=__version__)
    for key, default in _DEFAULT_OMITTED.items():
        if out.get(key) == default:
            out.pop(key, None)
    episodes = data_path(cfg.episodes)
    if episodes["root"] == "benchmark":
        bench, given, depth = benchmark_root(cfg.episodes), Path(cfg.episodes), len(Path(episodes["path"]).parts)
        out["episodes"] = episodes["path"]
        if benchmark_root(cfg.scene_dir) == bench:
            out["scene_dir"] = data_path(cfg.scene_dir)["path"]
        out["benchmark"] = {"episodes_sha256": sha256(cfg.episodes)}
        root = given.parents[depth - 1] if len(given.parents) >= depth else None  # the directory as given
        if root is not None and not root.is_absolute() and root.resolve() == bench:
            out["benchmark_dir"] = root.as_posix()
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
        progress: Callable[[EpisodeRecord, int, int], None] | None = None, *, overwrite: bool = False,
        execution: Execution | None = None, note: Callable[[str], None] = _note_stderr) -> RunSummary:
    """Run ``cfg``'s episodes into ``out`` and return the summary.

    Args:
        cfg: what the records depend on.
        make_agent: the agent's factory, called once per worker with ``cfg``.
        out: the run directory.
        resume: keep the records already there (each episode once; failed episodes are rerun); without
            it (or ``overwrite``) a directory that already holds a run is refused.
        progress: called as ``progress(record, done, total)`` after each episode; one with a ``live(in_flight,
            done, total)`` method also hears, about once a second, of the episodes in flight (local backend):
            (scene_id, episode_id, steps, subtasks closed, subtasks), the last two -1 without subtasks.
        overwrite: replace the run in ``out``.
        execution: how the episodes are run (default: one worker in this process, 2 retries); see
            :class:`~navbench.eval.config.Execution`. It is not part of config.json, so a run may resume
            with other settings, on either backend.
        note: where notes on the run directory go (default: stderr).

    Returns:
        The summary, as ``out/summary.json`` holds it. An episode whose agent or env fails is recorded
        as failed and the run goes on, unless ``execution.fail_fast``: then RunError (records kept).
    """
    execution = execution or Execution()
    if execution.backend == "ray":  # before the run directory is touched: a missing extra is one line
        from navbench.eval.ray_backend import require_ray
        require_ray()
    out = Path(out)
    make_run_dir(out)
    lock = RunLock(out, note)
    try:
        return _run_locked(cfg, make_agent, out, resume, progress, overwrite, execution, note)
    finally:
        lock.release()


def _run_locked(cfg, make_agent, out, resume, progress, overwrite, execution: Execution, note):
    cfg_json = config_json(cfg)
    jsonl = out / "episodes.jsonl"
    notes: list[str] = []
    old = read_records(jsonl, notes) if (resume or not overwrite) else []
    if not resume and not overwrite and (old or (out / "config.json").is_file()):
        raise RunError(f"{out} already holds a run ({len(old)} records): --resume to continue it, --overwrite to "
                       f"replace it, or another --out")
    # streamed: the selection only
    dataset = run_dataset(cfg.episodes, cfg.limit, cfg.per_scene, cfg.shard, cfg.task, cfg.gt)
    if resume:
        _check_resume(out, cfg_json, bool(old))
        records = _repair(old, jsonl, dataset, cfg.episodes, notes)
    else:
        records = []
    for n in notes:
        note(n)
    write_atomic(out / "config.json", json.dumps(cfg_json, indent=1) + "\n")
    write_provenance(out, cfg, dataset.episodes, resume)
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

        # A progress with a live() hears of the episodes in flight: (scene, episode, steps, subtasks closed, of)
        show = getattr(progress, "live", None)
        live = (lambda in_flight: show(in_flight, recorded[0], total)) if callable(show) else None
        tracker = LiveTracker(live) if live is not None else None

        def finish(rec):
            if rec.get("failed") and execution.fail_fast:
                raise RunError(f"{cfg.episodes}: episode {rec['episode_id']} ({rec['scene_id']}) failed: "
                               f"{rec['failure_reason']}")
            fh.append(rec)
            records.append(rec)
            recorded[0] += 1
            if tracker is not None:
                tracker.ended((rec["scene_id"], rec["episode_id"]))
            if progress:
                progress(rec, recorded[0], total)

        workers, step_timeout = execution.workers, execution.step_timeout
        size = task_size(len(todo), workers, cfg.envs_per_worker)
        # No more env slots than a worker can fill (a one-episode run builds one env and one agent).
        wcfg = dataclasses.replace(cfg, envs_per_worker=max(1, min(cfg.envs_per_worker, size)))
        pool = workers > 1 and len(todo) > 1 or step_timeout is not None
        if execution.backend != "ray" and pool and wcfg.envs_per_worker > 1:
            size = 1  # a pool worker refills each free slot with the next episode (navbench.eval.pool)
        if execution.backend == "ray":
            from navbench.eval.ray_backend import run_ray
            run_ray(wcfg, make_agent, todo, finish, address=execution.address, retries=execution.retries,
                    step_timeout=step_timeout, workers=workers)
        # In this process when one worker (or one episode) will do, unless a hung agent call must be killable.
        elif not pool or not todo:
            if todo:
                with EpisodeWorker(wcfg, make_agent) as worker:
                    worker.run(todo, finish, Clock(step_timeout), tracker or Tracker())
        else:
            from navbench.eval.pool import run_pool
            run_pool(wcfg, make_agent, [todo[i:i + size] for i in range(0, len(todo), size)], finish,
                     workers=workers, n_slots=wcfg.envs_per_worker, retries=execution.retries,
                     step_timeout=step_timeout, live=live)
        complete = True
    finally:
        fh.close()
        kept = [r for r in records if (r["scene_id"], r["episode_id"]) in wanted]
        summary = summarize(kept, cfg, complete)
        try:
            write_atomic(out / "summary.json", summary_text(summary))
        except RunError:
            if complete:
                raise
    return summary
