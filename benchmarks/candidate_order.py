"""How well the memory agent picks its first goal candidate: route over the keyframe poses vs straight line.

For every episode of an ObjectNav split where the localiser (oracle perception, the agent's default
memory) returns two or more candidates, the true geodesic distance from the start to each candidate
(its centre snapped to the navigability grid) is read off the grid, a privileged measurement the agent
never sees. Reported: the sum over those episodes of the geodesic excess of the candidate each ordering
puts first over the geodesically nearest one (0 = always the nearest), and the number of episodes
where that excess is over 1 m. No policy runs.

    .venv/bin/python benchmarks/candidate_order.py --split val_seen_synonyms
"""

from __future__ import annotations

import argparse

import numpy as np

from navbench.agents.memory_agent import nearest_first
from navbench.agents.perceive import SceneLocalizer
from navbench.episodes.io import load_dataset
from navbench.paths import EPISODES_DIR, SCENES_DIR
from navbench.scene.cache import load_scene_and_navgrid


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--split", default="val_seen_synonyms")
    args = ap.parse_args()
    files = sorted((EPISODES_DIR / "objectnav" / args.split).glob("*.json*"))
    if not files:
        raise SystemExit(f"{EPISODES_DIR / 'objectnav' / args.split}: no episode file")
    localizer = SceneLocalizer(SCENES_DIR)
    grids = {}
    excess = {"route": [], "straight": []}
    for path in files:
        for ep in load_dataset(path).episodes:
            cands = localizer(ep)
            if len(cands) < 2:
                continue
            if ep.scene_id not in grids:
                grids[ep.scene_id] = load_scene_and_navgrid(SCENES_DIR / ep.scene_id)[1]
            grid, start = grids[ep.scene_id], np.asarray(ep.start_position, np.float64)
            geo = np.array([grid.geodesic_distance(start, grid.snap_point(c.centre, max_dist=1.5)[None])
                            for c in cands])
            first = {"route": nearest_first(cands, start, localizer.route_lengths)[0][0],
                     "straight": nearest_first(cands, start, None)[0][0]}  # the agent's two orders
            for k, j in first.items():
                excess[k].append(geo[j] - geo.min())
    n = len(excess["route"])
    print(f"{args.split}: {n} episodes with 2+ candidates")
    for k, v in excess.items():
        v = np.asarray(v)
        print(f"  first by {k:8s}: geodesic excess {v.sum():6.1f} m in all, over 1 m in {int((v > 1).sum())} episodes")


if __name__ == "__main__":
    main()
