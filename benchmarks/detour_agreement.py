"""navbench's geodesic start distance (d0) against Detour's, the path query habitat-sim measures with.

The anchor (``shared/detour-anchor``: ``detour.cjs``) builds a Recast navmesh with habitat-sim's navmesh
settings for navbench's agent (radius 0.18 m, height 0.88 m, max climb 0.2 m, max slope 45 deg) from the
same mesh navbench reads, and returns Detour's shortest 3D path from each episode's start to the nearest
goal (ObjectNav: every view point). navbench's d0 is the env's own at reset (``PointNavEnv`` /
``ObjectNavEnv`` without sensors: the grid of the start's storey, or the joined surfaces of every storey when
a goal is on another one), so the script measures what the checkout builds, not the d0 stored in the
episode file; ``--changed`` also lists the episodes whose live d0 differs from the file's
``info.geodesic_distance``, and an episode the env refuses (a start off the navigable area) is listed.
``--storeys DIR`` writes the two-storey houses of the tests (joined by stairs, by a ramp, and by nothing)
with cross-storey PointNav and ObjectNav episodes, and the buildings of touching boxes (walls on slabs,
walled and open stairs, ramps of 10-30 deg) with theirs, into DIR and measures those too. ``--gaps`` holds the
reachability verdict through one gap in a wall (0.38-0.60 m wide, at four sub-cell alignments) against
Detour's: the narrowest passage each admits.

    npm install --prefix ~/.cache/recast @recast-navigation/core@0.43.1 @recast-navigation/generators@0.43.1
    PYTHONPATH=$PWD python benchmarks/detour_agreement.py                  # bundled val + val_unseen
    PYTHONPATH=$PWD python benchmarks/detour_agreement.py episodes/pointnav/val/val.json.gz -v
    PYTHONPATH=$PWD python benchmarks/detour_agreement.py --changed --json /tmp/agreement.json
    PYTHONPATH=$PWD python benchmarks/detour_agreement.py --storeys /tmp/storeys

Per split it prints the share of episodes whose d0 agrees within ``--tol`` (3%), every episode outside
it (worst first) and every reachability disagreement (one finite, the other not). ``--anchor DIR``
(or ``NAVBENCH_DETOUR_ANCHOR``) names the anchor directory (default ``../shared/detour-anchor`` beside
the repository), ``--recast`` the npm prefix holding ``@recast-navigation``. Where the two
differ by more than 3% navbench is shorter, for two reasons (results/detour_agreement.md): Recast
rounds the agent radius up to whole voxels, so the navmesh's edge sits ~0.22 m from walls where the
grid's sits at 0.18 m (each corner costs Detour a few cm more), and Detour's search over large navmesh
polygons can pick a route up to ~9% longer than the shortest one on its own navmesh.
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


def navbench_d0(env, index: int) -> float | str:
    """d0 as ``NavEnv.reset`` measures it; the env's refusal message if it refuses the episode."""
    from navbench.episodes.types import EpisodeError

    try:
        _, info = env.reset(options={"episode": index})
    except EpisodeError as exc:
        return str(exc)
    return float(info["distance_to_goal"])


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
    from navbench.env.config import EnvConfig
    from navbench.env.objectnav import ObjectNavEnv
    from navbench.env.pointnav import PointNavEnv
    from navbench.episodes.io import load_dataset
    from navbench.scene.asset import load_scene

    dataset = load_dataset(path)
    env_cls = ObjectNavEnv if dataset.task == "objectnav" else PointNavEnv
    env = env_cls(dataset, scene_dir=scene_dir, config=EnvConfig(rgb=False, depth=False))
    by_scene: dict[str, list] = {}
    for i, ep in enumerate(dataset.episodes[: args.limit]):
        by_scene.setdefault(ep.scene_id, []).append((i, ep))
    rows = []
    for scene_id, eps in sorted(by_scene.items()):
        mesh = load_scene(resolve_scene_path(scene_id, scene_dir)).mesh
        queries = [{"id": e.episode_id, "start": [float(v) for v in e.start_position],
                    "goals": e.goal_positions().tolist()} for _, e in eps]
        detour = {q["id"]: q["d"] for q in detour_d0(anchor, recast, mesh, queries, args.cell_size, args.cell_height)}
        for i, e in eps:
            d_nav = navbench_d0(env, i)
            refused = d_nav if isinstance(d_nav, str) else None
            d_nav = None if refused or not math.isfinite(d_nav) else d_nav
            rows.append({"split": str(path), "scene_id": scene_id, "episode_id": e.episode_id, "navbench": d_nav,
                         "detour": detour[e.episode_id], "file": e.info.get("geodesic_distance"),
                         "refused": refused})
    env.close()
    return rows


