"""The Ray backend's overhead: the same memory-agent episodes on 2 local workers and on a local Ray instance.

    python benchmarks/ray_overhead.py --episodes 48 --small 8 --rounds 3

Runs the first N ObjectNav val_unseen episodes with ``backend="local", workers=2`` and then with
``backend="ray"`` on a Ray instance started with 2 CPUs (its start is part of its time, as a user waits
for it), alternating for ``--rounds`` rounds, each at two sizes (``--small`` and ``--episodes``) so the
per-episode cost (the slope) and the start-up (the rest) come apart; prints both per backend and the
per-episode ratio ray / local. The memories are built once before the first run. Checks the two backends' records agree
(without the wall-clock fields).
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import tempfile
import time
from pathlib import Path

from navbench.agents.plugins import resolve_agent
from navbench.agents.registry import AGENTS, prebuild_memories
from navbench.api import resolve_episodes
from navbench.episodes.io import load_dataset
from navbench.eval.runner import Execution, RunConfig, comparable, read_records, run, select_episodes
from navbench.paths import SCENES_DIR


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--episodes", type=int, default=48)
    ap.add_argument("--small", type=int, default=8, help="the short run that separates start-up from per-episode "
                    "cost: per episode = (time(episodes) - time(small)) / (episodes - small)")
    ap.add_argument("--workers", type=int, default=2, help="local workers, and the Ray instance's CPUs")
    ap.add_argument("--rounds", type=int, default=1, help="local/ray pairs, alternating")
    args = ap.parse_args()

    task, split, episodes, sd = resolve_episodes("objectnav", "val_unseen", None)
    agent = resolve_agent("memory", {}, 0)
    cfg = RunConfig(task=task, split=split, agent="memory", episodes=str(episodes), scene_dir=str(SCENES_DIR),
                    success_distance=sd, limit=args.episodes, envs_per_worker=AGENTS["memory"].envs_per_worker,
                    agent_options=agent.options)
    prebuild_memories(cfg, select_episodes(load_dataset(episodes), cfg.limit))
    per: dict[str, list[float]] = {"local": [], "ray": []}
    fixed: dict[str, list[float]] = {"local": [], "ray": []}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.rounds):
            for backend in ("local", "ray"):
                t = {}
                for n in (args.small, args.episodes):
                    t0 = time.perf_counter()
                    run(dataclasses.replace(cfg, limit=n), agent.factory, Path(tmp) / f"{backend}{i}_{n}",
                        execution=Execution(workers=args.workers, backend=backend), note=lambda _: None)
                    t[n] = time.perf_counter() - t0
                per[backend].append((t[args.episodes] - t[args.small]) / (args.episodes - args.small))
                fixed[backend].append(t[args.small] - args.small * per[backend][-1])
                print(f"round {i + 1} {backend:5s}: {t[args.episodes]:.1f} s for {args.episodes} episodes, "
                      f"{t[args.small]:.1f} s for {args.small}: {per[backend][-1]:.3f} s per episode + "
                      f"{fixed[backend][-1]:.1f} s start-up ({args.workers} "
                      f"{'workers' if backend == 'local' else 'Ray CPUs'})", flush=True)
            local, ray = (comparable(read_records(Path(tmp) / f"{b}{i}_{args.episodes}" / "episodes.jsonl"))
                          for b in ("local", "ray"))
            print(f"round {i + 1} records equal: {local == ray}", flush=True)
    m = {b: statistics.median(v) for b, v in per.items()}
    f = {b: statistics.median(v) for b, v in fixed.items()}
    print(f"median of {args.rounds}: per episode local {m['local']:.3f} s, ray {m['ray']:.3f} s (overhead ray/local "
          f"{m['ray'] / m['local']:.2f}x); start-up local {f['local']:.1f} s, ray {f['ray']:.1f} s")

if __name__ == "__main__":
    main()
