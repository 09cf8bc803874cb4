"""Stateful rollout workers: each process owns some of the training envs and a copy of the policy.

Collection (render, expert, the acting policy's forward pass) is ~65% of the 2-hour training recipe, and
in one process it leaves a core idle most of the time: pyrender/OSMesa draws on one core (llvmpipe's second
thread helps little) and the expert and the env loop are Python. Two processes with one llvmpipe thread and
one torch thread each collected 266 frames/s together where one process with two threads collected 158
(session 31, family-25 EPYC; the platform notes measured the same 2x for rendering alone).

Unlike the evaluation runner's task pool, a training worker must keep its envs, its episodes in flight and
its recurrent states between calls, so each worker is a pinned process that builds one object with
``factory(*args)`` and then runs that object's methods on request. ``WorkerPool.call`` sends one request to
every worker and then waits for all of them, so the workers run in parallel and their results come back in
worker order: the same seed gives the same results whatever the timing.
"""

from __future__ import annotations

import os
import traceback
from collections.abc import Callable, Sequence
from multiprocessing import get_context
from typing import Any


class WorkerError(RuntimeError):
    """A worker raised; the message carries its traceback."""


def _serve(conn, factory: Callable[..., Any], args: tuple, threads: int) -> None:
    # Before anything renders or runs torch: one llvmpipe thread and ``threads`` torch threads, so the
    # workers share the cores instead of oversubscribing them (llvmpipe reads this when a context is made).
    os.environ["LP_NUM_THREADS"] = str(threads)
    import torch

    torch.set_num_threads(threads)
    try:
        obj = factory(*args)
    except BaseException:
        conn.send(("error", traceback.format_exc()))
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
            conn.send(("ok", getattr(obj, name)(*call_args)))
        except BaseException:
            conn.send(("error", traceback.format_exc()))


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
        results, errors = [], []
        for i, conn in enumerate(self._conns):
            try:
                status, value = conn.recv()
            except EOFError:
                status, value = "error", f"worker {i} exited (code {self._procs[i].exitcode})"
            if status == "error":
                errors.append(f"worker {i}: {value}")
            results.append(value)
        if errors:
            raise WorkerError("\n".join(errors))
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
                proc.terminate()
        for conn in self._conns:
            conn.close()
        self._conns, self._procs = [], []

    def __enter__(self) -> WorkerPool:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