def summarise(rows: list[dict], tol: float, verbose: bool, changed: bool) -> None:
    agree, outside, reach = 0, [], []
    for r in rows:
        if r.get("refused"):
            print(f"  refused: {r['refused']}")
        n, d = r["navbench"], r["detour"]
        if n is None or d is None:
            if (n is None) != (d is None):
                reach.append(r)
            else:
                agree += 1  # both unreachable: the same verdict
                if verbose:
                    print(f"  {r['scene_id']} ep {r['episode_id']}: unreachable for both")
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
        moved = [r for r in rows if r["file"] is not None and not r.get("refused") and
                 (r["navbench"] is None or abs(r["navbench"] - r["file"]) > 1e-5 * max(1.0, r["file"]))]
        print(f"  live d0 differs from the file's on {len(moved)}/{len(rows)} episodes")
        for r in moved:
            print(f"    changed: {r['scene_id']} ep {r['episode_id']}: file {r['file']}  live {r['navbench']}")


def write_storeys(out: Path) -> list[Path]:
    """The tests' two-storey houses (``tests/scene/storeys.py``) as GLBs, with PointNav episodes between the
    storeys and ObjectNav episodes whose category has an instance on each storey."""
    sys.path.insert(0, str(REPO / "tests" / "scene"))
    from storeys import UPPER, house

    out.mkdir(parents=True, exist_ok=True)
    pairs = [([1.0, 0.0, 2.6], [9.0, UPPER, 2.6]), ([1.0, 0.0, 1.0], [8.5, UPPER, 5.0]),
             ([9.0, UPPER, 1.0], [1.0, 0.0, 5.0]), ([0.5, 0.0, 5.5], [9.5, UPPER, 0.5]),
             ([2.0, 0.0, 4.2], [9.0, UPPER, 2.6]), ([8.0, 0.0, 1.0], [1.5, UPPER, 4.5])]
    point, objects = [], []
    for join in ("stairs", "ramp", "none"):
        house(None if join == "none" else join).export(out / f"{join}.glb")
        for k, (a, b) in enumerate(pairs):
            point.append({"episode_id": f"{join}-{k}", "scene_id": f"{join}.glb", "start_position": a,
                          "start_rotation": [0.0, 0.0, 0.0, 1.0], "goals": [{"position": b, "radius": None}],
                          "info": {}})
            # A category on both storeys: a view point 0.6 m above/below the start in xz, and b.
            other = [a[0] + 0.6, UPPER if a[1] == 0.0 else 0.0, a[2]]
            goals = [{"object_id": j, "object_category": "chair", "position": [p[0], p[1] + 0.5, p[2]],
                      "view_points": [{"agent_state": {"position": p, "rotation": [0.0, 0.0, 0.0, 1.0]}, "iou": 1.0}]}
                     for j, p in enumerate((other, b))]
            objects.append({"episode_id": f"{join}-{k}", "scene_id": f"{join}.glb", "start_position": a,
                            "start_rotation": [0.0, 0.0, 0.0, 1.0], "object_category": "chair", "goals": goals,
                            "info": {}})
    files = [out / "pointnav.json", out / "objectnav.json", out / "buildings.json"]
    files[0].write_text(json.dumps({"episodes": point}))
    files[1].write_text(json.dumps({"episodes": objects}))
    files[2].write_text(json.dumps({"episodes": building_episodes(out)}))
    return files


