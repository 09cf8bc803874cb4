"""navbench's renderer against the render anchor (the plain pyrender path), same scenes, poses and session.

The anchor (``benchmarks/anchor_scenes.py``: the scenes and poses; ``benchmarks/anchor_pyrender.py``:
the plain path) renders ``scene_simple.glb`` (1.2k triangles) and ``scene_dense.glb`` (205k) at
224x224, HFOV 79 deg, from 300 fixed camera-to-world poses, with pyrender's FLAT RGB-D (``rgbd``) or
DEPTH_ONLY (``depth``) pass on one merged node. This script renders the same GLBs the way the env does
(``load_scene`` -> ``Renderer(asset, CameraConfig())`` -> ``render(position, quaternion, rgb=...,
depth=True)``, the quaternions taken from ``anchor_scenes.mats()``), and alternates the two engines,
each in a fresh subprocess under the same ``LP_NUM_THREADS``, for ``--rounds`` rounds of ``--reps``
passes over the 300 poses (after a warm-up: 30 frames for the anchor, one pass for navbench, see
``_navbench_worker``).
It prints one JSON line per run and, per scene and mode, both engines' median frames/s, median CPU
ms per frame (``time.process_time``: every thread of the process, so it is what a frame costs the
machine, and less noisy than wall time on a shared one) and the ratios navbench / anchor.

    PYTHONPATH=$PWD python benchmarks/render_anchor.py                       # both scenes, both modes
    PYTHONPATH=$PWD python benchmarks/render_anchor.py --scenes dense --modes depth --rounds 5
    PYTHONPATH=$PWD python benchmarks/render_anchor.py --lp 0                # LP_NUM_THREADS=0 for both
    git archive REV navbench | tar -x -C /tmp/nb-before                      # (mkdir it first) and
    PYTHONPATH=$PWD python benchmarks/render_anchor.py --baseline /tmp/nb-before   # before vs after too

``--scene-dir DIR`` (or ``SBS_DIR``) holds the GLBs, written there first when missing (default: a
``navbench-render-anchor`` folder in the system's temporary directory). ``--lp`` sets
``LP_NUM_THREADS`` for both engines (``unset``: neither process has it set, so each uses what it
would by default; navbench's renderer then decides for itself). Each worker reports the value Mesa saw.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics as st
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import anchor_scenes

REPO = Path(__file__).resolve().parents[1]
HERE = Path(__file__).resolve().parent
DEFAULT_SCENE_DIR = Path(tempfile.gettempdir()) / "navbench-render-anchor"
W = H = 224
HFOV_DEG = 79.0


def _navbench_worker(scene_dir: Path, scene: str, mode: str, reps: int) -> dict:
    """Render the anchor's poses through navbench's scene loading and renderer; the anchor's JSON fields."""
    from scipy.spatial.transform import Rotation

    from navbench.render.camera import CameraConfig
    from navbench.render.renderer import Renderer
    from navbench.scene.asset import load_scene

    cams = [(m[:3, 3].copy(), Rotation.from_matrix(m[:3, :3]).as_quat()) for m in anchor_scenes.mats()]
    asset = load_scene(anchor_scenes.scene_path(scene_dir, scene))
    rgb = mode == "rgbd"
    r = Renderer(asset, CameraConfig(width=W, height=H, hfov_deg=HFOV_DEG))
    # Warm-up: the anchor renders 30 poses; here one pass over all 300, because on scenes of 200k+
    # triangles (the dense one) the renderer casts rays the first time the camera enters a 0.5 m
    # cell (occlusion culling's visibility sets, cached for the renderer's life), a one-off cost
    # per cell like scene loading, not a per-frame one.
    for p, q in cams:
        r.render(p, q, rgb=rgb, depth=True)
    fps, cpu, t0s, t1s = [], [], [], []
    for _ in range(reps):
        a, c = time.time(), time.process_time()
        for p, q in cams:
            r.render(p, q, rgb=rgb, depth=True)
        b = time.time()
        fps.append(len(cams) / (b - a))
        cpu.append(1e3 * (time.process_time() - c) / len(cams))
        t0s.append(a)
        t1s.append(b)
    out = dict(engine="navbench", scene=scene, mode=mode, LP=os.environ.get("LP_NUM_THREADS", "dflt"),
               fps_med=st.median(fps), fps=[round(x, 1) for x in fps], cpu_ms_per_frame=round(st.median(cpu), 2),
               t_start=t0s[0], t_end=t1s[-1], frames=len(cams) * reps, chunks=r.num_chunks)
    r.close()
    return out


