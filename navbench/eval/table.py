"""Result tables as navigation papers print them: one row per agent, SR and SPL in percent.

    navbench table runs/objectnav/val_seen/oracle runs/objectnav/val_unseen/oracle --format markdown|csv|latex
    navbench table runs/objectnav/val_unseen/frontier runs/objectnav/val_unseen/memory --first 20  # same 20 episodes
    navbench table runs/objectnav/val_unseen/memory --by scene   # one row per scene (or --by category)

Every figure carries its 95% interval, ``SR [lo, hi]`` (CSV: ``SR lo`` and ``SR hi`` columns): summary.json's
``ci95``, or for a run written without it the same two-stage bootstrap of its records
(:mod:`navbench.eval.stats`). Each task's runs show its own measures (:attr:`navbench.tasks.base.Task.columns`);
GOAT-Bench's runs show goat-bench's success and SPL by goal type (over the subtasks of each type,
:func:`navbench.eval.goat_table.type_figures`) beside its ``partial_success``, ``composite_success`` and
``composite_spl``. Runs scored under different protocols (:mod:`navbench.eval.provenance`) are shown side by side
with a ``protocol`` column, one column per protocol field that differs (each run's value) and a note under the
table; ``navbench compare``, which pairs runs episode by episode, refuses them.

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
    task = TASKS.get(cfg["task"])  # the task's own reader (GOAT-Bench's content/ layout), Habitat's JSON else
    read = task.read_episodes if task is not None else load_dataset
    head = read(episodes, lambda stream: list(itertools.islice(stream(), first))).episodes
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
                ci: dict[str, list[float]] | None = None, figures: dict[str, Any] | None = None) -> dict[str, Any]:
    """A table row of a summary; with ``ci`` (``{metric: [lo, hi]}``) each figure's ``lo`` and ``hi`` too;
    ``figures``: columns computed from the records (:func:`goat_figures`), placed before the summary's."""
    row = {"agent": s.get("agent"), **(identity or {}), "task": s.get("task"), "split": s.get("split") or "custom",
           "episodes": s.get("num_episodes"), **(figures or {})}
    for col, (m, scale) in task_columns(s.get("task")).items():
        row[col] = None if s[m] is None else scale * s[m]
        if ci is not None and m in ci:
            row[f"{col} lo"], row[f"{col} hi"] = scale * ci[m][0], scale * ci[m][1]
    return row


def shown_measures(summary: dict[str, Any]) -> tuple[str, ...]:
    """The measures of the summary's table columns that it has a figure for (the ones given intervals)."""
    return tuple(m for m, _ in task_columns(summary.get("task")).values() if summary.get(m) is not None)


GOAT_NOTE = ("object, description, image SR and SPL: over the subtasks of each goal type (goat-bench's "
             "success_by_subtask, spl_by_subtask); partial SR, composite SR, composite SPL: goat-bench's "
             "partial_success, composite_success, composite_spl, means over episodes; "
             "`python -m navbench.eval.goat_table` breaks them down further")


def goat_figures(run_dir: str | Path, first: int | None = None) -> dict[str, float]:
    """A GOAT-Bench run's success and SPL (%) by goal type with their intervals, as table columns (``object SR``,
    ``object SR lo``, ...): :func:`navbench.eval.goat_table.type_figures` of its records (of its first ``first``
    episodes)."""
    from navbench.eval.goat_table import scored_run, type_figures

    try:
        cfg, label, recs = scored_run(run_dir)
        if first is not None:
            keep = {(r["scene_id"], r["episode_id"]) for r in first_records(run_dir, first)}
            recs = [r for r in recs if (r["scene_id"], r["episode_id"]) in keep]
        by_type = type_figures((cfg, label, recs))
    except KeyError as exc:  # a record of an episode the run's episode file does not have
        raise TableError(f"{Path(run_dir) / 'episodes.jsonl'}: episode {exc} is not in the run's episode file"
                         [:300]) from None
    except (OSError, ValueError) as exc:
        raise TableError(str(exc)[:300]) from None
    out: dict[str, float] = {}
    for t, f in by_type.items():
        for m, head in (("success", "SR"), ("spl", "SPL")):
            out[f"{t} {head}"] = 100 * f[m]
            if f"{m} lo" in f:
                out[f"{t} {head} lo"], out[f"{t} {head} hi"] = 100 * f[f"{m} lo"], 100 * f[f"{m} hi"]
    return out


