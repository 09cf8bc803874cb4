"""What runs episodes in one process: :class:`EpisodeWorker` (an agent and its envs) and the episode loops
it drives, one episode at a time or several in lockstep through a batched agent.

The local process pool (:mod:`navbench.eval.pool`), the Ray actors (:mod:`navbench.eval.ray_backend`),
a run in the driver's own process (:func:`navbench.eval.runner.run`) and the soak benchmark all run
their episodes through an :class:`EpisodeWorker`; both backends charge a dead worker's episodes to one
:class:`RetryLedger`.

An episode whose agent or env raises, whose agent returns an action outside the action space, or whose
agent call takes longer than the step limit is recorded with ``failed: true``, a one-line
``failure_reason`` and a failure's metrics. A bad episode or scene in the dataset (EpisodeError,
SceneError) is bad input and is raised.
"""

from __future__ import annotations

import enum
import inspect
import math
import time
import warnings
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from navbench.agents.base import Agent, BatchAgent, episode_log, is_batch_agent, slot_agent
from navbench.agents.registry import is_privileged
from navbench.env.base import NavEnv
from navbench.env.make import task_env
from navbench.env.sensors import AGENT_POSE
from navbench.episodes.io import load_dataset
from navbench.episodes.types import Episode, EpisodeDataset, EpisodeError
from navbench.eval.config import RunConfig, selector
from navbench.eval.rundir import RunError
from navbench.eval.trace import Trace
from navbench.policy.workers import share_cores
from navbench.scene.asset import SceneError
from navbench.tasks import TASKS, get_task

Key = tuple[str, str]  # (scene_id, episode_id)
AgentFactory = Callable[[RunConfig], Any]
_CHUNK_PER_SLOT = 4  # a batched worker's task: this many episodes per slot


_DATASET: dict[tuple, EpisodeDataset] = {}


def run_dataset(path: str | Path, limit: int | None = None, per_scene: int | None = None,
                shard: str | None = None, task: str | None = None, gt: str | None = None) -> EpisodeDataset:
    """The run's episode file, parsed once per process (the driver and an in-process worker share it) by
    ``task``'s reader (Habitat's PointNav/ObjectNav JSON without one); read again when the file changed.
    With a selection (see :func:`~navbench.eval.config.select_episodes`) the file is streamed and the
    dataset holds only the episodes selected. ``gt``: a VLN-CE task's gt paths file, read instead of the one
    beside the episodes. Callers must not modify it."""
    st = Path(path).stat()
    key = (str(Path(path).resolve()), st.st_mtime_ns, st.st_size, limit, per_scene, shard, task, gt)
    if key not in _DATASET:
        select = None if limit is None and per_scene is None and shard is None else \
            selector(limit, per_scene, shard)
        if gt is not None:  # a VLN-CE task's gt paths, given instead of found beside the episodes
            if task is None or "gt" not in inspect.signature(get_task(task).read_episodes).parameters:
                raise ValueError(f"--gt applies to the VLN-CE tasks (r2r_ce, rxr_ce), not {task}")
            dataset = get_task(task).read_episodes(path, select, gt=gt)
        else:
            dataset = get_task(task).read_episodes(path, select) if task is not None else load_dataset(path, select)
        _DATASET.clear()
        _DATASET[key] = dataset
    return _DATASET[key]


def make_env(cfg: RunConfig, dataset: EpisodeDataset, sensors: tuple[str, ...]) -> NavEnv:
    env = task_env(cfg.task, dataset, scene_dir=cfg.scene_dir, config=cfg.env_config(sensors))
    if AGENT_POSE in sensors and is_privileged(cfg.agent):  # a built-in privileged agent reads the simulator's
        env.give_agent_pose()                                # pose, whatever the configuration senses
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


def step_counts(info: dict[str, Any]) -> tuple[int, int, int]:
    """How far an episode in flight is, from the env's last ``info``: (steps, subtasks closed, subtasks), the
    last two -1 for a task without subtasks (GOAT-Bench's ``subtasks_closed`` and ``subtask_success``)."""
    subtasks = info.get("subtask_success")
    if subtasks is None:
        return int(info["num_steps"]), -1, -1
    return int(info["num_steps"]), int(info.get("subtasks_closed", 0)), len(subtasks)


