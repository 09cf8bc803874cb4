"""Soak: many ObjectNav episodes across all 12 bundled houses with the memory agent, watching for leaks.

    python benchmarks/soak.py --episodes 2000 --workers 2 --csv soak.csv   # the full soak (not in CI)
    python benchmarks/soak.py --episodes 200 --workers 1                  # a quick check

Episodes cycle through the houses (the 8 train houses' ``train`` split, the 4 val houses'
``val_seen``/``val_unseen``), one house after another, so nearly every episode switches scene: the
path that closes a GL context and opens the next. Each worker steps its episodes through the
``EpisodeWorker`` a ``navbench run`` worker uses (one core, ``--envs-per-worker`` episodes in
lockstep, one env and GL context per slot).
After every episode each worker records its RSS, open file descriptors, live GL contexts (renderers
holding an OSMesa/EGL context) and threads. The CSV
has one row per episode; the summary gives the RSS growth between the 500th and the last episode of
each worker (scaled to a quarter of the run when it is shorter; the goal is under 5%) and the
fd / context / thread counts of the first and the last episode.
"""

from __future__ import annotations

import argparse
import csv
import gc
import itertools
import multiprocessing as mp
import os
import sys
import time
from pathlib import Path

from navbench.agents.registry import AGENTS
from navbench.episodes.io import load_dataset, save_dataset
from navbench.episodes.types import EpisodeDataset
from navbench.paths import SCENES_DIR, split_file

SPLITS = ("train", "val_seen", "val_unseen")  # together: all 8 train and 4 val houses
FIELDS = ("worker", "episode", "elapsed_s", "scene_id", "success", "rss_mb", "fds", "gl_contexts", "threads")


def soak_dataset(n: int) -> EpisodeDataset:
    """``n`` episodes taken round-robin over the houses of SPLITS (each house's episodes in file order)."""
    by_scene: dict[str, list] = {}
    out = EpisodeDataset()
    for split in SPLITS:
        ds = load_dataset(split_file("objectnav", split))
        for ep in ds.episodes:
            ep.extra["soak_split"] = split
            by_scene.setdefault(ep.scene_id, []).append(ep)
        out.goals_by_category.update(ds.goals_by_category)
        for cat in ds.category_to_task_category_id:
            out.category_to_task_category_id.setdefault(cat, len(out.category_to_task_category_id))
    cycles = [itertools.cycle(eps) for eps in by_scene.values()]
    seen: dict[tuple[str, str], int] = {}
    for ep in itertools.islice((next(c) for c in itertools.cycle(cycles)), n):
        key = (ep.scene_id, ep.episode_id)
        seen[key] = seen.get(key, 0) + 1
        copy = type(ep)(**{**ep.__dict__, "episode_id": f"{ep.episode_id}-{seen[key]}"})
        out.episodes.append(copy)
    return out


def _status(field: str) -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    return -1


def gl_contexts() -> int:
    """Renderers in this process that hold a GL context (open pyrender OffscreenRenderers)."""
    import pyrender
    return sum(1 for o in gc.get_objects()
               if isinstance(o, pyrender.OffscreenRenderer) and getattr(o, "_platform", None) is not None)


def probe() -> dict:
    return {"rss_mb": round(_status("VmRSS") / 1024, 1), "fds": len(os.listdir("/proc/self/fd")),
            "gl_contexts": gl_contexts(), "threads": _status("Threads")}