def building_episodes(out: Path) -> list[dict]:
    """The touching-box buildings of the tests (``tests/scene/storeys.py``: walled and open stairs, ramps of
    10, 20 and 30 deg) as GLBs in ``out``, with their cross-storey PointNav episodes."""
    sys.path.insert(0, str(REPO / "tests" / "scene"))
    from storeys import BUILDINGS, building, building_name, building_pairs

    eps = []
    for join, angle, walled in BUILDINGS:
        name = building_name(join, angle, walled)
        building(join, angle, walled).export(out / f"{name}.glb")
        eps += [{"episode_id": f"{name}-{k}", "scene_id": f"{name}.glb", "start_position": a,
                 "start_rotation": [0.0, 0.0, 0.0, 1.0], "goals": [{"position": b, "radius": None}], "info": {}}
                for k, (a, b) in enumerate(building_pairs(join, angle))]
    return eps


def gaps(anchor: Path, recast: Path) -> None:
    """A wall across a 6 x 6 m room with one gap: is the far side reachable, for navbench and for Detour?"""
    import trimesh

    from navbench.scene.navigability import NavGrid

    def box(lo, hi):
        b = trimesh.creation.box(np.subtract(hi, lo))
        b.apply_translation(np.add(lo, hi) / 2)
        return b

    agree = total = 0
    print("gap (m)  offset (m)  navbench  detour")
    for off in (0.0, 0.013, 0.025, 0.037):
        for gap in (0.38, 0.42, 0.44, 0.46, 0.48, 0.50, 0.52, 0.56, 0.60):
            x, z = 3.0 + off, 2.8 + off
            mesh = trimesh.util.concatenate([box((0, -0.1, 0), (6, 0, 6)), box((x - 0.05, 0, 0), (x + 0.05, 2.5, z)),
                                             box((x - 0.05, 0, z + gap), (x + 0.05, 2.5, 6))])
            a, b = [1.5, 0.0, 1.5], [4.5, 0.0, 1.5]
            d_nav = NavGrid.from_mesh(mesh).geodesic_distance(a, b)
            d_det = detour_d0(anchor, recast, mesh, [{"id": "0", "start": a, "goals": [b]}], 0.05, 0.05)[0]["d"]
            same = math.isfinite(d_nav) == (d_det is not None)
            agree, total = agree + same, total + 1
            print(f"{gap:7.2f}  {off:10.3f}  {d_nav:8.3f}  {d_det if d_det is None else round(d_det, 3)}"
                  + ("" if same else "  (verdicts differ)"))
    print(f"same reachability verdict on {agree}/{total} gaps")


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
    ap.add_argument("--storeys", type=Path, help="write the two-storey fixtures here and measure them too")
    ap.add_argument("--gaps", action="store_true", help="only the gap-width table (see above)")
    ap.add_argument("-v", "--verbose", action="store_true", help="print every episode")
    args = ap.parse_args(argv)
    if not (args.anchor / "detour.cjs").is_file():
        sys.exit(f"{args.anchor}/detour.cjs not found: pass --anchor DIR (or set NAVBENCH_DETOUR_ANCHOR)")
    if not (args.recast / "node_modules" / "@recast-navigation" / "core").is_dir():
        sys.exit(f"@recast-navigation is not installed under {args.recast}: see this script's docstring")
    if args.gaps:
        gaps(args.anchor, args.recast)
        return
    files = [(Path(p), args.scene_dir) for p in args.episodes] or \
        ([] if args.storeys else [(REPO / p, args.scene_dir) for p in BUNDLED])
    if args.storeys:
        files += [(f, args.storeys) for f in write_storeys(args.storeys)]
    every = []
    for f, scene_dir in files:
        rows = compare(f, scene_dir, args.anchor, args.recast, args)
        summarise(rows, args.tol, args.verbose, args.changed)
        every += rows
    if args.json:
        args.json.write_text(json.dumps(every, indent=1))


if __name__ == "__main__":
    main()
