"""Failure rate of a finished run by how close each episode's start is to an obstacle.

The clearance of a start is the distance from the agent's centre to the nearest non-navigable cell of
the navigability grid (Euclidean distance transform; 0.05 m cells; the grid is already eroded by the
agent's 0.18 m radius, so a clearance of 0.1 m leaves 0.28 m between the body's centre and the
obstacle). A privileged measurement: no agent sees the grid. It separates the starts wedged beside
furniture or in a slit between furniture and a wall, where depth reads 0 (nearer than 0.5 m) on the
blocked side, from the rest. No policy runs.

    .venv/bin/python benchmarks/start_clearance.py results/runs/pointnav_val results/runs/memory_val_unseen
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pandas as pd

from navbench.env.config import EnvConfig
from navbench.episodes.io import load_dataset
from navbench.eval.runner import read_records
from navbench.paths import SCENES_DIR, split_file
from navbench.scene.cache import load_scene_and_navgrid

BINS = (0.0, 0.1, 0.2, np.inf)  # metres of clearance: <= 0.1, (0.1, 0.2], > 0.2


def start_clearances(episodes_file: str, scene_dir: Path) -> dict[str, float]:
    """Episode id -> clearance (m) of its start on the scene's navigability grid."""
    cfg = EnvConfig().nav_grid_config()  # the grid the env moves the agent on
    grids: dict[str, tuple] = {}
    out = {}
    for ep in load_dataset(episodes_file).episodes:
        if ep.scene_id not in grids:
            _, grid = load_scene_and_navgrid(scene_dir / ep.scene_id, cfg)
            grids[ep.scene_id] = grid, grid.navigable_clearance()
        grid, clearance = grids[ep.scene_id]
        i, j = grid.world_to_grid(np.asarray(ep.start_position, np.float64))
        out[ep.episode_id] = float(clearance[i, j])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+", help="run directories (episodes.jsonl + config.json)")
    args = ap.parse_args()
    rows = []
    for run in map(Path, args.runs):
        cfg = json.loads((run / "config.json").read_text())
        # a bundled split is read from this checkout (config.json holds the absolute paths of the run's)
        episodes = split_file(cfg["task"], cfg["split"]) if cfg.get("split") else cfg["episodes"]
        scene_dir = SCENES_DIR if cfg.get("split") else Path(cfg["scene_dir"])
        clear = start_clearances(str(episodes), scene_dir)
        recs = [r for r in read_records(run / "episodes.jsonl") if not r.get("skipped")]
        df = pd.DataFrame({"clearance": [clear[r["episode_id"]] for r in recs],
                           "failed": [1 - r["success"] for r in recs]})
        df["start clearance (m)"] = pd.cut(df["clearance"], BINS, include_lowest=True,
                                           labels=["<= 0.1", "0.1-0.2", "> 0.2"])
        g = df.groupby("start clearance (m)", observed=False)["failed"].agg(episodes="size", failures="sum")
        g["failure rate (%)"] = 100 * g["failures"] / g["episodes"].clip(lower=1)
        g.insert(0, "run", run.name)
        rows.append(g.reset_index())
    print(pd.concat(rows).to_markdown(index=False, floatfmt=".1f"))


if __name__ == "__main__":
    main()
