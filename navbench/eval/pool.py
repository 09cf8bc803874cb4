"""The evaluation runner's process pool: workers that may die without taking the run with them.

Each worker is a spawned process with its own :class:`~navbench.eval.worker.EpisodeWorker` that takes
tasks (lists of episode keys) over a pipe and sends back (:class:`~navbench.eval.worker.Msg`), per
episode, where it begins and its record when it ends. The driver hands the next task to whichever
worker is idle, in order; a batched worker with a free slot and no episode left asks for the next task
(``Msg.MORE``) without waiting for its slots to drain, so every slot stays busy and the workers finish
together however long the episodes are. When a worker dies (SIGKILL, a segfault in the GL driver, the OOM killer),
its records already sent are kept, the episodes it was running are retried on a fresh worker up to
``retries`` times and then recorded as failed ("worker died (signal 9)"), and the rest of its task
goes back to the front of the queue (a :class:`~navbench.eval.worker.RetryLedger` keeps the count).
A worker whose agent call outlives the step limit is killed and the episodes of that call are
recorded as failed.
"""

from __future__ import annotations

import time
import traceback
from collections import deque
from collections.abc import Callable
from multiprocessing import get_context
from multiprocessing.connection import wait
from typing import Any

from navbench.eval.rundir import RunError
from navbench.eval.worker import (
    Clock,
    EpisodeWorker,
    Key,
    Msg,
    RetryLedger,
    Tracker,
    failed_record,
    failure_reason,
    step_counts,
    step_timeout_reason,
)

_LIVE_EVERY = 1.0  # seconds between the driver's looks at the episodes in flight (run_pool's live)


class _PipeTracker(Tracker):
    """Tells the driver where each slot's episode is: a message when it begins, shared counters after the
    env's reset (the start's geodesic distance) and each step (with a GOAT-Bench episode's subtasks closed)."""

    def __init__(self, conn, steps, dist, d0, closed, subtasks) -> None:
        self.conn, self.steps, self.dist, self.d0 = conn, steps, dist, d0
        self.closed, self.subtasks = closed, subtasks

    def begin(self, slot: int, record: dict[str, Any], d0: float) -> None:
        self.steps[slot], self.dist[slot], self.d0[slot] = 0, d0, d0
        self.closed[slot] = self.subtasks[slot] = -1
        self.conn.send((Msg.BEGIN, (slot, (record["scene_id"], record["episode_id"]), record)))

    def started(self, slot: int, d0: float) -> None:
        self.dist[slot] = self.d0[slot] = d0

    def step(self, slot: int, info: dict[str, Any]) -> None:
        self.steps[slot], self.closed[slot], self.subtasks[slot] = step_counts(info)
        self.dist[slot] = info["distance_to_goal"]


def _send_exception(conn, exc: BaseException) -> None:
    try:
        conn.send((Msg.ERROR, exc))
    except Exception:  # unpicklable: its one line is enough
        conn.send((Msg.ERROR, RunError(f"worker: {failure_reason(exc)}")))


def _more(conn) -> list[Key]:
    """A batched worker's refill: ask the driver for more keys and wait for them ([]: there are none)."""
    conn.send((Msg.MORE, None))
    keys = conn.recv()
    if keys is None:  # the driver is stopping
        raise EOFError
    return keys


def _serve(conn, cfg, make_agent, limit, busy, steps, dist, d0, closed, subtasks) -> None:
    try:
        worker = EpisodeWorker(cfg, make_agent, single_thread=True)
    except Exception as exc:
        exc.add_note(traceback.format_exc())
        _send_exception(conn, exc)
        return
    clock, tracker = Clock(limit, busy), _PipeTracker(conn, steps, dist, d0, closed, subtasks)
    try:
        conn.send((Msg.READY, None))
        while True:
            try:
                keys = conn.recv()
            except EOFError:  # the driver went away
                return
            if keys is None:
                return
            try:
                worker.run(keys, lambda rec: conn.send((Msg.RECORD, rec)), clock, tracker, lambda: _more(conn))
            except (BrokenPipeError, EOFError):
                raise
            except Exception as exc:  # bad input (EpisodeError, SceneError) or a bug: ends the run
                _send_exception(conn, exc)
                continue
            conn.send((Msg.DONE, None))
    except (BrokenPipeError, EOFError, KeyboardInterrupt):  # the driver is gone or stopping
        return
    finally:
        worker.close()  # the envs' renderers, then the agent's close() (a remote agent ends its session)


