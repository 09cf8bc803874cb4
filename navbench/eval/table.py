"""Result tables as navigation papers print them: one row per agent, SR and SPL in percent.

    navbench table runs/objectnav/val_seen/oracle runs/objectnav/val_unseen/oracle --format markdown|csv|latex
    navbench table runs/objectnav/val_unseen/frontier runs/objectnav/val_unseen/memory --first 20  # same 20 episodes
    navbench table runs/objectnav/val_unseen/memory --by scene   # one row per scene (or --by category)

Every figure carries its 95% interval, ``SR [lo, hi]`` (CSV: ``SR lo`` and ``SR hi`` columns): summary.json's
``ci95``, or for a run written without it the same two-stage bootstrap of its records
(:mod:`navbench.eval.stats`). Runs scored under different protocols (:mod:`navbench.eval.provenance`) are
refused unless ``mix_protocols``, which adds a ``protocol`` column and a note under the table.

Every row carries the run's identity from its ``config.json``: the checkpoint and decoding of agents
that drive with the PointNav policy, the seed, and the perception of agents that localise objects
("-" where a column does not apply to the agent).
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path
from typing import Any

import pandas as pd

from navbench.safeio import read_input
from navbench.tasks import TASKS
from navbench.tasks.base import COLUMNS

FORMATS = ("markdown", "csv", "latex")


class TableError(ValueError):
    pass


METRICS = ("success", "spl", "soft_spl", "distance_to_goal")
METRE_COLUMNS = ("DTG", "NE", "TL")  # shown with two decimals


def task_metrics(task: Any) -> tuple[str, ...]:
    """The measures a run of ``task`` summarises (:attr:`navbench.tasks.base.Task.summary_keys`); navbench's
    four for a task this checkout does not know."""
    t = TASKS.get(task) if isinstance(task, str) else None
    return t.summary_keys if t is not None else METRICS


def task_columns(task: Any) -> dict[str, tuple[str, float]]:
    """``{header: (measure, scale)}`` of a run of ``task``'s table row (:attr:`navbench.tasks.base.Task.columns`)."""
    t = TASKS.get(task) if isinstance(task, str) else None
    return {h: (m, k) for h, m, k in (t.columns if t is not None else COLUMNS)}


def _read_object(path: Path, what: str) -> dict[str, Any]:
    """A JSON object from ``path``, or a one-line TableError naming it."""
    try:
        doc = json.loads(read_input(path, gunzip=False))
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
    for k in task_metrics(s.get("task")):
        v = s.get(k)
        if v is None and k in s:  # a measure the run could not take (a split without goals or gt paths)
            continue
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
    from navbench.eval.config import recorded_paths
    from navbench.eval.rundir import RunError
    from navbench.eval.runner import read_records
    from navbench.paths import split_file

    run_dir = Path(run_dir)
    cfg = load_config(run_dir)
    if not cfg.get("task") or not (cfg.get("split") or cfg.get("episodes")):
        raise TableError(f"{run_dir / 'config.json'}: corrupt config (no 'task', or neither 'split' nor 'episodes')")
    # a bundled split is read where this checkout keeps it (config.json holds the writer's path)
    bundled = split_file(cfg["task"], cfg["split"]) if cfg.get("split") else None
    try:
        episodes = bundled if bundled is not None and bundled.is_file() else \
            Path(recorded_paths(cfg, run_dir / "config.json")[0])
    except RunError as exc:
        raise TableError(str(exc)) from None
    head = load_dataset(episodes, lambda stream: list(itertools.islice(stream(), first))).episodes
    keep = {(e.scene_id, e.episode_id) for e in head}
    recs = [r for r in read_records(run_dir / "episodes.jsonl") if (r["scene_id"], r["episode_id"]) in keep]
    if len(recs) < len(keep):
        raise TableError(f"{run_dir}: has {len(recs)} of the first {first} episodes of {episodes.name}")
    return recs


def first_summary(run_dir: str | Path, first: int) -> dict[str, Any]:
    """The run's summary recomputed on :func:`first_records`, so runs of different lengths can be
    compared on the same episodes."""
    from navbench.metrics import aggregate

    summary = load_summary(run_dir)
    task = TASKS.get(str(summary.get("task")))
    by = task.group_by if task is not None else None
    return {**summary, **aggregate(first_records(run_dir, first), by=by, keys=task_metrics(summary.get("task")))}


IDENTITY = ("checkpoint", "decoding", "seed", "perception")


def run_split(run_dir: str | Path, summary: dict[str, Any]) -> str | None:
    """The run's bundled split, else the name of the episode file it ran (as its directory is named)."""
    from navbench.episodes.io import file_split

    if summary.get("split"):
        return summary["split"]
    episodes = load_config(run_dir).get("episodes")
    return file_split(episodes) if episodes else None


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