def worker(args: tuple) -> list[dict]:
    wid, episodes_file, indices, csv_dir, envs = args
    from navbench.agents.registry import AGENTS, agent_options
    from navbench.env.config import SUCCESS_DISTANCE
    from navbench.eval.config import RunConfig
    from navbench.eval.worker import EpisodeWorker

    cfg = RunConfig(task="objectnav", split=None, agent="memory", episodes=str(episodes_file),
                    scene_dir=str(SCENES_DIR), success_distance=SUCCESS_DISTANCE["ovon"],
                    envs_per_worker=envs, agent_options=agent_options("memory"))
    worker = EpisodeWorker(cfg, AGENTS["memory"].factory, single_thread=True)  # as a `navbench run` worker
    episodes = worker.dataset.episodes
    rows: list[dict] = []
    t0 = time.perf_counter()
    path = Path(csv_dir) / f"worker{wid}.csv"
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, FIELDS)
        w.writeheader()

        def finish(rec: dict) -> None:
            row = {"worker": wid, "episode": len(rows) + 1, "elapsed_s": round(time.perf_counter() - t0, 2),
                   "scene_id": rec["scene_id"], "success": rec.get("success"), **probe()}
            w.writerow(row)
            fh.flush()
            rows.append(row)

        worker.run([(episodes[i].scene_id, episodes[i].episode_id) for i in indices], finish)
    worker.close()
    return rows


def summarize(rows: list[dict], warmup: int) -> str:
    lines = []
    for wid in sorted({r["worker"] for r in rows}):
        rs = [r for r in rows if r["worker"] == wid]
        last = rs[-1]
        ref = rs[min(warmup, len(rs)) - 1]
        growth = 100 * (last["rss_mb"] - ref["rss_mb"]) / ref["rss_mb"]
        per100 = 100 * last["elapsed_s"] / len(rs)
        lines.append(
            f"worker {wid}: {len(rs)} episodes, {per100:.0f} s per 100 | RSS {rs[0]['rss_mb']:.0f} MB (ep 1), "
            f"{ref['rss_mb']:.0f} MB (ep {ref['episode']}), {last['rss_mb']:.0f} MB (ep {last['episode']}): "
            f"growth {growth:+.1f}% after ep {ref['episode']} | fds {rs[0]['fds']} -> {last['fds']} | "
            f"GL contexts {rs[0]['gl_contexts']} -> {last['gl_contexts']} | threads {rs[0]['threads']} -> "
            f"{last['threads']}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--episodes", type=int, default=2000, help="episodes in all (split among workers)")
    p.add_argument("--workers", type=int, default=1)
    p.add_argument("--warmup", type=int, default=500, help="RSS growth is measured from this episode of each "
                   "worker on (a quarter of the worker's episodes if it runs fewer than 4x this)")
    p.add_argument("--envs-per-worker", type=int, default=AGENTS["memory"].envs_per_worker,
                   help="episodes a worker steps in lockstep (default: navbench run's)")
    p.add_argument("--csv", default="soak.csv")
    args = p.parse_args(argv)
    if args.episodes < 1 or args.workers < 1:
        p.error("--episodes and --workers must be >= 1")
    out_dir = Path(args.csv).resolve().parent
    episodes_file = save_dataset(soak_dataset(args.episodes), out_dir / "soak_episodes.json.gz")
    # Every house's memory is built once here, so workers never build the same one at once.
    from navbench.agents.registry import agent_options
    from navbench.env.config import SUCCESS_DISTANCE
    from navbench.eval.config import RunConfig
    cfg = RunConfig(task="objectnav", split=None, agent="memory", episodes=str(episodes_file),
                    scene_dir=str(SCENES_DIR), success_distance=SUCCESS_DISTANCE["ovon"],
                    agent_options=agent_options("memory"))
    AGENTS["memory"].prepare(cfg, load_dataset(episodes_file).episodes)
    chunks = [(w, str(episodes_file), list(range(w, args.episodes, args.workers)), str(out_dir), args.envs_per_worker)
              for w in range(args.workers)]
    # spawn: each worker starts clean, as `navbench run` workers do, not a copy of this process
    with mp.get_context("spawn").Pool(args.workers) as pool:
        results = pool.map(worker, chunks)
    rows = [r for rs in results for r in rs]
    with open(args.csv, "w", newline="") as fh:
        w = csv.DictWriter(fh, FIELDS)
        w.writeheader()
        w.writerows(rows)
    per_worker = args.episodes // args.workers
    warmup = args.warmup if per_worker >= 4 * args.warmup else max(1, per_worker // 4)
    print(summarize(rows, warmup))
    print(f"wrote {args.csv} (and per-worker CSVs as they run in {out_dir})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
