"""Run an agent over an episode dataset and record Habitat's metrics, one JSON line per episode.

    navbench run --split val_unseen --agent oracle --out runs/oracle_val_unseen

Writes ``OUT/episodes.jsonl`` (appended and flushed as each episode finishes, so a killed run loses at
most the episodes in flight), ``OUT/config.json`` (everything needed to rerun) and ``OUT/summary.json``.
``resume=True`` skips episodes already in ``episodes.jsonl``; it refuses a run directory whose
config differs in anything that changes results.

Parallelism: ``workers`` processes, each with its own env (and renderer) and agent, one episode per
task; agents with a batched policy (``pointnav``) step ``envs_per_worker`` episodes per worker in
lockstep with one forward pass for all of them. Every episode's outcome depends only on the episode
and the seed, never on which worker or slot ran it or in what order, so the same seed gives the same
records and summary to the last digit.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass, field
from multiprocessing import get_context
from pathlib import Path
from typing import Any

from navbench import __version__
from navbench.agents.base import Agent, BatchAgent, episode_log
from navbench.env.base import NavEnv
from navbench.env.config import EnvConfig
from navbench.env.objectnav import ObjectNavEnv
from navbench.env.pointnav import PointNavEnv
from navbench.eval.trace import Trace
from navbench.episodes.io import load_dataset
from navbench.episodes.types import Episode, EpisodeDataset, EpisodeError
from navbench.metrics import aggregate
from navbench.policy.workers import share_cores
from navbench.scene.asset import SceneError


class RunError(ValueError):
    """A run cannot start or continue (bad config, incompatible resume); the message says why."""


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
def select_episodes(dataset: EpisodeDataset, limit: int | None, per_scene: int | None = None) -> list[Episode]:
    """The first ``limit`` episodes in file order (Habitat's convention for partial evaluation), after
    keeping only the first ``per_scene`` episodes of each scene when that is set."""
    episodes = list(dataset.episodes)
    if per_scene is not None:
        seen: dict[str, int] = {}
        kept = []
        for e in episodes:
            seen[e.scene_id] = seen.get(e.scene_id, 0) + 1
            if seen[e.scene_id] <= per_scene:
                kept.append(e)
        episodes = kept
    return episodes[:limit] if limit is not None else episodes


def make_env(cfg: RunConfig, dataset: EpisodeDataset, sensors: tuple[str, ...]) -> NavEnv:
    env_cls = ObjectNavEnv if cfg.task == "objectnav" else PointNavEnv
    env = env_cls(dataset, scene_dir=cfg.scene_dir, config=cfg.env_config(sensors))
    env.reset(seed=cfg.seed)  # seeds the env's generator; episodes are then given explicitly
    return env


def _begin(env: NavEnv, episode: Episode, cfg: RunConfig) -> tuple[dict[str, Any], dict | None, float]:
    """Reset ``env`` to ``episode``: (record so far, first observation or None if skipped, start time)."""
    t0 = time.perf_counter()
    try:
        obs, info = env.reset(options={"episode": episode})
    except (EpisodeError, SceneError) as exc:  # name the dataset file too: the user's way to the culprit
        raise type(exc)(f"{cfg.episodes}: {exc}") from None
    record: dict[str, Any] = {
        "episode_id": episode.episode_id, "scene_id": episode.scene_id, "split": cfg.split, "task": cfg.task,
        "agent": cfg.agent, "object_category": episode.object_category,
    }
    if not math.isfinite(info["geodesic_distance"]):
        record.update(skipped=True, skip_reason="unreachable: no goal on the start's navigable island",
                      geodesic_distance=None, elapsed_s=round(time.perf_counter() - t0, 4))
        return record, None, t0
    return record, obs, t0


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


def run_episode(env: NavEnv, agent: Agent, episode: Episode, cfg: RunConfig) -> dict[str, Any]:
    record, obs, t0 = _begin(env, episode, cfg)
    if obs is None:
        return record
    agent.reset(episode)
    trace = Trace(env, agent)
    while True:
        action = agent.act(obs)
        obs, _, terminated, truncated, info = env.step(action)
        trace.step(action, env)
        if terminated or truncated:
            break
    return _end(record, info, t0, episode_log(agent), trace)


def run_episodes_batched(envs: list[NavEnv], agent: BatchAgent, episodes: list[Episode], cfg: RunConfig,
                         finish: Callable[[dict[str, Any]], None]) -> None:
    """Step ``len(envs)`` episodes in lockstep, one ``agent.act_batch`` per step for all of them; a slot
    whose episode ends takes the next one, in order. Each record goes to ``finish`` as its episode ends.

    Every slot's recurrent state is its own, so an episode's outcome does not depend on which slot or
    batch it ran in (tests/eval/test_runner.py checks the records equal the one-at-a-time run's).
    """
    queue = list(episodes)
    slots: list[tuple[dict[str, Any], float] | None] = [None] * len(envs)
    traces: list[Trace | None] = [None] * len(envs)
    obs: list[dict | None] = [None] * len(envs)
    failed: list[Exception] = []

    def start(i: int) -> None:
        slots[i] = None
        while queue:
            ep = queue.pop(0)
            try:
                record, first, t0 = _begin(envs[i], ep, cfg)
            except (EpisodeError, SceneError) as exc:
                # A bad episode ends the run, but the episodes in flight finish and are recorded first.
                failed.append(exc)
                queue.clear()
                return
            if first is None:
                finish(record)
                continue
            agent.reset_env(i, ep)
            slots[i], obs[i], traces[i] = (record, t0), first, Trace(envs[i])
            return

    for i in range(len(envs)):
        start(i)
    while any(s is not None for s in slots):
        filler = next(o for o, s in zip(obs, slots) if s is not None)
        actions = agent.act_batch([o if s is not None else filler for o, s in zip(obs, slots)])
        for i, env in enumerate(envs):
            if slots[i] is None:
                continue
            obs[i], _, terminated, truncated, info = env.step(int(actions[i]))
            traces[i].step(int(actions[i]), env)
            if terminated or truncated:
                record, t0 = slots[i]
                finish(_end(record, info, t0, {}, traces[i]))
                start(i)
    if failed:
        raise failed[0]


# ------------------------------------------------------------------------------------------ workers
_WORKER: dict[str, Any] = {}


def _worker_init(cfg: RunConfig, make_agent: AgentFactory, single_thread: bool) -> None:
    if single_thread:
        share_cores(1)
    dataset = load_dataset(cfg.episodes)
    agent = make_agent(cfg)
    sensors = tuple(getattr(agent, "sensors", ("rgb", "depth")))
    n_envs = agent.num_envs if isinstance(agent, BatchAgent) else 1
    _WORKER.update(cfg=cfg, dataset=dataset, agent=agent,
                   envs=[make_env(cfg, dataset, sensors) for _ in range(n_envs)],
                   by_key={(e.scene_id, e.episode_id): e for e in dataset.episodes})


def _run_keys(keys: list[tuple[str, str]], finish: Callable[[dict[str, Any]], None]) -> None:
    """Run episodes with this process's agent and envs, handing each record to ``finish`` as it ends."""
    w = _WORKER
    episodes = [w["by_key"][k] for k in keys]
    if isinstance(w["agent"], BatchAgent):
        run_episodes_batched(w["envs"], w["agent"], episodes, w["cfg"], finish)
    else:
        for ep in episodes:
            finish(run_episode(w["envs"][0], w["agent"], ep, w["cfg"]))


def _worker_run(keys: list[tuple[str, str]]) -> tuple[list[dict[str, Any]], Exception | None]:
    """A worker task (one episode for single-episode agents, a chunk for batched ones): the records and
    the error that stopped the task, if any, so the records finished before it are kept."""
    out: list[dict[str, Any]] = []
    try:
        _run_keys(keys, out.append)
    except (EpisodeError, SceneError) as exc:
        return out, exc
    return out, None


# -------------------------------------------------------------------------------------------- files
def read_records(path: Path) -> list[dict[str, Any]]:
    """Records of ``episodes.jsonl``; a truncated last line (a run killed mid-write) is dropped."""
    if not path.is_file():
        return []
    records, lines = [], path.read_text().splitlines()
    for i, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            records.append(json.loads(line))
        except json.JSONDecodeError:
            if i == len(lines) - 1:
                break
            raise RunError(f"{path}: line {i + 1} is corrupt") from None
    return records


def _append(fh, record: dict[str, Any]) -> None:
    fh.write(json.dumps(record, allow_nan=False) + "\n")
    fh.flush()
    os.fsync(fh.fileno())


def summarize(records: list[dict[str, Any]], cfg: RunConfig, complete: bool,
              extra: dict[str, Any] | None = None) -> dict[str, Any]:
    summary = aggregate(records, by="object_category" if cfg.task == "objectnav" else None)
    summary.update(task=cfg.task, split=cfg.split, agent=cfg.label or cfg.agent, success_distance=cfg.success_distance,
                   seed=cfg.seed, complete=complete)
    if extra:
        summary.update(extra)
    return summary


def _check_resume(out: Path, cfg_json: dict[str, Any]) -> None:
    old_path = out / "config.json"
    if not old_path.is_file():
        return
    old = json.loads(old_path.read_text())
    diff = sorted(k for k in set(old) | set(cfg_json)
                  if k not in _RESUME_FREE_KEYS and old.get(k) != cfg_json.get(k))
    if diff:
        raise RunError(f"{old_path}: cannot --resume, the run's config differs in {', '.join(diff)} "
                       f"(use another --out or drop --resume to start over)")


# ---------------------------------------------------------------------------------------------- run
def run(cfg: RunConfig, make_agent: AgentFactory, out: Path, resume: bool = False,
        progress: Callable[[dict[str, Any], int, int], None] | None = None) -> dict[str, Any]:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cfg_json = dict(dataclasses.asdict(cfg), navbench_version=__version__)
    jsonl = out / "episodes.jsonl"
    if resume:
        _check_resume(out, cfg_json)
        records = read_records(jsonl)
    else:
        records = []
    (out / "config.json").write_text(json.dumps(cfg_json, indent=1) + "\n")
    # Rewrite the kept records so a torn last line does not stay in the file.
    with open(jsonl, "w") as fh:
        for r in records:
            fh.write(json.dumps(r) + "\n")

    dataset = load_dataset(cfg.episodes)
    episodes = select_episodes(dataset, cfg.limit, cfg.per_scene)
    done = {(r["scene_id"], r["episode_id"]) for r in records}
    todo = [(e.scene_id, e.episode_id) for e in episodes if (e.scene_id, e.episode_id) not in done]
    todo.sort()  # group by scene so each worker loads a scene once
    wanted = {(e.scene_id, e.episode_id) for e in episodes}
    total = len(episodes)

    complete = False
    try:
        with open(jsonl, "a") as fh:
            recorded = [total - len(todo)]  # episodes of this selection already in the file

            def finish(rec):
                records.append(rec)
                _append(fh, rec)
                recorded[0] += 1
                if progress:
                    progress(rec, recorded[0], total)

            if cfg.workers <= 1 or len(todo) <= 1:
                _worker_init(cfg, make_agent, single_thread=False)
                _run_keys(todo, finish)
            else:
                # Batched agents take chunks of episodes (a worker keeps its slots busy; a killed run
                # loses at most the chunks in flight), others one episode per task.
                size = cfg.envs_per_worker * _CHUNK_PER_SLOT if cfg.envs_per_worker > 1 else 1
                tasks = [todo[i:i + size] for i in range(0, len(todo), size)]
                with ProcessPoolExecutor(max_workers=cfg.workers, mp_context=get_context("spawn"),
                                         initializer=_worker_init, initargs=(cfg, make_agent, True)) as pool:
                    pending = {pool.submit(_worker_run, t) for t in tasks}
                    try:
                        while pending:
                            finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                            for f in finished:
                                recs, error = f.result()
                                for rec in recs:
                                    finish(rec)
                                if error is not None:
                                    raise error
                    except BaseException:
                        for f in pending:
                            f.cancel()
                        raise
        complete = True
    finally:
        kept = [r for r in records if (r["scene_id"], r["episode_id"]) in wanted]
        summary = summarize(kept, cfg, complete)
        (out / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    return summary