def _valid_ci(ci: Any, metrics: tuple[str, ...] = METRICS) -> bool:
    return isinstance(ci, dict) and all(
        isinstance(ci.get(m), list) and len(ci[m]) == 2
        and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in ci[m]) for m in metrics)


def summary_row(s: dict[str, Any], identity: dict[str, Any] | None = None,
                ci: dict[str, list[float]] | None = None) -> dict[str, Any]:
    """A table row of a summary; with ``ci`` (``{metric: [lo, hi]}``) each figure's ``lo`` and ``hi`` too."""
    row = {"agent": s.get("agent"), **(identity or {}), "task": s.get("task"), "split": s.get("split") or "custom",
           "episodes": s.get("num_episodes")}
    for col, (m, scale) in task_columns(s.get("task")).items():
        row[col] = None if s[m] is None else scale * s[m]
        if ci is not None and m in ci:
            row[f"{col} lo"], row[f"{col} hi"] = scale * ci[m][0], scale * ci[m][1]
    return row


def run_records(run_dir: str | Path, first: int | None = None) -> list[dict[str, Any]] | None:
    """The run's records (of its first ``first`` episodes), or None when it has no episodes.jsonl."""
    from navbench.eval.rundir import read_records

    if first is not None:
        return first_records(run_dir, first)
    path = Path(run_dir) / "episodes.jsonl"
    return read_records(path) if path.is_file() else None


def run_intervals(run_dir: str | Path, summary: dict[str, Any], first: int | None = None) -> dict | None:
    """summary.json's ``ci95`` (all episodes), else the two-stage bootstrap of the records the row scores."""
    from navbench.eval.stats import StatsError, intervals

    metrics = tuple(m for m in task_metrics(summary.get("task")) if summary.get(m) is not None)
    if first is None and _valid_ci(summary.get("ci95"), metrics):
        return summary["ci95"]
    recs = run_records(run_dir, first)
    if not recs:
        return None
    # A measure some episodes cannot take (null: GOAT's per-type figures without that type) is bootstrapped over
    # the episodes that have it, as the summary averages it; the others together.
    whole = tuple(m for m in metrics if all(r.get(m) is not None for r in recs))
    try:
        out = intervals(recs, whole) if whole else {}
        for m in metrics:
            if m not in whole and any(r.get(m) is not None for r in recs):
                out.update(intervals([r for r in recs if r.get(m) is not None], (m,)))
    except StatsError as exc:
        raise TableError(f"{Path(run_dir) / 'episodes.jsonl'}: {exc}") from None
    return out


def _protocols(run_dirs: list[str | Path], mix_protocols: bool) -> list[str] | None:
    """Each run's protocol_id when they differ (and ``mix_protocols``), else None; refused otherwise."""
    from navbench.eval.provenance import ProtocolError, check_same_protocol

    try:
        ids = check_same_protocol(run_dirs, allow_mixed=mix_protocols)
    except ProtocolError as exc:
        raise TableError(str(exc)) from None
    return ids if len(set(ids)) > 1 else None


def runs_frame(run_dirs: list[str | Path], wide: bool = True, first: int | None = None,
               mix_protocols: bool = False) -> pd.DataFrame:
    """Long form (one row per run) or wide form (rows = agent, columns = (split, SR/SPL)); with
    ``first``, every run is scored on the first ``first`` episodes of its split only."""
    summaries = [load_summary(d) if first is None else first_summary(d, first) for d in run_dirs]
    protocols = _protocols(run_dirs, mix_protocols)
    rows = []
    for i, (d, s) in enumerate(zip(run_dirs, summaries)):
        ident = {**run_identity(d), **({"protocol": protocols[i]} if protocols else {})}
        rows.append(summary_row({**s, "split": run_split(d, s)}, ident, run_intervals(d, s, first)))
    df = pd.DataFrame(rows)
    if protocols:
        df.attrs["note"] = f"mixed protocols ({', '.join(dict.fromkeys(protocols))}): figures are not comparable"
    if not wide or df["split"].nunique() <= 1:
        return df
    ident = [*IDENTITY, *(["protocol"] if protocols else [])]
    metrics = [c for m in ("SR", "SPL") for c in (m, f"{m} lo", f"{m} hi") if c in df.columns]
    wide_df = df.pivot_table(index=["agent", *ident], columns="split", values=metrics, aggfunc="first", sort=False)
    wide_df = wide_df.swaplevel(0, 1, axis=1)
    splits = list(dict.fromkeys(df["split"]))
    wide_df = wide_df.reindex(columns=[(sp, m) for sp in splits for m in metrics])
    wide_df.attrs = df.attrs
    return wide_df


