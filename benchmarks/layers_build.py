"""LayeredNav on the scan-like fixture (navbench.bench.scan_fixture): build time and memory, and the disk cache.

    python benchmarks/layers_build.py --root /tmp/navbench-scan        # the fixture is made there if missing

Each figure is measured in a fresh process: ``build_s`` (LayeredNav.from_mesh; the mesh's ray intersector is
made before the clock starts), ``build_peak_mb`` (the process's peak RSS, scene loading included; the peak
before the build is ``load_peak_mb``), ``build_alloc_mb`` (the build's peak of Python-heap allocations, numpy's
arrays included, from tracemalloc in a run of its own), ``cold_s`` (``layers_for`` with an empty cache: build
and write), ``cached_s`` (``layers_for`` reading the file) and ``cache_file_mb``. Medians of ``--repeats`` runs.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

_CHILD = r"""
import json, resource, sys, time, tracemalloc
from navbench.scene.asset import load_scene
from navbench.scene.cache import layers_for
from navbench.scene.layers import LayeredNav
mode, path = sys.argv[1], sys.argv[2]
asset = load_scene(path)
asset.mesh.ray.intersects_any([[0.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
if mode == "alloc":
    tracemalloc.start()
t = time.perf_counter()
LayeredNav.from_mesh(asset.mesh) if mode in ("build", "alloc") else layers_for(asset)
dt = time.perf_counter() - t
alloc = tracemalloc.get_traced_memory()[1] / 1e6 if mode == "alloc" else 0.0
print(json.dumps({"s": dt, "load_mb": rss0, "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "alloc_mb": alloc}))
"""


def _child(mode: str, scene: Path, cache: str) -> dict:
    env = dict(os.environ, NAVBENCH_CACHE=cache)
    out = subprocess.run([sys.executable, "-c", _CHILD, mode, str(scene)], env=env, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main() -> None:
    from navbench.bench.scan_fixture import SCENE_DIR_NAME, SCENE_NAME, SPLIT, make_scan_fixture

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", required=True)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    root = Path(args.root)
    scene = root / "scene_datasets" / "hm3d" / SPLIT / SCENE_DIR_NAME / f"{SCENE_NAME}.glb"
    if not scene.is_file():
        make_scan_fixture(root, texture_size=1024, basis=False)
    builds, peaks, loads, colds, cacheds, size = [], [], [], [], [], 0.0
    for _ in range(args.repeats):
        b = _child("build", scene, tempfile.mkdtemp())
        builds.append(b["s"])
        peaks.append(b["peak_mb"])
        loads.append(b["load_mb"])
        with tempfile.TemporaryDirectory() as cache:
            colds.append(_child("layers_for", scene, cache)["s"])
            cacheds.append(_child("layers_for", scene, cache)["s"])
            size = sum(f.stat().st_size for f in Path(cache, "layers").glob("*.npz")) / 1e6
    alloc = _child("alloc", scene, tempfile.mkdtemp())["alloc_mb"]
    med = statistics.median
    print(json.dumps({"scene": str(scene), "build_s": round(med(builds), 2), "build_peak_mb": round(med(peaks)),
                      "load_peak_mb": round(med(loads)), "build_alloc_mb": round(alloc),
                      "cold_s": round(med(colds), 2), "cached_s": round(med(cacheds), 3),
                      "cache_file_mb": round(size, 1), "load_avg_1min": round(os.getloadavg()[0], 2)}))


if __name__ == "__main__":
    main()
