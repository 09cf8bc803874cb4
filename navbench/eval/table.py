"""Result tables as navigation papers print them: one row per agent, SR and SPL in percent.

    navbench table runs/objectnav/val_seen/oracle runs/objectnav/val_unseen/oracle --format markdown|csv|latex
    navbench table runs/objectnav/val_unseen/frontier runs/objectnav/val_unseen/memory --first 20  # same 20 episodes

Every row carries the run's identity from its ``config.json``: the checkpoint and decoding of agents
that drive with the PointNav policy, the seed, and the perception of agents that localise objects
("-" where a column does not apply to the agent).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pandas as pd

FORMATS = ("markdown", "csv", "latex")


class TableError(ValueError):
    pass


METRICS = ("success", "spl", "soft_spl", "distance_to_goal")


def _read_object(path: Path, what: str) -> dict[str, Any]:
    """A JSON object from ``path``, or a one-line TableError naming it."""
    try:
        doc = json.loads(path.read_bytes())
    except FileNotFoundError:
        raise TableError(f"{path}: no {path.name} (is this a navbench run directory?)") from None
    except (OSError, ValueError, RecursionError) as exc:  # JSONDecodeError and UnicodeDecodeError are ValueErrors
        raise TableError(f"{path}: corrupt {what} ({type(exc).__name__}: {exc})") from None
    if not isinstance(doc, dict):
        raise TableError(f"{path}: corrupt {what} (not a JSON object)")
    return doc


def load_summary(run_dir: str | Path) -> dict[str, Any]:
    path = Path(run_dir) / "summary.json"
    s = _read_object(path, "summary")
    for k in METRICS:
        v = s.get(k)
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise TableError(f"{path}: corrupt summary ({k!r} must be a number, got {v!r})"[:300])
    for k in ("agent", "task", "split"):
        if s.get(k) is not None and not isinstance(s[k], str):
            raise TableError(f"{path}: corrupt summary ({k!r} must be a string, got {s[k]!r})"[:300])
    return s


def load_config(run_dir: str | Path) -> dict[str, Any]:
    """A run's config.json, with the fields the table reads checked for type."""
    path = Path(run_dir) / "config.json"
    cfg = _read_object(path, "config")
    problem = None
    for k in ("agent", "task", "split", "episodes"):
        if cfg.get(k) is not None and not isinstance(cfg[k], str):
            problem = f"{k!r} must be a string, got {cfg[k]!r}"
    if isinstance(cfg.get("seed"), bool) or not isinstance(cfg.get("seed", 0), int):
        problem = f"'seed' must be an integer, got {cfg.get('seed')!r}"
    o = cfg.get("agent_options", {})
    if not isinstance(o, dict):
        problem = f"'agent_options' must be an object, got {o!r}"
    else:
        for k in ("checkpoint", "decoding", "perception", "noise"):
            if o.get(k) is not None and not isinstance(o[k], str):
                problem = f"agent_options.{k} must be a string, got {o[k]!r}"
        t = o.get("temperature", 1.0)
        if isinstance(t, bool) or not isinstance(t, (int, float)):
            problem = f"agent_options.temperature must be a number, got {t!r}"
    if problem:
        raise TableError(f"{path}: corrupt config ({problem})"[:300])
    return cfg


def first_records(run_dir: str | Path, first: int) -> list[dict[str, Any]]:
    """The run's records of the first ``first`` episodes of its dataset file (file order); a run
    lacking any of them is an error."""
    from navbench.episodes.io import load_dataset
    from navbench.eval.runner import read_records
    from navbench.paths import split_file

    run_dir = Path(run_dir)
    cfg = load_config(run_dir)
    if not cfg.get("task") or not (cfg.get("split") or cfg.get("episodes")):
        raise TableError(f"{run_dir / 'config.json'}: corrupt config (no 'task', or neither 'split' nor 'episodes')")
    # a bundled split is read where this checkout keeps it (config.json holds the writer's path)
    bundled = split_file(cfg["task"], cfg["split"]) if cfg.get("split") else None
    episodes = bundled if bundled is not None and bundled.is_file() else Path(cfg.get("episodes") or "")
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


IDENTITY = ("checkpoint", "decoding", "seed", "perception")


def run_identity(run_dir: str | Path) -> dict[str, Any]:
    """What makes a run what it is, beyond its agent and split: the table's identity columns (those the
    run's agent has, from its options; "-" for the others and for a plug-in agent's run)."""
    from navbench.agents.registry import AGENTS

    path = Path(run_dir) / "config.json"
    cfg = load_config(run_dir)
    ident: dict[str, Any] = {k: "-" for k in IDENTITY}
    ident["seed"] = cfg.get("seed", 0)
    spec = AGENTS.get(cfg.get("agent"))
    if spec is not None:
        try:
            ident.update(spec.options.from_record(cfg.get("agent_options", {})).identity())
        except (TypeError, ValueError) as exc:
            raise TableError(f"{path}: corrupt config (agent_options: {exc})"[:300]) from None
    return ident


def summary_row(s: dict[str, Any], identity: dict[str, Any] | None = None) -> dict[str, Any]:
    return {
        "agent": s.get("agent"), **(identity or {}), "task": s.get("task"), "split": s.get("split") or "custom",
        "episodes": s.get("num_episodes"),
        "SR": 100 * s["success"], "SPL": 100 * s["spl"], "SoftSPL": 100 * s["soft_spl"],
        "DTG": s["distance_to_goal"],
    }


def runs_frame(run_dirs: list[str | Path], wide: bool = True, first: int | None = None) -> pd.DataFrame:
    """Long form (one row per run) or wide form (rows = agent, columns = (split, SR/SPL)); with
    ``first``, every run is scored on the first ``first`` episodes of its split only."""
    df = pd.DataFrame([summary_row(load_summary(d) if first is None else first_summary(d, first), run_identity(d))
                       for d in run_dirs])
    if not wide or df["split"].nunique() <= 1:
        return df
    wide_df = df.pivot_table(index=["agent", *IDENTITY], columns="split", values=["SR", "SPL"], aggfunc="first",
                             sort=False)
    wide_df = wide_df.swaplevel(0, 1, axis=1)
    splits = list(dict.fromkeys(df["split"]))
    return wide_df.reindex(columns=[(sp, m) for sp in splits for m in ("SR", "SPL")])


def render(df: pd.DataFrame, fmt: str = "markdown") -> str:
    if isinstance(df.columns, pd.MultiIndex):  # wide form: flat "split SR" headers, identity as columns
        df = df.copy()
        df.columns = [f"{a} {b}" for a, b in df.columns]
        df = df.reset_index()
    if fmt == "markdown":
        return df.to_markdown(floatfmt=".1f", index=False)
    if fmt == "csv":
        return df.to_csv(float_format="%.2f", index=False)
    if fmt == "latex":
        return df.style.hide(axis="index").format(precision=1).to_latex(hrules=True)
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
