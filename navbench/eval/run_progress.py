"""The driver's progress: episodes done / total, rate, ETA and failures so far.

A tqdm bar on a terminal; on a pipe or a log file (a SLURM job's), one plain line per episode, at most
one every ``every`` seconds on long runs (failures and the last episode always get theirs).
"""

from __future__ import annotations

import sys
import time
from typing import Any, TextIO


def _hms(seconds: float) -> str:
    s = int(round(seconds))
    return f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}"


class Progress:
    """A ``progress(record, done, total)`` callback for :func:`navbench.eval.runner.run`."""

    def __init__(self, stream: TextIO | None = None, tty: bool | None = None, every: float = 10.0,
                 long_run: int = 100) -> None:
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty() if tty is None else tty
        self.every, self.long_run = every, long_run
        self.t0 = time.monotonic()
        self.first: int | None = None  # episodes already done when this driver started (a resumed run)
        self.failed = 0
        self.last_line = -float("inf")
        self.bar = None

    def __call__(self, rec: dict[str, Any], n: int, total: int) -> None:
        if self.first is None:
            self.first = n - 1
        self.failed += bool(rec.get("failed"))
        ran, now = n - self.first, time.monotonic()
        rate = ran / max(now - self.t0, 1e-9)
        eta = (total - n) / rate if rate > 0 else float("inf")
        if self.tty:
            if self.bar is None:
                from tqdm import tqdm
                self.bar = tqdm(total=total, initial=self.first, file=self.stream, unit="ep", dynamic_ncols=True)
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