def group_frame(run_dirs: list[str | Path], by: str, first: int | None = None,
                mix_protocols: bool = False) -> pd.DataFrame:
    """One row per run and scene (``by="scene"``) or object category (``by="category"``), with intervals
    (one scene: an episode bootstrap)."""
    from navbench.eval.stats import intervals
    from navbench.metrics import aggregate

    key = {"scene": "scene_id", "category": "object_category"}[by]
    summaries = [load_summary(d) for d in run_dirs]
    protocols = _protocols(run_dirs, mix_protocols)
    rows = []
    for i, (d, s) in enumerate(zip(run_dirs, summaries)):
        recs = run_records(d, first)
        if recs is None:
            raise TableError(f"{Path(d) / 'episodes.jsonl'}: missing (a table --by {by} reads the records)")
        groups: dict[str, list[dict[str, Any]]] = {}
        for r in recs:
            groups.setdefault(str(r.get(key)), []).append(r)
        ident = {**run_identity(d), **({"protocol": protocols[i]} if protocols else {})}
        split = run_split(d, s)
        for g, rs in sorted(groups.items()):
            metrics = task_metrics(s.get("task"))
            agg = aggregate(rs, keys=metrics)
            if not agg["num_episodes"]:
                continue
            row = summary_row({**s, **agg, "split": split}, ident, intervals(rs, metrics))
            rows.append({**{k: v for k, v in row.items() if k != "task"}, by: g})
    df = pd.DataFrame(rows)
    shown = {h for s in summaries for h in task_columns(s.get("task"))}
    cols = [c for c in df.columns if c not in (by, "episodes") and c not in shown and not c.endswith((" lo", " hi"))]
    df = df[[*cols, by, "episodes", *[c for c in df.columns if c in shown or c.endswith((" lo", " hi"))]]]
    if protocols:
        df.attrs["note"] = f"mixed protocols ({', '.join(dict.fromkeys(protocols))}): figures are not comparable"
    return df


def _cell(v: Any, lo: Any, hi: Any, digits: int) -> str:
    if pd.isna(v):
        return ""
    if pd.isna(lo) or pd.isna(hi):
        return f"{v:.{digits}f}"
    return f"{v:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"


def _with_intervals(df: pd.DataFrame) -> pd.DataFrame:
    """Each figure with ``lo``/``hi`` columns beside it as one ``v [lo, hi]`` text cell."""
    df = df.copy()
    for c in list(df.columns):
        if f"{c} lo" in df.columns and f"{c} hi" in df.columns:
            df[c] = [_cell(v, lo, hi, 2 if str(c).endswith(METRE_COLUMNS) else 1)
                     for v, lo, hi in zip(df[c], df[f"{c} lo"], df[f"{c} hi"])]
            df = df.drop(columns=[f"{c} lo", f"{c} hi"])
    return df


def render(df: pd.DataFrame, fmt: str = "markdown") -> str:
    note = df.attrs.get("note")
    if isinstance(df.columns, pd.MultiIndex):  # wide form: flat "split SR" headers, identity as columns
        df = df.copy()
        df.columns = [f"{a} {b}" for a, b in df.columns]
        df = df.reset_index()
    if fmt == "markdown":
        text = _with_intervals(df).to_markdown(floatfmt=".1f", index=False)
        return text + (f"\n\n*{note}*" if note else "")
    if fmt == "csv":
        text = df.to_csv(float_format="%.2f", index=False)
        return text + (f"# {note}\n" if note else "")
    if fmt == "latex":
        text = _with_intervals(df).style.hide(axis="index").format(precision=1).to_latex(hrules=True)
        return text + (f"% {note}\n" if note else "")
    raise TableError(f"unknown format {fmt!r}: choose from {', '.join(FORMATS)}")


def summary_markdown(summary: dict[str, Any]) -> str:
    """The table ``navbench run`` prints: the overall row, then per-category rows for ObjectNav, each
    figure with its 95% interval when the summary has one."""
    metrics = tuple(m for m in task_metrics(summary.get("task")) if summary.get(m) is not None)
    ci = summary.get("ci95") if _valid_ci(summary.get("ci95"), metrics) else None
    rows = [dict(summary_row(summary, ci=ci), category="all")]
    for cat, m in (summary.get("by_object_category") or {}).items():
        cat_ci = m.get("ci95") if _valid_ci(m.get("ci95"), metrics) else None
        rows.append(dict(summary_row({**summary, **m}, ci=cat_ci), category=cat))
    df = pd.DataFrame(rows).set_index("category").drop(columns=["task"])
    return _with_intervals(df).to_markdown(floatfmt=".1f")
