"""The memory/efficiency table (the paper's Table 4): what each keyframe setting stores and costs, and
the SR/SPL the memory agent reaches with it, from memory-agent run directories.

    python -m navbench.eval.memory_table [--first N] results/runs/objectnav/val_unseen/memory \
        results/runs/objectnav/val_unseen/memory-allframes ...

Per run: the stored frames and bytes, the build time (pre-scan + keyframes + index, as measured when
the scene's memory was built) averaged over the run's scenes, the mean localisation query latency,
and SR/SPL. ``--first N`` scores every run on the first N episodes of its dataset file (what
``navbench run --limit N`` runs), so runs made with different limits compare on the same episodes.
Storage and build time come from the memory's own stats, so a cached memory reports the build it was
made by.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pandas as pd

from navbench.eval.runner import read_records
from navbench.eval.table import first_records, first_summary


def memory_row(run_dir: str | Path, first: int | None = None) -> dict:
    run_dir = Path(run_dir)
    cfg = json.loads((run_dir / "config.json").read_text())
    if first is None:
        summary, recs = json.loads((run_dir / "summary.json").read_text()), read_records(run_dir / "episodes.jsonl")
    else:
        summary, recs = first_summary(run_dir, first), first_records(run_dir, first)
    recs = [r for r in recs if not r.get("skipped")]
    logs = pd.DataFrame([{"scene": r["scene_id"], **(r.get("log") or {})} for r in recs])
    missing = {"memory_keyframes", "memory_frames", "memory_bytes", "query_ms"} - set(logs.columns)
    if missing:
        raise ValueError(f"{run_dir}: records lack {sorted(missing)} (not a memory-agent run?)")
    per_scene = logs.groupby("scene").first()
    opts = cfg.get("agent_options", {})
    return {
        "run": summary.get("agent"), "split": summary.get("split"), "episodes": summary["num_episodes"],
        "frames": "all frames" if opts.get("all_frames") else "keyframes",
        "resolution": opts.get("keyframe_res", "full"),
        "pre-scan frames / scene": per_scene["memory_frames"].mean(),
        "stored frames / scene": per_scene["memory_keyframes"].mean(),
        "storage MB / scene": per_scene["memory_bytes"].mean() / 1e6,
        "build s / scene": per_scene["memory_build_s"].mean() if "memory_build_s" in per_scene else float("nan"),
        "query ms": logs["query_ms"].mean(),
        "SR": 100 * summary["success"], "SPL": 100 * summary["spl"],
    }


def memory_table(run_dirs: list[str | Path], first: int | None = None) -> str:
    return pd.DataFrame([memory_row(d, first) for d in run_dirs]).set_index("run").to_markdown(floatfmt=".1f")


if __name__ == "__main__":
    args = sys.argv[1:]
    n = None
    if args[:1] == ["--first"]:
        n, args = int(args[1]), args[2:]
    print(memory_table(args, n))
