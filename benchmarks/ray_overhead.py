"""The Ray backend's overhead: the same memory-agent episodes on 2 local workers and on a local Ray instance.

    python benchmarks/ray_overhead.py --episodes 48 --rounds 1

Runs the first N ObjectNav val_unseen episodes with ``backend="local", workers=2`` and then with
``backend="ray"`` on a Ray instance started with 2 CPUs (its start is part of its time, as a user waits
for it), alternating for ``--rounds`` rounds, and prints each run's wall time per episode and the ratio
ray / local. The memories are built once before the first run. Checks the two backends' records agree
(without the wall-clock fields).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from navbench.agents.plugins import resolve_agent
from navbench.agents.registry import prebuild_memories
from navbench.api import resolve_episodes
from navbench.episodes.io import load_dataset
from navbench.eval.runner import RunConfig, run, select_episodes
from navbench.paths import SCENES_DIR


def _records(path: Path) -> list[dict]:
    out = []
    for line in path.read_text().splitlines():
        r = json.loads(line)
        r.pop("elapsed_s")
        r.get("log", {}).pop("query_ms", None)
        out.append(r)
    return sorted(out, key=lambda r: (r["scene_id"], r["episode_id"]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--episodes", type=int, default=48)
    ap.add_argument("--workers", type=int, default=2, help="local workers, and the Ray instance's CPUs")
    ap.add_argument("--rounds", type=int, default=1, help="local/ray pairs, alternating")
    args = ap.parse_args()

    task, split, episodes, sd = resolve_episodes("objectnav", "val_unseen", None)
    agent = resolve_agent("memory", {}, 0)
    cfg = RunConfig(task=task, split=split, agent="memory", episodes=str(episodes), scene_dir=str(SCENES_DIR),
                    success_distance=sd, limit=args.episodes, workers=args.workers, agent_options=agent.options)
    prebuild_memories(cfg, select_episodes(load_dataset(episodes), cfg.limit))
    times: dict[str, list[float]] = {"local": [], "ray": []}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.rounds):
            for backend in ("local", "ray"):
                out = Path(tmp) / f"{backend}{i}"
                t0 = time.perf_counter()
                run(cfg, agent.factory, out, backend=backend, note=lambda _: None)
                per = (time.perf_counter() - t0) / args.episodes
                times[backend].append(per)
                print(f"round {i + 1} {backend:5s}: {per:.2f} s/episode ({args.episodes} episodes, "
                      f"{args.workers} {'workers' if backend == 'local' else 'Ray CPUs'})", flush=True)
            local, ray = (_records(Path(tmp) / f"{b}{i}" / "episodes.jsonl") for b in ("local", "ray"))
            same = local == ray
            print(f"round {i + 1} records equal: {same}", flush=True)
    local, ray = (min(times[b]) for b in ("local", "ray"))
    print(f"best of {args.rounds}: local {local:.2f} s/episode, ray {ray:.2f} s/episode, overhead ray/local "
          f"{ray / local:.2f}x")


if __name__ == "__main__":
    main()