def _run(cmd: list[str], env: dict, cwd: Path) -> dict:
    res = subprocess.run(cmd, env=env, cwd=cwd, capture_output=True, text=True)
    if res.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({res.returncode}):\n{res.stderr[-2000:]}")
    return json.loads(res.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene-dir", default=os.environ.get("SBS_DIR", str(DEFAULT_SCENE_DIR)),
                    help="where the anchor's GLBs are (written there first when missing)")
    ap.add_argument("--scenes", default="simple,dense")
    ap.add_argument("--modes", default="rgbd,depth")
    ap.add_argument("--rounds", type=int, default=3, help="alternations of the two engines")
    ap.add_argument("--reps", type=int, default=3, help="passes over the 300 poses per run")
    ap.add_argument("--lp", default="unset", help="LP_NUM_THREADS for both engines, or 'unset'")
    ap.add_argument("--baseline", help="another navbench checkout (e.g. an older commit, `git archive`d) "
                    "to run as a third engine, alternated with the other two")
    ap.add_argument("--worker", nargs=3, metavar=("SCENE", "MODE", "REPS"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    sbs = Path(args.scene_dir).resolve()
    if args.worker:
        scene, mode, reps = args.worker
        print(json.dumps(_navbench_worker(sbs, scene, mode, int(reps))), flush=True)
        return {}
    anchor_scenes.write_scenes(sbs, args.scenes.split(","))
    env = dict(os.environ, PYOPENGL_PLATFORM="osmesa", SBS_DIR=str(sbs))
    env.pop("LP_NUM_THREADS", None)
    if args.lp != "unset":
        env["LP_NUM_THREADS"] = args.lp
    env["PYTHONPATH"] = os.pathsep.join([str(REPO)] + [p for p in [os.environ.get("PYTHONPATH")] if p])
    summary: dict = {}
    for scene in args.scenes.split(","):
        for mode in args.modes.split(","):
            runs: dict[str, list[dict]] = {"pyrender": [], "navbench": []}
            if args.baseline:
                runs["baseline"] = []
            for k in range(args.rounds):
                order = list(runs) if k % 2 == 0 else list(runs)[::-1]
                for engine in order:
                    cmd = ([sys.executable, str(HERE / "anchor_pyrender.py"), scene, mode, str(args.reps)]
                           if engine == "pyrender" else
                           [sys.executable, __file__, "--scene-dir", str(sbs), "--worker", scene, mode, str(args.reps)])
                    run_env = env if engine != "baseline" else dict(env, PYTHONPATH=str(Path(args.baseline).resolve()))
                    out = _run(cmd, run_env, REPO)
                    out["engine"] = engine
                    runs[engine].append(out)
                    fields = ("engine", "scene", "mode", "LP", "fps", "cpu_ms_per_frame")
                    print(json.dumps({k2: out[k2] for k2 in fields}), flush=True)
            med = {e: dict(fps=st.median(x for r in rs for x in r["fps"]),
                           cpu_ms=st.median(r["cpu_ms_per_frame"] for r in rs)) for e, rs in runs.items()}
            row = dict(scene=scene, mode=mode, lp=args.lp,
                       anchor_fps=round(med["pyrender"]["fps"], 1), navbench_fps=round(med["navbench"]["fps"], 1),
                       anchor_cpu_ms=med["pyrender"]["cpu_ms"], navbench_cpu_ms=med["navbench"]["cpu_ms"],
                       ratio_fps=round(med["navbench"]["fps"] / med["pyrender"]["fps"], 2),
                       ratio_cpu=round(med["pyrender"]["cpu_ms"] / med["navbench"]["cpu_ms"], 2))
            if args.baseline:
                row.update(baseline_fps=round(med["baseline"]["fps"], 1), baseline_cpu_ms=med["baseline"]["cpu_ms"],
                           baseline_ratio_fps=round(med["baseline"]["fps"] / med["pyrender"]["fps"], 2),
                           baseline_ratio_cpu=round(med["pyrender"]["cpu_ms"] / med["baseline"]["cpu_ms"], 2))
            summary[f"{scene}/{mode}"] = row
            print("SUMMARY " + json.dumps(row), flush=True)
    return summary


if __name__ == "__main__":
    main()
