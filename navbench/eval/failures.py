"""Per-category SR/SPL (with 95% intervals, :mod:`navbench.eval.stats`) and a failure breakdown of ObjectNav
runs, from their ``episodes.jsonl``.

    python -m navbench.eval.failures results/runs/objectnav/val_unseen/memory [...] > results/objectnav_failures.md

A failed episode is classified from its record (and the agent's decision log when it has one):
- ``wrong instance``: STOP called more than 2 m (geodesic) from every goal view point, i.e. the agent
  stopped at something else;
- ``stopped early``: STOP called within 2 m of a goal but outside the success distance;
- ``stuck``: no STOP before the step limit and the agent's log reports being stuck or oscillating;
- ``timeout``: no STOP before the step limit otherwise.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pandas as pd

from navbench.eval.runner import read_records
from navbench.eval.stats import intervals

WRONG_INSTANCE_DISTANCE = 2.0


def failure_kind(r: dict) -> str | None:
    if r.get("skipped") or r.get("success"):
        return None
    if r.get("stop_called"):
        return "wrong instance" if r["distance_to_goal"] > WRONG_INSTANCE_DISTANCE else "stopped early"
    events = {e.get("event") for e in (r.get("log") or {}).get("events", [])}
    return "stuck" if events & {"stuck", "oscillating"} else "timeout"


def _cell(mean: float, ci: list[float]) -> str:
    return f"{100 * mean:.1f} [{100 * ci[0]:.1f}, {100 * ci[1]:.1f}]"


def breakdown(run_dirs: list[Path]) -> str:
    rows, fails = [], []
    for d in run_dirs:
        recs = [r for r in read_records(Path(d) / "episodes.jsonl") if not r.get("skipped")]
        if not recs:
            continue
        df = pd.DataFrame(recs)
        summary = Path(d) / "summary.json"  # its agent is the run's label (e.g. memory-norerank)
        agent = json.loads(summary.read_text())["agent"] if summary.is_file() else recs[0]["agent"]
        name = f"{agent} / {recs[0]['split']}"
        for cat, group in df.groupby("object_category"):
            ci = intervals(group.to_dict("records"))
            rows.append({"run": name, "object_category": cat, "episodes": len(group),
                         **{k: _cell(group[m].mean(), ci[m]) for k, m in (("SR", "success"), ("SPL", "spl"))}})
        kinds = pd.Series([failure_kind(r) for r in recs]).value_counts()
        fails.append({"run": name, "episodes": len(recs), **{k: int(kinds.get(k, 0)) for k in
                      ("wrong instance", "stopped early", "stuck", "timeout")}})
    out = ["## Failure breakdown (episodes)\n", pd.DataFrame(fails).set_index("run").to_markdown(), "",
           "## Per-category SR / SPL (%) [95% interval]\n",
           pd.DataFrame(rows).to_markdown(index=False), ""]
    return "\n".join(out)


if __name__ == "__main__":
    print(breakdown([Path(p) for p in sys.argv[1:]]))
