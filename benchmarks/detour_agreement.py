"""navbench's geodesic start distance (d0) against Detour's, the path query habitat-sim measures with.

The anchor (``shared/detour-anchor``: ``detour.cjs``) builds a Recast navmesh with habitat-sim's navmesh
settings for navbench's agent (radius 0.18 m, height 0.88 m, max climb 0.2 m, max slope 45 deg) from the
same mesh navbench reads, and returns Detour's shortest 3D path from each episode's start to the nearest
goal (ObjectNav: every view point). navbench's d0 is computed here, live, as the env computes it at reset
(the grid of the start's storey, the start snapped if off it, the distance field to the goal points), so
the script measures the grid the checkout builds, not the d0 stored in the episode file; ``--changed``
also lists the episodes whose live d0 differs from the file's ``info.geodesic_distance``.

    npm install --prefix ~/.cache/recast @recast-navigation/core@0.43.1 @recast-navigation/generators@0.43.1
    PYTHONPATH=$PWD python benchmarks/detour_agreement.py                  # bundled val + val_unseen
    PYTHONPATH=$PWD python benchmarks/detour_agreement.py episodes/pointnav/val/val.json.gz -v
    PYTHONPATH=$PWD python benchmarks/detour_agreement.py --changed --json /tmp/agreement.json

Per split it prints the share of episodes whose d0 agrees within ``--tol`` (3%), every episode outside
it (worst first) and every reachability disagreement (one finite, the other not). ``--anchor DIR``
(or ``NAVBENCH_DETOUR_ANCHOR``) names the anchor directory (default ``../shared/detour-anchor`` beside
the repository), ``--recast`` the npm prefix holding ``@recast-navigation``. Detour's paths follow
navmesh polygon edges, so on open floors they run up to ~1-2% longer than navbench's any-angle paths.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
BUNDLED = ["episodes/pointnav/val/val.json.gz", "episodes/objectnav/val_unseen/val_unseen.json.gz"]


def navbench_d0(grid, episode) -> float:
    """d0 as ``NavEnv.reset`` measures it (start snapped onto the grid if it is off it)."""
    start = np.asarray(episode.start_position, np.float64)
    if not grid.is_navigable(start):
        start = grid.snap_point(start)
        if not np.isfinite(start).all():
            return math.inf
    return float(grid.distance_field(episode.goal_positions()).distance(start))


def detour_d0(anchor: Path, recast: Path, mesh, queries: list[dict], cell_size: float, cell_height: float) -> list:
    """Detour's d0 per query ({id, start, goals}); None where no goal is reachable."""
    with tempfile.TemporaryDirectory() as tmp:
        job = Path(tmp) / "job.json"
        job.write_text(json.dumps({"positions": np.asarray(mesh.vertices, float).ravel().tolist(),
                                   "indices": np.asarray(mesh.faces, int).ravel().tolist(), "queries": queries,
                                   "cell_size": cell_size, "cell_height": cell_height}))
        r = subprocess.run(["node", str(anchor / "detour.cjs"), str(recast.resolve()), str(job)],
                           capture_output=True, text=True, timeout=3600, check=False)
    if r.returncode:
        sys.exit(f"detour failed: {r.stdout[-300:]} {r.stderr[-500:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def compare(path: Path, scene_dir: Path, anchor: Path, recast: Path, args) -> list[dict]:
    from navbench.env.base import resolve_scene_path
    from navbench.episodes.io import load_dataset
    from navbench.scene.cache import load_scene_and_navgrid

    dataset = load_dataset(path)
    by_scene: dict[str, list] = {}
    for ep in dataset.episodes[: args.limit]:
        by_scene.setdefault(ep.scene_id, []).append(ep)
    rows = []
    for scene_id, eps in sorted(by_scene.items()):
        asset, grid = load_scene_and_navgrid(resolve_scene_path(scene_id, scene_dir))
        queries = [{"id": e.episode_id, "start": [float(v) for v in e.start_position],
                    "goals": e.goal_positions().tolist()} for e in eps]
        detour = {q["id"]: q["d"] for q in detour_d0(anchor, recast, asset.mesh, queries, args.cell_size,
                                                     args.cell_height)}
        for e in eps:
            g = grid
            if abs(float(e.start_position[1]) - grid.floor_height) > grid.config.agent_height / 2:
                g = load_scene_and_navgrid(resolve_scene_path(scene_id, scene_dir),
                                           floor_hint=float(e.start_position[1]))[1]
            d_nav = navbench_d0(g, e)
            d_det = detour[e.episode_id]
            rows.append({"split": str(path), "scene_id": scene_id, "episode_id": e.episode_id,
                         "navbench": d_nav if math.isfinite(d_nav) else None, "detour": d_det,
                         "file": e.info.get("geodesic_distance")})
    return rows


def summarise(rows: list[dict], tol: float, verbose: bool, changed: bool) -> None:
    agree, outside, reach = 0, [], []
    for r in rows:
        n, d = r["navbench"], r["detour"]
        if n is None or d is None:
            if (n is None) != (d is None):
                reach.append(r)
            else:
                agree += 1  # both unreachable: the same verdict
            continue
        rel = (n - d) / d
        r["rel"] = rel
        if abs(rel) <= tol:
            agree += 1
        else:
            outside.append(r)
        if verbose:
            print(f"  {r['scene_id']} ep {r['episode_id']}: navbench {n:.3f}  detour {d:.3f}  ({100 * rel:+.2f}%)")
    print(f"{rows[0]['split']}: {agree}/{len(rows)} = {100 * agree / len(rows):.1f}% within {100 * tol:g}% of "
          f"Detour and the same reachability; {len(outside)} outside, {len(reach)} reachability disagreements")
    for r in sorted(outside, key=lambda r: -abs(r["rel"])):
        print(f"  outside: {r['scene_id']} ep {r['episode_id']}: navbench {r['navbench']:.3f}  "
              f"detour {r['detour']:.3f}  ({100 * r['rel']:+.1f}%)")
    for r in reach:
        print(f"  reachability: {r['scene_id']} ep {r['episode_id']}: navbench {r['navbench']}  detour {r['detour']}")
    if changed:
        moved = [r for r in rows if r["file"] is not None and
                 (r["navbench"] is None or abs(r["navbench"] - r["file"]) > 1e-5 * max(1.0, r["file"]))]
        print(f"  live d0 differs from the file's on {len(moved)}/{len(rows)} episodes")
        for r in moved:
            print(f"    changed: {r['scene_id']} ep {r['episode_id']}: file {r['file']}  live {r['navbench']}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("episodes", nargs="*", help="episode files (default: the bundled val and val_unseen)")
    ap.add_argument("--scene-dir", type=Path, default=REPO / "envs")
    ap.add_argument("--anchor", type=Path, default=Path(os.environ.get(
        "NAVBENCH_DETOUR_ANCHOR", REPO.parent / "shared" / "detour-anchor")))
    ap.add_argument("--recast", type=Path, default=Path.home() / ".cache" / "recast")
    ap.add_argument("--cell-size", type=float, default=0.05, help="Recast cs (habitat-sim default 0.05)")
    ap.add_argument("--cell-height", type=float, default=0.05, help="Recast ch (the anchor's default 0.05)")
    ap.add_argument("--tol", type=float, default=0.03)
    ap.add_argument("--limit", type=int)
    ap.add_argument("--changed", action="store_true", help="list episodes whose live d0 differs from the file's")
    ap.add_argument("--json", type=Path, help="write every episode's row here")
    ap.add_argument("-v", "--verbose", action="store_true", help="print every episode")
    args = ap.parse_args(argv)
    if not (args.anchor / "detour.cjs").is_file():
        sys.exit(f"{args.anchor}/detour.cjs not found: pass --anchor DIR (or set NAVBENCH_DETOUR_ANCHOR)")
    if not (args.recast / "node_modules" / "@recast-navigation" / "core").is_dir():
        sys.exit(f"@recast-navigation is not installed under {args.recast}: see this script's docstring")
    files = [Path(p) for p in args.episodes] or [REPO / p for p in BUNDLED]
    every = []
    for f in files:
        rows = compare(f, args.scene_dir, args.anchor, args.recast, args)
        summarise(rows, args.tol, args.verbose, args.changed)
        every += rows
    if args.json:
        args.json.write_text(json.dumps(every, indent=1))


if __name__ == "__main__":
    main()