def run_figures(run_dir: str | Path, summary: dict[str, Any], first: int | None = None) -> dict[str, float] | None:
    """The columns a run's row computes from its records beyond its summary: a GOAT-Bench run's by goal type."""
    return goat_figures(run_dir, first) if summary.get("task") == "goat" else None


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

    metrics = shown_measures(summary)
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


def _protocol_value(proto: dict[str, Any], field: str) -> str:
    """A protocol field's value as a table cell: a realistic condition a protocol leaves out is off (its
    EnvConfig default); any other field it lacks does not apply ("-")."""
    from navbench.env.config import CONDITIONS

    v = proto.get(field, CONDITIONS.get(field, "-"))
    if isinstance(v, (list, tuple)):
        return ",".join(str(x) for x in v)
    return "-" if v is None else str(v).lower() if isinstance(v, bool) else str(v)


def _protocols(run_dirs: list[str | Path]) -> tuple[list[dict[str, str]] | None, str | None]:
    """When the runs' protocols differ: each run's identity columns for it (``protocol``: its id, then one
    column per field that differs between them, the run's value) and the note under the table; else None."""
    from navbench.eval.provenance import ProtocolError, protocol_id, run_protocol

    try:
        protos = [run_protocol(d) for d in run_dirs]
        ids = [protocol_id(p) for p in protos]
    except ProtocolError as exc:
        raise TableError(str(exc)) from None
    if len(set(ids)) <= 1:
        return None, None
    keys = sorted({k for p in protos for k in p} - {"derived"})
    differ = [k for k in keys if len({json.dumps(p.get(k), sort_keys=True) for p in protos}) > 1]
    cols = [{"protocol": i, **{k: _protocol_value(p, k) for k in differ}} for i, p in zip(ids, protos)]
    note = (f"runs under {len(set(ids))} protocols ({', '.join(dict.fromkeys(ids))}), which differ in "
            f"{', '.join(differ)} (a column each); `navbench compare` pairs runs under one protocol only")
    return cols, note


def runs_frame(run_dirs: list[str | Path], wide: bool = True, first: int | None = None) -> pd.DataFrame:
    """Long form (one row per run) or wide form (rows = agent, columns = (split, SR/SPL)); with
    ``first``, every run is scored on the first ``first`` episodes of its split only."""
    summaries = [load_summary(d) if first is None else first_summary(d, first) for d in run_dirs]
    protocols, note = _protocols(run_dirs)
    rows = []
    for i, (d, s) in enumerate(zip(run_dirs, summaries)):
        ident = {**run_identity(d), **(protocols[i] if protocols else {})}
        rows.append(summary_row({**s, "split": run_split(d, s)}, ident, run_intervals(d, s, first),
                                run_figures(d, s, first)))
    df = pd.DataFrame(rows)
    notes = [n for n in (GOAT_NOTE if any(s.get("task") == "goat" for s in summaries) else None, note) if n]
    df.attrs["notes"] = notes
    if not wide or df["split"].nunique() <= 1 or df["task"].nunique() > 1:  # one task's splits side by side
        return df
    ident = [*IDENTITY, *(protocols[0] if protocols else {})]
    heads = [h for h in ("SR", "SPL") if h in df.columns] or list(task_columns(summaries[0].get("task")))
    metrics = [c for m in heads for c in (m, f"{m} lo", f"{m} hi") if c in df.columns]
    wide_df = df.pivot_table(index=["agent", *ident], columns="split", values=metrics, aggfunc="first", sort=False)
    wide_df = wide_df.swaplevel(0, 1, axis=1)
    splits = list(dict.fromkeys(df["split"]))
    wide_df = wide_df.reindex(columns=[(sp, m) for sp in splits for m in metrics])
    wide_df.attrs = df.attrs
    return wide_df


