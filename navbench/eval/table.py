"""Result tables as navigation papers print them: one row per agent, SR and SPL in percent.

    navbench table runs/oracle_val_seen runs/oracle_val_unseen --format markdown|csv|latex
    navbench table runs/frontier_val_unseen runs/memory_val_unseen --first 20   # on the same 20 episodes
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pandas as pd

FORMATS = ("markdown", "csv", "latex")


class TableError(ValueError):
    pass


def load_summary(run_dir: str | Path) -> dict[str, Any]:
    path = Path(run_dir) / "summary.json"
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise TableError(f"{path}: no summary.json (is this a navbench run directory?)") from None
    except json.JSONDecodeError as exc:
        raise TableError(f"{path}: corrupt summary ({exc})") from None


def first_records(run_dir: str | Path, first: int) -> list[dict[str, Any]]:
    """The run's records of the first ``first`` episodes of its dataset file (file order); a run
    lacking any of them is an error."""
    from navbench.episodes.io import load_dataset
    from navbench.eval.runner import read_records
    from navbench.paths import split_file

    run_dir = Path(run_dir)
    cfg = json.loads((run_dir / "config.json").read_text())
    # a bundled split is read where this checkout keeps it (config.json holds the writer's path)
    bundled = split_file(cfg["task"], cfg["split"]) if cfg.get("split") else None
    episodes = bundled if bundled is not None and bundled.is_file() else Path(cfg["episodes"])
    keep = {(e.scene_id, e.episode_id) for e in load_dataset(episodes).episodes[:first]}
    recs = [r for r in read_records(run_dir / "episodes.jsonl") if (r["scene_id"], r["episode_id"]) in keep]
    if len(recs) < len(keep):
        raise TableError(f"{run_dir}: has {len(recs)} of the first {first} episodes of {episodes.name}")
    return recs


def first_summary(run_dir: str | Path, first: int) -> dict[str, Any]:
    """The run's summary recomputed on :func:`first_records`, so runs of different lengths can be
    compared on the same episodes."""
    from navbench.metrics import aggregate

    summary = load_summary(run_dir)
    by = "object_category" if summary.get("task") == "objectnav" else None
    return {**summary, **aggregate(first_records(run_dir, first), by=by)}


def summary_row(s: dict[str, Any]) -> dict[str, Any]:
    return {
        "agent": s.get("agent"), "task": s.get("task"), "split": s.get("split") or "custom",
        "episodes": s.get("num_episodes"),
        "SR": 100 * s["success"], "SPL": 100 * s["spl"], "SoftSPL": 100 * s["soft_spl"],
        "DTG": s["distance_to_goal"],
    }


def runs_frame(run_dirs: list[str | Path], wide: bool = True, first: int | None = None) -> pd.DataFrame:
    """Long form (one row per run) or wide form (rows = agent, columns = (split, SR/SPL)); with
    ``first``, every run is scored on the first ``first`` episodes of its split only."""
    df = pd.DataFrame([summary_row(load_summary(d) if first is None else first_summary(d, first))
                       for d in run_dirs])
    if not wide or df["split"].nunique() <= 1:
        return df
    wide_df = df.pivot_table(index="agent", columns="split", values=["SR", "SPL"], aggfunc="first", sort=False)
    wide_df = wide_df.swaplevel(0, 1, axis=1)
    splits = list(dict.fromkeys(df["split"]))
    return wide_df.reindex(columns=[(sp, m) for sp in splits for m in ("SR", "SPL")])


def render(df: pd.DataFrame, fmt: str = "markdown") -> str:
    if fmt == "markdown":
        if isinstance(df.columns, pd.MultiIndex):
            df = df.copy()
            df.columns = [f"{a} {b}" for a, b in df.columns]
        return df.to_markdown(floatfmt=".1f")
    if fmt == "csv":
        return df.to_csv(float_format="%.2f")
    if fmt == "latex":
        return df.style.format(precision=1).to_latex(hrules=True)
    raise TableError(f"unknown format {fmt!r}: choose from {', '.join(FORMATS)}")


def summary_markdown(summary: dict[str, Any]) -> str:
    """The table ``navbench run`` prints: the overall row, then per-category rows for ObjectNav."""
    rows = [dict(summary_row(summary), category="all")]
    for cat, m in (summary.get("by_object_category") or {}).items():
        rows.append({"agent": summary.get("agent"), "task": summary.get("task"), "split": summary.get("split"),
                     "episodes": m["num_episodes"], "SR": 100 * m["success"], "SPL": 100 * m["spl"],
                     "SoftSPL": 100 * m["soft_spl"], "DTG": m["distance_to_goal"], "category": cat})
    df = pd.DataFrame(rows).set_index("category")[["agent", "split", "episodes", "SR", "SPL", "SoftSPL", "DTG"]]
    return df.to_markdown(floatfmt=".1f")