class LiveTracker(Tracker):
    """Hands the episodes in flight, (scene_id, episode_id, steps, subtasks closed, subtasks) each, to ``live`` at
    most once every ``every`` seconds, from the steps of a worker in the driver's own process. ``ended(key)``
    drops an episode whose record came (an idle slot keeps nothing)."""

    every = 1.0

    def __init__(self, live: Callable[[list[tuple[str, str, int, int, int]]], None]) -> None:
        self.live = live
        self.slots: dict[int, list] = {}  # slot -> [scene_id, episode_id, steps, closed, subtasks]
        self.last = time.monotonic()

    def begin(self, slot: int, record: dict[str, Any], d0: float) -> None:
        self.slots[slot] = [record["scene_id"], record["episode_id"], 0, -1, -1]

    def step(self, slot: int, info: dict[str, Any]) -> None:
        self.slots[slot][2:] = step_counts(info)
        now = time.monotonic()
        if now - self.last >= self.every:
            self.last = now
            self.live([tuple(v) for _, v in sorted(self.slots.items())])

    def ended(self, key: Key) -> None:
        for slot, v in list(self.slots.items()):
            if (v[0], v[1]) == key:
                del self.slots[slot]


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


def base_record(episode: Episode, cfg: RunConfig) -> dict[str, Any]:
    return {"episode_id": episode.episode_id, "scene_id": episode.scene_id, "split": cfg.split, "task": cfg.task,
            "agent": cfg.agent, "object_category": episode.object_category}


def start_distance(episode: Episode) -> float:
    """The start's geodesic distance from the episode file, else the straight line to the nearest goal."""
    d = episode.info.get("geodesic_distance") if isinstance(episode.info, dict) else None
    if isinstance(d, (int, float)) and math.isfinite(d):
        return float(d)
    if not episode.goals and episode.object_category is None:
        return math.nan  # a VLN-CE test split's episode: no goal, not scored
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
    record.update(_task_measures(record, info, failed=True))
    return _nan_to_null(record)


def _extra_measures(record: dict[str, Any]) -> tuple[str, ...]:
    """The measures of the record's task beyond Habitat's four (none for a task no longer registered)."""
    task = TASKS.get(str(record.get("task")))
    return task.extra_measures if task is not None else ()


def _begin(env: NavEnv, episode: Episode, cfg: RunConfig, tracker: Tracker = _NO_TRACKER,
           slot: int = 0) -> tuple[dict[str, Any], dict | None, float, float]:
    """Reset ``env`` to ``episode``: (record so far, first observation or None if skipped, start time, d0).
    A bad episode or scene (EpisodeError, SceneError) is bad input and ends the run; any other error
    raised by the env is raised as an :class:`_EnvFailure` carrying the record so far."""
    t0 = time.perf_counter()
    record = base_record(episode, cfg)
    tracker.begin(slot, record, start_distance(episode))
    try:
        obs, info = env.reset(options={"episode": episode})
    except (EpisodeError, SceneError) as exc:  # name the dataset file too: the user's way to the culprit
        raise type(exc)(f"{cfg.episodes}: {exc}") from None
    except Exception as exc:
        raise _EnvFailure(failed_record(record, failure_reason(exc), start_distance(episode), None, 0,
                                        time.perf_counter() - t0)) from None
    if info["geodesic_distance"] == math.inf:  # NaN: an episode without a goal runs, unscored
        record.update(skipped=True, skip_reason="unreachable: no goal on the start's navigable island",
                      geodesic_distance=None, elapsed_s=round(time.perf_counter() - t0, 4))
        return record, None, t0, math.inf
    tracker.started(slot, float(info["geodesic_distance"]))
    return record, obs, t0, float(info["geodesic_distance"])


class _EnvFailure(Exception):
    def __init__(self, record: dict[str, Any]) -> None:
        super().__init__(record["failure_reason"])
        self.record = record


_SCORES = ("success", "spl", "soft_spl", "distance_to_goal", "geodesic_distance")


def _task_measures(record: dict[str, Any], info: dict[str, Any] | None, failed: bool = False) -> dict[str, Any]:
    """The task's measures beyond Habitat's four (VLN-CE's oracle_success, ndtw...), from the env's ``info``,
    and the path VLN-CE's leaderboard files are written from (``vlnce_path``). A measure the env could not take
    (NaN: an episode without a goal, a split without gt paths) is recorded as null; a failed episode's measures
    that only its end gives (nDTW) count as a failure's, 0."""
    info = info or {}
    out: dict[str, Any] = {}
    for m in _extra_measures(record):
        if m == "path_length":  # a standard field, set from the same info
            continue
        v = float(info.get(m, math.nan))
        out[m] = v if v == v else (0.0 if failed else None)
    if "vlnce_path" in info:
        out["vlnce_path"] = info["vlnce_path"]
    return out