class _Worker:
    def __init__(self, ctx, cfg, make_agent, limit: float | None, n_slots: int) -> None:
        self.busy = ctx.Value("d", 0.0, lock=False)
        self.steps = ctx.Array("l", n_slots, lock=False)
        self.dist = ctx.Array("d", n_slots, lock=False)
        self.d0 = ctx.Array("d", n_slots, lock=False)
        self.closed = ctx.Array("l", n_slots, lock=False)
        self.subtasks = ctx.Array("l", n_slots, lock=False)
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_serve, daemon=True,
                                args=(child, cfg, make_agent, limit, self.busy, self.steps, self.dist, self.d0,
                                      self.closed, self.subtasks))
        self.proc.start()
        child.close()
        self.ready = False
        self.task: list[Key] | None = None
        self.begun: dict[int, tuple[Key, dict[str, Any]]] = {}  # slot -> episode in flight
        self.done: set[Key] = set()
        self.started = time.monotonic()
        self.kill_reason: str | None = None

    def give(self, task: list[Key]) -> None:
        self.task, self.begun, self.done = list(task), {}, set()
        self.task_started = time.monotonic()
        self.conn.send(task)

    def death(self) -> str:
        self.proc.join(timeout=10)
        code = self.proc.exitcode
        if code is None:
            return "worker died (no exit status)"
        if code < 0:
            return f"worker died (signal {-code})"
        return f"worker died (exit code {code})"

    def in_flight(self) -> list[tuple[str, str, int, int, int]]:
        """(scene_id, episode_id, steps, subtasks closed, subtasks) of the episodes running on this worker."""
        return [(*key, int(self.steps[slot]), int(self.closed[slot]), int(self.subtasks[slot]))
                for slot, (key, _) in sorted(self.begun.items()) if key not in self.done]

    def stop(self) -> None:
        try:
            self.conn.send(None)
        except (BrokenPipeError, OSError):
            pass

    def kill(self) -> None:
        if self.proc.is_alive():
            self.proc.kill()
        self.proc.join(timeout=10)
        self.conn.close()


def run_pool(cfg, make_agent, tasks: list[list[Key]], finish: Callable[[dict[str, Any]], None], workers: int,
             n_slots: int, retries: int = 2, step_timeout: float | None = None,
             live: Callable[[list[tuple[str, str, int, int, int]]], None] | None = None) -> None:
    """Run ``tasks`` on ``workers`` processes, handing every record (run or failed) to ``finish``, and about once a
    second the episodes in flight to ``live`` (see :meth:`_Worker.in_flight`).

    Bad input raised in a worker (a bad episode or scene, an agent that cannot be built) ends the run: no
    further episode is handed out, the episodes other workers have in flight finish and are recorded, then it
    is raised here; ``finish`` may raise to stop the run.
    """
    ctx = get_context("spawn")  # torch and OSMesa state must not be forked
    queue: deque[list[Key]] = deque(tasks)
    ledger = RetryLedger(retries, cfg.episodes)
    pool: list[_Worker] = []

    def spawn() -> _Worker:
        return _Worker(ctx, cfg, make_agent, step_timeout, n_slots)

    def lost(w: _Worker) -> None:
        """``w`` is gone: fail or retry the episodes it was running and requeue the rest of its task."""
        reason = w.kill_reason or w.death()
        w.kill()
        if not w.ready:
            ledger.startup_death(reason)
        in_flight = {key: (rec, slot) for slot, (key, rec) in w.begun.items() if key not in w.done}
        rest, failed = ledger.settle(w.task or [], w.done, set(in_flight), retry=w.kill_reason is None)
        for key in failed:
            rec, slot = in_flight[key]
            finish(failed_record(rec, reason, float(w.d0[slot]), float(w.dist[slot]), int(w.steps[slot]),
                                 time.monotonic() - w.task_started))
        if rest:
            queue.appendleft(rest)
        if queue:
            pool[pool.index(w)] = spawn()
        else:
            pool.remove(w)

    last_live = time.monotonic()
    error: BaseException | None = None  # the first bad input a worker raised: raised once the others are done
    try:
        pool.extend(spawn() for _ in range(max(1, min(workers, len(tasks)))))
        while queue or any(w.task is not None for w in pool):
            for w in pool:
                if w.ready and w.task is None and queue:
                    w.give(queue.popleft())
            timeout = 0.2 if step_timeout is not None else _LIVE_EVERY if live is not None else None
            ready = wait([w.conn for w in pool], timeout=timeout)
            for conn in ready:
                w = next((w for w in pool if w.conn is conn), None)
                if w is None:
                    continue
                try:
                    kind, value = conn.recv()
                except (EOFError, OSError):
                    lost(w)
                    continue
                if kind is Msg.READY:
                    w.ready = True
                elif kind is Msg.BEGIN:
                    slot, key, rec = value
                    w.begun[slot] = (key, rec)
                elif kind is Msg.RECORD:
                    w.done.add((value["scene_id"], value["episode_id"]))
                    finish(value)
                elif kind is Msg.MORE:  # a free slot: the next task joins this worker's
                    keys = queue.popleft() if queue else []
                    if w.task is not None:
                        w.task.extend(keys)
                    w.conn.send(keys)
                elif kind is Msg.DONE:
                    w.task = None
                elif kind is Msg.ERROR:
                    error = error or value
                    w.task = None
                    queue.clear()  # nothing more is handed out; what other workers have begun finishes
            if live is not None and time.monotonic() - last_live >= _LIVE_EVERY:
                last_live = time.monotonic()
                live([e for w in pool if w.ready for e in w.in_flight()])
            if step_timeout is not None:
                now = time.monotonic()
                for w in pool:
                    t = w.busy.value
                    if w.task is not None and w.kill_reason is None and t and now - t > step_timeout:
                        w.kill_reason = step_timeout_reason(now - t, step_timeout)
                        w.proc.kill()  # its pipe then reads EOF: lost() records the call's episodes
        if error is not None:
            raise error
    finally:
        for w in pool:
            w.stop()
        deadline = time.monotonic() + 5
        for w in pool:
            w.proc.join(timeout=max(0.0, deadline - time.monotonic()))
            w.kill()

