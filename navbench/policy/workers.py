"""Stateful rollout workers: each process owns some of the training envs and a copy of the policy.

    navbench train dagger --workers 2 ...    # navbench.policy.rollout.Collection starts the pool

Collection (render, expert, the acting policy's forward pass) is most of a DAgger iteration, and in one process
only the policy's convolutions use both cores: pyrender/OSMesa gains little from llvmpipe's second thread, and the
expert and the env loop are Python. Two processes with one llvmpipe thread and one torch thread each keep both
cores busy.

Unlike the evaluation runner's task pool, a training worker must keep its envs, its episodes in flight and
its recurrent states between calls, so each worker is a pinned process that builds one object with
``factory(*args)`` and then runs that object's methods on request. ``WorkerPool.call`` sends one request to
every worker and then waits for all of them, so the workers run in parallel and their results come back in
worker order: the same seed gives the same results whatever the timing.
"""

from __future__ import annotations

import os
import signal
import traceback
from collections.abc import Callable, Sequence
from multiprocessing import get_context
from typing import Any


class WorkerError(RuntimeError):
    """A worker failed with an error that could not be sent back (or its process died); the message says which."""


def _send_error(conn, exc: BaseException) -> None:
    # The exception itself, so the parent re-raises the same type (the CLI turns a ValueError or a missing file
    # into its one-line error), with the worker's traceback as text; an unpicklable one goes as text only.
    tb = traceback.format_exc()
    try:
        conn.send(("error", (exc, tb)))
    except Exception:
        conn.send(("error", (None, tb)))


def share_cores(threads: int) -> None:
    """Give this worker process ``threads`` llvmpipe and torch threads. Call it before anything renders
    (llvmpipe reads ``LP_NUM_THREADS`` when a context is made). Why: two processes with one thread each use
    2 cores about twice as well for rendering as one process with two (platform notes), and more threads
    than cores would only oversubscribe them."""
    os.environ["LP_NUM_THREADS"] = str(threads)
    import torch

    torch.set_num_threads(threads)


def _serve(conn, factory: Callable[..., Any], args: tuple, threads: int) -> None:
    # SLURM's scancel and time-limit warning, and `kill -- -PGID`, reach every process of the job: the trainer
    # notes them, finishes its update, saves, and then closes its workers, which must still answer until then
    for s in (signal.SIGTERM, signal.SIGUSR1):
        signal.signal(s, signal.SIG_IGN)
    share_cores(threads)
    try:
        obj = factory(*args)
    except Exception as exc:
        _send_error(conn, exc)
        return
    conn.send(("ready", None))
    while True:
        try:
            msg = conn.recv()
        except EOFError:  # the parent went away
            return
        if msg is None:
            return
        name, call_args = msg
        try:
            result = getattr(obj, name)(*call_args)
        except Exception as exc:
            _send_error(conn, exc)
            continue
        conn.send(("ok", result))


class WorkerPool:
    """``len(args)`` spawned processes; worker ``i`` holds ``factory(*args[i])``.

    ``call(name, per_worker_args)`` runs ``obj.name(*per_worker_args[i])`` in every worker at once and
    returns the results in worker order. Use as a context manager (or call ``close``) so the processes end.
    """

    def __init__(self, factory: Callable[..., Any], args: Sequence[tuple], threads: int = 1) -> None:
        ctx = get_context("spawn")  # torch and OSMesa state must not be forked
        self._conns, self._procs = [], []
        for a in args:
            parent, child = ctx.Pipe()
            proc = ctx.Process(target=_serve, args=(child, factory, tuple(a), threads), daemon=True)
            proc.start()
            child.close()
            self._conns.append(parent)
            self._procs.append(proc)
        try:
            self._gather()  # wait until every worker has built its object (or report why one could not)
        except BaseException:
            self.close()
            raise

    def __len__(self) -> int:
        return len(self._procs)

    def _gather(self) -> list[Any]:
        """Every worker's answer, in worker order; the first worker's error is raised once all have answered."""
        results, error = [], None
        for i, conn in enumerate(self._conns):
            try:
                status, value = conn.recv()
            except EOFError:
                self._procs[i].join(timeout=5)
                status, value = "error", (None, f"exited with code {self._procs[i].exitcode}")
            if status == "error" and error is None:
                exc, tb = value
                if exc is None:
                    error = WorkerError(f"rollout worker {i}: {tb.strip().splitlines()[-1]}")
                    error.add_note(tb)
                else:
                    error = exc
                    error.add_note(f"raised in rollout worker {i}:\n{tb}")
            results.append(value)
        if error is not None:
            raise error
        return results

    def call(self, name: str, per_worker_args: Sequence[tuple] | None = None) -> list[Any]:
        per_worker_args = per_worker_args if per_worker_args is not None else [()] * len(self)
        if len(per_worker_args) != len(self):
            raise ValueError(f"{len(per_worker_args)} argument tuples for {len(self)} workers")
        for conn, a in zip(self._conns, per_worker_args):
            conn.send((name, tuple(a)))
        return self._gather()

    def close(self) -> None:
        for conn in self._conns:
            try:
                conn.send(None)
            except (BrokenPipeError, OSError):
                pass
        for proc in self._procs:
            proc.join(timeout=10)
            if proc.is_alive():
                proc.kill()  # a worker ignores SIGTERM
                proc.join(timeout=5)
        for conn in self._conns:
            conn.close()
        self._conns, self._procs = [], []

    def __enter__(self) -> WorkerPool:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
