"""The driver's progress: episodes done / total, rate, ETA and failures so far, and the episodes in flight.

A tqdm bar on a terminal; on a pipe or a log file (a SLURM job's), one plain line per episode, at most
one every ``every`` seconds on long runs (failures and the last episode always get theirs). An episode
still running after ``live_every`` seconds without a line (a GOAT-Bench episode runs up to 5000 steps) gets
one saying its steps and, on GOAT-Bench, the subtasks it closed, so a slow run reads apart from a stuck one.
"""

from __future__ import annotations

import sys
import time
from typing import Any, NamedTuple, TextIO


class InFlight(NamedTuple):
    """An episode being run: its steps so far and, on GOAT-Bench, its subtasks closed of all (else -1)."""
    scene_id: str
    episode_id: str
    steps: int
    closed: int = -1
    subtasks: int = -1

    def describe(self) -> str:
        done = f", subtasks {self.closed}/{self.subtasks} closed" if self.subtasks >= 0 else ""
        return f"{self.scene_id} ep {self.episode_id}: step {self.steps}{done}"


def _hms(seconds: float) -> str:
    s = int(round(seconds))
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"


class Progress:
    """A ``progress(record, done, total)`` callback for :func:`navbench.eval.runner.run`."""

    def __init__(self, stream: TextIO | None = None, tty: bool | None = None, every: float = 10.0,
                 long_run: int = 100, live_every: float = 30.0) -> None:
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty() if tty is None else tty
        self.every, self.long_run, self.live_every = every, long_run, live_every
        self.t0 = time.monotonic()
        self.first: int | None = None  # episodes already done when this driver started (a resumed run)
        self.failed = 0
        self.last_line = -float("inf")
        self.last_live = time.monotonic()  # the last line saying something (a record's or the episodes in flight)
        self.bar = None

    def __call__(self, rec: dict[str, Any], n: int, total: int) -> None:
        if self.first is None:
            self.first = n - 1
        self.failed += bool(rec.get("failed"))
        ran, now = n - self.first, time.monotonic()
        rate = ran / max(now - self.t0, 1e-9)
        eta = (total - n) / rate if rate > 0 else float("inf")
        self.last_live = now
        if self.tty:
            self._bar(total, self.first)
            self.bar.set_postfix(failed=self.failed, refresh=False)
            self.bar.update(1)
            if n >= total:
                self.bar.close()
            return
        last = n >= total
        if not (rec.get("failed") or last or total <= self.long_run or now - self.last_line >= self.every):
            return
        self.last_line = now
        if rec.get("skipped"):
            status = "skipped"
        elif rec.get("failed"):
            status = f"FAILED: {rec['failure_reason']}"
        else:
            status = f"success={rec['success']:.0f} spl={rec['spl']:.3f}"
        print(f"[{n}/{total}] {rate:.2f} ep/s, ETA {_hms(eta) if eta != float('inf') else '?'}, "
              f"{self.failed} failed | {rec['scene_id']} ep {rec['episode_id']}: {status}",
              file=self.stream, flush=True)

    def _bar(self, total: int, initial: int) -> None:
        if self.bar is None:
            from tqdm import tqdm
            self.bar = tqdm(total=total, initial=initial, file=self.stream, unit="ep", dynamic_ncols=True)

    def live(self, in_flight: list[tuple], done: int, total: int) -> None:
        """The episodes in flight, as :class:`InFlight` fields (the runner calls this about once a second): a
        line once ``live_every`` seconds passed without one; on a terminal, the bar's postfix."""
        now = time.monotonic()
        if not in_flight or now - self.last_live < (1.0 if self.tty else self.live_every):
            return
        self.last_live = now
        shown = "; ".join(InFlight(*e).describe() for e in in_flight[:3]) + \
            (f"; {len(in_flight) - 3} more" if len(in_flight) > 3 else "")
        if self.tty:
            self._bar(total, done)
            self.bar.set_postfix_str(shown)
            return
        print(f"[{done}/{total}] running {_hms(now - self.t0)} | {shown}", file=self.stream, flush=True)