def group_frame(run_dirs: list[str | Path], by: str, first: int | None = None) -> pd.DataFrame:
    """One row per run and scene (``by="scene"``) or object category (``by="category"``), with intervals
    (one scene: an episode bootstrap)."""
    from navbench.eval.stats import intervals
    from navbench.metrics import aggregate

    key = {"scene": "scene_id", "category": "object_category"}[by]
    summaries = [load_summary(d) for d in run_dirs]
    protocols, note = _protocols(run_dirs)
    rows = []
    for i, (d, s) in enumerate(zip(run_dirs, summaries)):
        recs = run_records(d, first)
        if recs is None:
            raise TableError(f"{Path(d) / 'episodes.jsonl'}: missing (a table --by {by} reads the records)")
        groups: dict[str, list[dict[str, Any]]] = {}
        for r in recs:
            groups.setdefault(str(r.get(key)), []).append(r)
        ident = {**run_identity(d), **(protocols[i] if protocols else {})}
        split = run_split(d, s)
        for g, rs in sorted(groups.items()):
            agg = aggregate(rs, keys=task_metrics(s.get("task")))
            if not agg["num_episodes"]:
                continue
            metrics = shown_measures({**s, **agg})
            row = summary_row({**s, **agg, "split": split}, ident, intervals(rs, metrics) if metrics else None)
            rows.append({**{k: v for k, v in row.items() if k != "task"}, by: g})
    df = pd.DataFrame(rows)
    shown = {h for s in summaries for h in task_columns(s.get("task"))}
    cols = [c for c in df.columns if c not in (by, "episodes") and c not in shown and not c.endswith((" lo", " hi"))]
    df = df[[*cols, by, "episodes", *[c for c in df.columns if c in shown or c.endswith((" lo", " hi"))]]]
    df.attrs["notes"] = [note] if note else []
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
    notes = df.attrs.get("notes") or []
    if isinstance(df.columns, pd.MultiIndex):  # wide form: flat "split SR" headers, identity as columns
        df = df.copy()
        df.columns = [f"{a} {b}" for a, b in df.columns]
        df = df.reset_index()
    if fmt == "markdown":
        text = _with_intervals(df).to_markdown(floatfmt=".1f", index=False)
        return text + "".join(f"\n\n*{n}*" for n in notes)
    if fmt == "csv":
        text = df.to_csv(float_format="%.2f", index=False)
        return text + "".join(f"# {n}\n" for n in notes)
    if fmt == "latex":
        text = _with_intervals(df).style.hide(axis="index").format(precision=1).to_latex(hrules=True)
        return text + "".join(f"% {n}\n" for n in notes)
    raise TableError(f"unknown format {fmt!r}: choose from {', '.join(FORMATS)}")


PERCEPTION_WORDS = {"oracle": "the simulator's ground-truth object labels, not a model"}


def identity_line(agent: Any, identity: dict[str, Any]) -> str | None:
    """The run's agent as its identity columns say (checkpoint, decoding, perception: those it has), the
    perception in words (``oracle`` ground truth, or the models that detect objects); None for an agent
    with none of them."""
    parts = []
    for k in ("checkpoint", "decoding", "perception"):
        v = identity.get(k)
        if not isinstance(v, str) or v == "-":
            continue
        if k == "perception":
            name, _, noise = v.partition(", ")
            words = PERCEPTION_WORDS.get(name, "objects detected in RGB by these models")
            v = f"{name} ({words}{'; ' + noise if noise else ''})"
        parts.append(f"{k} {v}")
    return f"agent {agent}: " + ", ".join(parts) if parts else None


def summary_markdown(summary: dict[str, Any], run_dir: str | Path | None = None) -> str:
    """The table ``navbench run`` prints: the overall row, then per-category rows for ObjectNav, each
    figure with its 95% interval when the summary has one. With the ``run_dir``: a line under it with the
    agent's checkpoint, decoding and perception (``oracle`` ground truth or a model: those it has); for a
    GOAT-Bench run, success and SPL by goal type (:func:`goat_figures`) and what the columns are."""
    metrics = shown_measures(summary)
    ci = summary.get("ci95") if _valid_ci(summary.get("ci95"), metrics) else None
    goat = run_dir is not None and summary.get("task") == "goat" and summary.get("num_episodes")
    figures = goat_figures(run_dir) if goat else None
    rows = [dict(summary_row(summary, ci=ci, figures=figures), category="all")]
    for cat, m in (summary.get("by_object_category") or {}).items():
        cat_ci = m.get("ci95") if _valid_ci(m.get("ci95"), metrics) else None
        rows.append(dict(summary_row({**summary, **m}, ci=cat_ci), category=cat))
    df = pd.DataFrame(rows).set_index("category").drop(columns=["task"])
    who = identity_line(summary.get("agent"), run_identity(run_dir)) if run_dir is not None else None
    notes = [n for n in (who, GOAT_NOTE if goat else None) if n]
    return _with_intervals(df).to_markdown(floatfmt=".1f") + "".join(f"\n\n*{n}*" for n in notes)
