"""Scene-switch cost and memory: reset a depth-only PointNav env into a new house again and again.

    python benchmarks/scene_switch.py                     # 150 switches over the train_large houses
    python benchmarks/scene_switch.py --ballast 2000000   # with 2M live Python objects, like a trainer

DAgger collection on the train_large houses switches scene on nearly every episode, so the cost of a
switch (closing the old GL context, loading the new scene and navigability grid, a new context) is
paid many times per iteration. Prints ms per switch and the process's RSS after the first and the
last third of the switches: RSS that keeps growing after every house has been visited once is a leak
(GL buffers or contexts not freed).
"""

from __future__ import annotations

import argparse
import json
import resource
import time

from navbench.env.config import EnvConfig
from navbench.env.pointnav import PointNavEnv
from navbench.episodes.io import load_dataset
from navbench.paths import split_file


def rss_mb() -> float:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", default="train_large", help="PointNav split whose houses are cycled")
    parser.add_argument("--switches", type=int, default=150)
    parser.add_argument("--ballast", type=int, default=0,
                        help="live Python objects to hold (a full gc.collect walks them all)")
    args = parser.parse_args()
    ballast = [(i,) for i in range(args.ballast)]  # noqa: F841 (kept alive on purpose)

    ds = load_dataset(split_file("pointnav", args.split))
    first_of_scene: dict[str, int] = {}
    for i, ep in enumerate(ds.episodes):
        first_of_scene.setdefault(ep.scene_id, i)
    order = list(first_of_scene.values())
    env = PointNavEnv(ds, config=EnvConfig(rgb=False, depth=True))
    env.reset(seed=0, options={"episode": order[0]})
    third = max(1, args.switches // 3)
    marks, t0 = {}, time.perf_counter()
    for k in range(1, args.switches + 1):
        env.reset(options={"episode": order[k % len(order)]})  # always another house than before
        if k in (third, args.switches):
            marks[k] = rss_mb()
    elapsed = time.perf_counter() - t0
    env.close()
    print(json.dumps({"split": args.split, "houses": len(order), "switches": args.switches,
                      "ballast_objects": args.ballast, "ms_per_switch": round(1000 * elapsed / args.switches, 1),
                      f"rss_mb_after_{third}": round(marks[third], 1),
                      f"rss_mb_after_{args.switches}": round(marks[args.switches], 1)}))


if __name__ == "__main__":
    main()
