"""Start-up cost: how long a worker takes to be ready, and a one-episode run end to end.

    python benchmarks/startup.py            # memory agent, ObjectNav val_unseen, memories cached

Prints, median of ``--repeats`` fresh processes: the imports a worker needs; the worker's set-up after
them (episode file, agent with its checkpoint, localiser and detector, envs); and the wall time of
``navbench run --split val_unseen --limit 1`` (memory cached). Run it on an otherwise idle machine.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

WORKER = r"""
import json, sys, time
t0 = time.perf_counter()
import navbench.agents.lockstep, navbench.agents.memory_agent, navbench.agents.perceive  # noqa: E401
from navbench.agents.registry import agent_options, make_memory
from navbench.eval.config import RunConfig
from navbench.eval.worker import EpisodeWorker
from navbench.paths import SCENES_DIR, split_file
t1 = time.perf_counter()
cfg = RunConfig(task="objectnav", split="val_unseen", agent="memory",
                episodes=str(split_file("objectnav", "val_unseen")), scene_dir=str(SCENES_DIR),
                success_distance=0.1, agent_options=agent_options("memory"))
w = EpisodeWorker(cfg, make_memory, single_thread=True)
ep = w.dataset.episodes[0]
w.envs[0].reset(options={"episode": ep})
w.agent.reset(ep)
t2 = time.perf_counter()
print(json.dumps({"imports_s": t1 - t0, "ready_s": t2 - t1}))
"""


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args(argv)
    env = {**os.environ, "PYOPENGL_PLATFORM": os.environ.get("PYOPENGL_PLATFORM", "osmesa")}
    with tempfile.TemporaryDirectory() as tmp:
        run = [sys.executable, "-m", "navbench.cli", "run", "--split", "val_unseen", "--limit", "1", "--out", tmp,
               "--overwrite", "-q"]
        subprocess.run(run, check=True, env=env, capture_output=True)  # memory built or checked once
        rows, walls = [], []
        for _ in range(args.repeats):
            out = subprocess.run([sys.executable, "-c", WORKER], check=True, env=env, capture_output=True, text=True)
            rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
            t = time.perf_counter()
            subprocess.run(run, check=True, env=env, capture_output=True)
            walls.append(time.perf_counter() - t)
    med = {k: statistics.median(r[k] for r in rows) for k in rows[0]}
    print(f"worker imports {med['imports_s']:.2f} s, then ready to step in {med['ready_s']:.2f} s (goal <= 2 s); "
          f"`navbench run --split val_unseen --limit 1`: {statistics.median(walls):.2f} s wall (goal <= 4 s); "
          f"{os.cpu_count()} CPUs, median of {args.repeats}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