def _nan_to_null(record: dict[str, Any]) -> dict[str, Any]:
    """Scores an env reports as NaN (nothing to measure against) as null: records are strict JSON."""
    for k in _SCORES:
        v = record.get(k)
        if isinstance(v, float) and v != v:
            record[k] = None
    return record


def _end(record: dict[str, Any], info: dict[str, Any], t0: float, log: dict[str, Any],
         trace: Trace | None = None) -> dict[str, Any]:
    record.update(
        success=info["success"], spl=info["spl"], soft_spl=info["soft_spl"],
        distance_to_goal=info["distance_to_goal"], geodesic_distance=info["geodesic_distance"],
        path_length=info["path_length"], num_steps=info["num_steps"], stop_called=info["stop_called"],
        collisions=info["collisions"], elapsed_s=round(time.perf_counter() - t0, 4),
    )
    record.update(_task_measures(record, info))
    task = TASKS.get(str(record.get("task")))
    record.update({f: _plain(info[f]) for f in (task.record_fields if task is not None else ()) if f in info})
    _nan_to_null(record)
    if log:
        record["log"] = log
    if trace is not None:
        record["trace"] = trace.record()
    return record


def _plain(value: Any) -> Any:
    """A measure as a record holds it: numbers as floats, lists as lists, a NaN (undefined) as None."""
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    value = float(value)
    return value if math.isfinite(value) else None


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
                         tracker: Tracker = _NO_TRACKER, more: Callable[[], list[Episode]] | None = None) -> None:
    """Step ``len(envs)`` episodes in lockstep, one ``agent.act_batch`` per step for all of them; a slot
    whose episode ends takes the next one, in order, and when ``episodes`` are used up the ones ``more()``
    hands out (until it returns none). Each record goes to ``finish`` as its episode ends.

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

    def refill() -> bool:
        nonlocal more
        if more is not None and not failed:
            queue.extend(more())
            if not queue:
                more = None  # the driver has nothing left
        return bool(queue)

    def start(i: int) -> None:
        slots[i] = None
        while queue or refill():
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


def task_size(n: int, workers: int, envs_per_worker: int) -> int:
    """Episodes per pool task: one for one-episode workers; for batched ones, chunks of at most
    ``_CHUNK_PER_SLOT`` episodes per slot (a worker's slots stay busy between refills), as many per worker
    (the workers finish together rather than one running a last chunk alone)."""
    if envs_per_worker <= 1:
        return 1
    per_worker = max(1, math.ceil(n / (workers * envs_per_worker * _CHUNK_PER_SLOT)))  # chunks per worker
    return max(1, math.ceil(n / (workers * per_worker)))


# ------------------------------------------------------------------------------------------- worker
class EpisodeWorker:
    """One process's agent and envs: :meth:`run` plays a task's episodes (their keys) and hands each
    record to ``finish`` as its episode ends.

    The agent is built once by ``make_agent(cfg)``; the env renders only the agent's ``sensors`` (all
    of RGB and depth when it declares none). A batched agent (``act_batch``) gets ``num_envs`` envs
    (default 1) stepped in lockstep; any other agent one env. Close the worker (or use it as a context
    manager) to release the envs' renderers.

    Args:
        cfg: the run's config.
        make_agent: the agent's factory.
        single_thread: use one core for torch and the renderer (a pool worker shares the machine).
    """

    def __init__(self, cfg: RunConfig, make_agent: AgentFactory, *, single_thread: bool = False) -> None:
        if single_thread:
            share_cores(1)
        self.cfg = cfg
        self.dataset = run_dataset(cfg.episodes, cfg.limit, cfg.per_scene, cfg.shard, cfg.task, cfg.gt)
        self.agent = make_agent(cfg)
        self.envs: list[NavEnv] = []
        try:  # an env that fails to start (a bad first episode, a bad scene) still closes the agent
            self.batched = is_batch_agent(self.agent)
            sensors = tuple(getattr(self.agent, "sensors", ("rgb", "depth")))
            n_envs = max(1, int(getattr(self.agent, "num_envs", 1))) if self.batched else 1
            for _ in range(n_envs):
                self.envs.append(make_env(cfg, self.dataset, sensors))
        except BaseException:
            self.close()
            raise
        self._by_key = {(e.scene_id, e.episode_id): e for e in self.dataset.episodes}

    def episode(self, key: Key) -> Episode:
        return self._by_key[key]

    def run(self, keys: Iterable[Key], finish: Callable[[dict[str, Any]], None], clock: Clock | None = None,
            tracker: Tracker = _NO_TRACKER, more: Callable[[], list[Key]] | None = None) -> None:
        """Run the episodes ``keys`` in order, handing each record to ``finish`` as its episode ends.

        Args:
            keys: (scene_id, episode_id) of episodes of the run's dataset.
            finish: takes each record; it may raise to stop the task.
            clock: times agent calls against the step limit (default: no limit).
            tracker: hears where each slot's episode is (a pool worker tells its driver).
            more: a batched worker's refill: further keys for a free slot once ``keys`` are used up ([]: none).
        """
        episodes = [self._by_key[k] for k in keys]
        if self.batched:
            refill = (lambda: [self._by_key[k] for k in more()]) if more is not None else None
            run_episodes_batched(self.envs, self.agent, episodes, self.cfg, finish, clock, tracker, refill)
        else:
            for ep in episodes:
                finish(run_episode(self.envs[0], self.agent, ep, self.cfg, clock, tracker))

    def close(self) -> None:
        """Release the envs, then call the agent's ``close()`` if it has one (a remote agent ends its
        session on the server); the records are written, so a failing ``close()`` only warns."""
        for env in self.envs:
            env.close()
        self.envs = []
        close, self.agent = getattr(self.agent, "close", None), None
        if callable(close):
            try:
                close()
            except Exception as exc:
                warnings.warn(f"agent close() raised {failure_reason(exc)}", RuntimeWarning, stacklevel=2)

    def __enter__(self) -> EpisodeWorker:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


class Msg(enum.Enum):
    """What a worker tells its driver (the local pool's pipe, the Ray backend's record queue)."""
    READY = "ready"  # the agent and envs are built
    BEGIN = "begin"  # an episode begins: (slot, key, record so far)
    RECORD = "record"  # an episode ended: its record
    DONE = "done"  # the task is finished
    MORE = "more"  # a batched worker has a free slot and no episode left: the driver answers with keys, [] at the end
    ERROR = "error"  # bad input or a bug: the exception, which ends the run


class RetryLedger:
    """How often each episode was running on a worker that died, for both backends: an episode that
    began on a worker that died is run again on a fresh one up to ``retries`` times, then recorded as
    failed; the episodes of the task that had not begun go back without a charge. A worker that dies
    before it is ready counts towards ``retries`` too (more such deaths end the run).

    >>> ledger = RetryLedger(retries=1, episodes="eps.json")
    >>> ledger.settle([("s", "1"), ("s", "2"), ("s", "3")], done={("s", "1")}, began={("s", "2")})
    ([('s', '2'), ('s', '3')], [])
    >>> ledger.settle([("s", "2"), ("s", "3")], done=set(), began={("s", "2")})
    ([('s', '3')], [('s', '2')])
    """

    def __init__(self, retries: int, episodes: str) -> None:
        self.retries, self.episodes = retries, episodes
        self.attempts: dict[Key, int] = {}
        self.startup_deaths = 0

    def startup_death(self, reason: str, what: str = "a worker") -> None:
        """A worker died before it was ready: a RunError once that happened more than ``retries`` times."""
        self.startup_deaths += 1
        if self.startup_deaths > self.retries:
            raise RunError(f"{self.episodes}: {what} could not start ({reason})")

    def settle(self, task: Iterable[Key], done: set[Key], began: set[Key], retry: bool = True
               ) -> tuple[list[Key], list[Key]]:
        """A dead worker's task: (the keys to run again, in task order; the keys that failed for good).

        Args:
            task: the keys of the worker's task.
            done: the keys whose records the driver has.
            began: the keys that began on the worker and had not ended.
            retry: False when the worker was killed for its episodes (a hung call): they fail at once.
        """
        rest: list[Key] = []
        failed: list[Key] = []
        for key in task:
            if key in done:
                continue
            if key in began:
                self.attempts[key] = self.attempts.get(key, 0) + 1
                if not retry or self.attempts[key] > self.retries:
                    failed.append(key)
                    continue
            rest.append(key)
        return rest, failed
