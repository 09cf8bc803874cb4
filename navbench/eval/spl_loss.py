"""Where a run loses SPL, episode by episode, from its ``episodes.jsonl`` (and the action/pose trace it records).

    python -m navbench.eval.spl_loss results/runs/pointnav/val/{oracle,optimistic,pointnav} [...] > results/spl_loss.md

SPL's shortfall ``1 - SPL`` splits exactly into what failed episodes lose (all of their weight) and what
successful ones lose to a path longer than the geodesic (``1 - geodesic / path``). Per run the table gives:

- ``lost: failures``: the share of episodes that failed, by kind: ``early stop`` (STOP called outside the success
  distance), ``timeout`` (no STOP before the step limit);
- ``lost: path``: successes' summed ``1 - SPL`` over all episodes, and the successes' path-length ratio
  (path / geodesic: median, 90th percentile);
- what the trace shows of driving: refused FORWARDs (``collisions``), turn reversals (a LEFT right after a RIGHT or
  the reverse: the agent hesitating), revisits (FORWARD steps ending within 0.15 m of a position held at least 4 steps
  earlier: back-and-forth), and turns per FORWARD; with the SPL lost on successes that collided or reversed.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

from navbench.eval.runner import read_records

FORWARD, LEFT, RIGHT = "1", "2", "3"
REVISIT_RADIUS = 0.15  # metres
REVISIT_GAP = 4  # steps


def reversals(actions: str) -> int:
    """Turns that undo the turn just before them (LEFT then RIGHT, or RIGHT then LEFT)."""
    return sum(1 for a, b in zip(actions, actions[1:]) if {a, b} == {LEFT, RIGHT})


def revisits(actions: str, poses: list[list[float]]) -> int:
    """FORWARD steps that end within ``REVISIT_RADIUS`` of where the agent stood ``REVISIT_GAP`` or more steps
    before (``poses[t]`` is the pose before action ``t``, ``poses[t + 1]`` after it)."""
    xz = np.asarray([p[:2] for p in poses], np.float64)
    count = 0
    for t, a in enumerate(actions):
        if a != FORWARD or t + 1 >= len(xz) or t + 1 - REVISIT_GAP < 0:
            continue
        d = np.hypot(*(xz[: t + 2 - REVISIT_GAP] - xz[t + 1]).T)
        count += bool((d < REVISIT_RADIUS).any())
    return count


def episode_measures(r: dict) -> dict:
    """One record's outcome, SPL shortfall and driving measures."""
    trace = r.get("trace") or {}
    actions = str(trace.get("actions", ""))
    poses = trace.get("poses") or []
    geo, path = float(r["geodesic_distance"]), float(r["path_length"])
    if r.get("success"):
        outcome = "success"
    elif r.get("stop_called"):
        outcome = "early stop"
    else:
        outcome = "timeout"
    forwards = actions.count(FORWARD)
    return {"outcome": outcome, "spl_loss": 1.0 - float(r["spl"]),
            "path_ratio": path / geo if geo > 0 else math.nan, "collisions": int(r.get("collisions", 0)),
            "reversals": reversals(actions), "revisits": revisits(actions, poses) if poses else 0,
            "turns_per_forward": (len(actions) - forwards - actions.count("0")) / max(1, forwards),
            "steps": int(r.get("num_steps", len(actions)))}


def run_summary(run_dir: Path) -> dict:
    recs = [r for r in read_records(Path(run_dir) / "episodes.jsonl") if not r.get("skipped")]
    if not recs:
        raise ValueError(f"{run_dir}: no episode records")
    summary = Path(run_dir) / "summary.json"
    agent = json.loads(summary.read_text()).get("agent", recs[0]["agent"]) if summary.is_file() else recs[0]["agent"]
    m = [episode_measures(r) for r in recs]
    n = len(m)
    ok = [e for e in m if e["outcome"] == "success"]
    ratios = np.array([e["path_ratio"] for e in ok]) if ok else np.array([math.nan])

    def share(pred) -> float:
        return 100 * sum(1 for e in m if pred(e)) / n

    def lost(pred) -> float:
        return 100 * sum(e["spl_loss"] for e in ok if pred(e)) / n

    return {"run": f"{agent} / {recs[0]['split']} ({Path(run_dir).name})", "episodes": n,
            "SR": 100 * len(ok) / n, "SPL": 100 * float(np.mean([1 - e["spl_loss"] for e in m])),
            "lost: early stop": share(lambda e: e["outcome"] == "early stop"),
            "lost: timeout": share(lambda e: e["outcome"] == "timeout"),
            "lost: path": lost(lambda e: True),
            "path ratio median": float(np.median(ratios)), "path ratio p90": float(np.percentile(ratios, 90)),
            "collisions / ep": float(np.mean([e["collisions"] for e in m])),
            "reversals / ep": float(np.mean([e["reversals"] for e in m])),
            "revisits / ep": float(np.mean([e["revisits"] for e in m])),
            "turns / forward": float(np.mean([e["turns_per_forward"] for e in m])),
            "path lost, successes that collided": lost(lambda e: e["collisions"] > 0),
            "path lost, successes that reversed": lost(lambda e: e["reversals"] > 0)}


def report(run_dirs: list[Path]) -> str:
    rows = [run_summary(d) for d in run_dirs]
    cols = list(rows[0])
    out = ["## Where SPL is lost (SPL points per 100 episodes; ratios are path / geodesic on successes)\n",
           "| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for r in rows:
        out.append("| " + " | ".join(v if isinstance(v, str) else (str(v) if isinstance(v, int) else f"{v:.2f}")
                                     for v in r.values()) + " |")
    out.append("")
    out.append("`SPL = 100 - lost: early stop - lost: timeout - lost: path` for every run (up to rounding).")
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if not args:
        print("usage: python -m navbench.eval.spl_loss RUN_DIR [RUN_DIR ...]", file=sys.stderr)
        return 2
    try:
        print(report([Path(a) for a in args]), end="")
    except (OSError, ValueError, KeyError) as exc:
        print(f"spl_loss: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
