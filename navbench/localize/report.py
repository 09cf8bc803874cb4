"""Render localisation run summaries as the paper's Table 1 (SR@K by query type).

    python -m navbench.localize.report results/localize > results/localization_sr5.md
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pandas as pd


def table(root: Path) -> str:
    rows = []
    for summary in sorted(Path(root).glob("*/summary.json")):
        s = json.loads(summary.read_text())
        rows.append({"run": summary.parent.name, "perception": s["perception"], "noise": s["noise"],
                     "fusion": "yes" if s["fusion"] else "no (single view)",
                     **{t: 100 * s["sr_by_type"].get(t, float("nan")) for t in ("object", "image", "language")},
                     "avg": 100 * s["sr"], "query ms": s["query_ms"],
                     "memory MB (all scenes)": s["storage_bytes"] / 1e6,
                     "build s (all scenes)": s["build_s"]})
    if not rows:
        raise SystemExit(f"{root}: no */summary.json")
    k = json.loads(next(Path(root).glob("*/summary.json")).read_text())["k"]
    df = pd.DataFrame(rows).set_index("run")
    return f"SR@{k} (%), GOAT-style goat_val\n\n" + df.to_markdown(floatfmt=".1f") + "\n"


if __name__ == "__main__":
    print(table(Path(sys.argv[1] if len(sys.argv) > 1 else "results/localize")), end="")
