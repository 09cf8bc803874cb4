"""Write the scan-like HM3D fixture (navbench.bench.scan_fixture) and print its paths and build time.

    python benchmarks/scan_fixture.py --out /tmp/navbench-scan                  # ~800k triangles, 4096^2 atlas
    python benchmarks/scan_fixture.py --out /tmp/scan-small --faces 60000 --texture 1024 --no-basis

Then ``navbench bench --scan /tmp/navbench-scan`` measures load, grid, rendering and memory build on it,
and ``navbench run --episodes /tmp/navbench-scan/objectnav_hm3d_v1/val/val.json.gz
--scene-dir /tmp/navbench-scan/scene_datasets --agent oracle`` runs its episodes.
"""

from __future__ import annotations

import argparse
import json
import time

from navbench.bench.scan_fixture import make_scan_fixture


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--faces", type=int, default=800_000)
    ap.add_argument("--texture", type=int, default=4096)
    ap.add_argument("--episodes", type=int, default=12)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-basis", action="store_true", help="skip the KTX2 (Basis Universal) copy of the scene")
    args = ap.parse_args()
    t0 = time.perf_counter()
    fx = make_scan_fixture(args.out, faces=args.faces, texture_size=args.texture, seed=args.seed,
                           basis=not args.no_basis, episodes=args.episodes)
    print(json.dumps({"root": str(fx.root), "scene_id": fx.scene_id, "episodes": str(fx.episodes), "faces": fx.faces,
                      "texture": fx.texture_size, "build_s": round(time.perf_counter() - t0, 1)}))


if __name__ == "__main__":
    main()
