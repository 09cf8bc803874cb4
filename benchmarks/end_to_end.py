"""End to end: ObjectNav val_unseen with the memory agent, batched (the default) against one episode at a time.

    python benchmarks/end_to_end.py                      # the whole 160-episode split, 2 workers
    python benchmarks/end_to_end.py --limit 48 --repeats 3

Runs ``navbench run --split val_unseen --workers 2`` with the default ``--envs-per-worker`` (8 episodes per
worker in lockstep, one PointNav forward pass per step) and with ``--envs-per-worker 1``, alternating, and
prints each run's wall time (start-up included, memories already cached), the ratio and whether the two
give the same records (wall-clock fields aside). Run it on an otherwise idle machine.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from navbench.eval.runner import comparable, read_records


def records(out: Path) -> list[dict]:
    return comparable(read_records(out / "episodes.jsonl"))


def run(out: Path, limit: int | None, workers: int, envs: int | None) -> float:
    cmd = [sys.executable, "-m", "navbench.cli", "run", "--split", "val_unseen", "--workers", str(workers),
           "--out", str(out), "--overwrite", "-q"]
    cmd += ["--limit", str(limit)] if limit else []
    cmd += ["--envs-per-worker", str(envs)] if envs else []
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, env={**os.environ, "PYOPENGL_PLATFORM": os.environ.get("PYOPENGL_PLATFORM",
                                                                                           "osmesa")})
    return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--limit", type=int, help="the first N episodes (default: all 160)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--repeats", type=int, default=1)
    args = p.parse_args(argv)
    # build or check the cached memories once, outside the timed runs
    with tempfile.TemporaryDirectory() as tmp:
        run(Path(tmp) / "warm", 1, 1, 1)
        times: dict[str, list[float]] = {"batched": [], "one at a time": []}
        for _ in range(args.repeats):
            times["one at a time"].append(run(Path(tmp) / "single", args.limit, args.workers, 1))
            times["batched"].append(run(Path(tmp) / "batched", args.limit, args.workers, None))
        same = records(Path(tmp) / "single") == records(Path(tmp) / "batched")
        n = len(records(Path(tmp) / "batched"))
    med = {k: statistics.median(v) for k, v in times.items()}
    print(f"memory agent, val_unseen, {n} episodes, {args.workers} workers, {os.cpu_count()} CPUs")
    for k, v in times.items():
        print(f"  {k:>14}: {med[k]:6.1f} s  (runs: {', '.join(f'{x:.1f}' for x in v)})")
    print(f"  speed-up: {med['one at a time'] / med['batched']:.2f}x; records identical: {same}")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
