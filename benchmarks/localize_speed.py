"""Localisation benchmark numbers: memory build time and storage per scene, SR@K and query latency.

Builds fresh memories of the GOAT-style split's scenes (into a temporary directory unless
``--memory-root`` is given, so build times are real), then runs the oracle benchmark in the four
settings of the report: noise none/default x fusion on/off.

    .venv/bin/python benchmarks/localize_speed.py [--split goat_val] [--k 5] [--out results/localize]

Wall-clock numbers on a shared machine vary from run to run, so the summary reports process CPU
time per query beside wall time.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from navbench.localize.benchmark import run_localize

SETTINGS = [("none", True), ("none", False), ("default", True), ("default", False)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--split", default="goat_val")
    ap.add_argument("--k", type=int, default=5)
    ap.add_argument("--limit", type=int, default=None)
    ap.add_argument("--memory-root", type=Path, default=None, help="reuse memories here (default: fresh temp dir)")
    ap.add_argument("--out", type=Path, default=None, help="write each setting's predictions and summaries here")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        root = args.memory_root or Path(tmp)
        rows = []
        for noise, fusion in SETTINGS:
            out = None if args.out is None else args.out / f"oracle-{noise}-{'fusion' if fusion else 'single'}"
            s = run_localize(args.split, "oracle", noise, fusion=fusion, k=args.k, out=out, limit=args.limit,
                             memory_root=root)
            rows.append(s)
            by = s["sr_by_type"]
            print(f"oracle/{noise:<7} fusion={'on ' if fusion else 'off'}  SR@{args.k} "
                  f"obj {by.get('object', 0):.3f} img {by.get('image', 0):.3f} lang {by.get('language', 0):.3f} "
                  f"avg {s['sr']:.3f}  query {s['query_ms']:.0f} ms wall / {s['query_cpu_ms']:.0f} ms cpu "
                  f"(p95 {s['query_ms_p95']:.0f} ms)", flush=True)
        first = rows[0]
        n = len(first["build_s_per_scene"])
        print(f"memory: {n} scenes built in {first['build_s']:.1f} s ({first['build_s'] / n:.2f} s/scene, max "
              f"{max(first['build_s_per_scene'].values()):.2f} s), {first['storage_bytes'] / 1e6:.2f} MB "
              f"({first['storage_bytes'] / n / 1e6:.2f} MB/scene, max "
              f"{max(first['storage_bytes_per_scene'].values()) / 1e6:.2f} MB)")
        if args.out is not None:
            args.out.mkdir(parents=True, exist_ok=True)
            (args.out / "speed.json").write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
