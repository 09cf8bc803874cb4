"""GOAT-Bench runs by subtask: success and SPL of the 1st, 2nd, ... subtask of an episode and of each goal type,
with 95% intervals, from run directories of ``navbench run --task goat``.

    python -m navbench.eval.goat_table results/runs/goat/val/oracle results/runs/goat/val/memory

A subtask's success and SPL are the records' ``subtask_success`` and ``spl_by_subtask`` (goat-bench's
per-subtask figures); its type is its episode's ``tasks[k]``, read from the run's episode file. A subtask the
episode never reached (a plain STOP or the step limit first) counts as a failure. The intervals are
:func:`navbench.eval.stats.intervals`' two-stage bootstrap over the subtasks (houses, then subtasks).
Where a run's records carry the memory agent's per-subtask log, the mean localisation time per subtask is
shown beside them: the memory is built once per house and every subtask is a query to it. Last, the steps each
run took per subtask it closed.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from navbench.eval.runner import read_records
from navbench.eval.stats import intervals
from navbench.metrics import GOAT_TYPES
from navbench.paths import split_file
from navbench.tasks import get_task

ORDINALS = ("1st", "2nd", "3rd") + tuple(f"{k}th" for k in range(4, 21))


Run = tuple[dict[str, Any], str, list[dict[str, Any]]]  # a run's config, its label, its scored records


def scored_run(run_dir: str | Path) -> Run:
    """A GOAT-Bench run's config.json, label and records (skipped episodes left out)."""
    run_dir = Path(run_dir)
    cfg = json.loads((run_dir / "config.json").read_text())
    if cfg.get("task") != "goat":
        raise ValueError(f"{run_dir}: not a GOAT-Bench run (task {cfg.get('task')!r})")
    recs = [r for r in read_records(run_dir / "episodes.jsonl") if not r.get("skipped")]
    return cfg, cfg.get("label") or run_dir.name, recs


def subtask_rows(run: str | Path | Run) -> tuple[str, list[dict[str, Any]]]:
    """(the run's label, one row per subtask of every scored episode: scene, episode, index, type, success,
    spl, and the memory agent's query time when logged), from a run directory or its :func:`scored_run`."""
    cfg, label, recs = run if isinstance(run, tuple) else scored_run(run)
    path = split_file("goat", cfg["split"]) if cfg.get("split") else Path(cfg["episodes"])
    episodes = {(e.scene_id, e.episode_id): e for e in get_task("goat").read_episodes(path).episodes}
    rows = []
    for r in recs:
        ep = episodes[(r["scene_id"], str(r["episode_id"]))]
        success, spl = r.get("subtask_success") or [], r.get("spl_by_subtask") or []
        logged = {s["subtask"]: s.get("query_ms") for s in (r.get("log") or {}).get("subtasks", [])}
        for k, task in enumerate(ep.tasks):
            rows.append({"scene_id": r["scene_id"], "episode_id": f"{r['episode_id']}:{k:03d}", "index": k,
                         "type": task.type, "success": float(success[k]) if k < len(success) else 0.0,
                         "spl": float(spl[k]) if k < len(spl) else 0.0, "query_ms": logged.get(k)})
    return label, rows


def type_figures(run: str | Path | Run) -> dict[str, dict[str, float]]:
    """goat-bench's success and SPL by goal type: ``{type: {"success", "spl": mean over the run's subtasks of
    that type, "success lo", "success hi", "spl lo", "spl hi": their 95% interval, "subtasks": count}}``,
    for the types the run has (``navbench table``'s per-type columns, in [0, 1])."""
    _, rows = subtask_rows(run)
    out = {}
    for t in GOAT_TYPES:
        sel = [r for r in rows if r["type"] == t]
        if not sel:
            continue
        ci = intervals(sel, ("success", "spl")) or {}
        out[t] = {"subtasks": len(sel), **{m: sum(r[m] for r in sel) / len(sel) for m in ("success", "spl")},
                  **{f"{m} {e}": ci[m][i] for m in ci for i, e in enumerate(("lo", "hi"))}}
    return out


def _cell(rows: list[dict[str, Any]], metric: str, ci: dict[str, list[float]] | None) -> str:
    mean = 100 * sum(r[metric] for r in rows) / len(rows)
    lo, hi = (100 * v for v in ci[metric]) if ci else (mean, mean)
    return f"{mean:.1f} [{lo:.1f}, {hi:.1f}]"


def table(runs: list[tuple[str, list[dict[str, Any]]]], key: str, order: list[Any], name) -> list[str]:
    labels = [label for label, _ in runs]
    with_query = [label for label, rows in runs if any(r["query_ms"] is not None for r in rows)]
    head = f"| {key} | subtasks | " + " | ".join(f"{a} SR | {a} SPL" for a in labels) + \
        "".join(f" | {a} query (ms)" for a in with_query) + " |"
    lines = [head, "|" + "---|" * (2 + 2 * len(labels) + len(with_query))]
    for value in order:
        cells, n = [], 0
        for _, rows in runs:
            sel = [r for r in rows if r[key] == value]
            n = max(n, len(sel))
            ci = intervals(sel, ("success", "spl")) if sel else None
            cells += [_cell(sel, "success", ci), _cell(sel, "spl", ci)] if sel else ["-", "-"]
        for label, rows in runs:
            if label in with_query:
                q = [r["query_ms"] for r in rows if r[key] == value and r["query_ms"] is not None]
                cells.append(f"{sum(q) / len(q):.0f}" if q else "-")
        lines.append(f"| {name(value)} | {n} | " + " | ".join(cells) + " |")
    return lines


def measures(runs: list[Run]) -> list[str]:
    """goat-bench's episode measures of each run (%), as its evaluation averages them, the corrected figures
    (an episode without the type left out) beside them, with 95% intervals over episodes."""
    from navbench.tasks.goat import GOAT_MEASURES

    lines = ["| measure | " + " | ".join(label for _, label, _ in runs) + " |", "|---|" + "---|" * len(runs)]
    for m in GOAT_MEASURES:
        cells = []
        for _, _, recs in runs:
            sel = [{**r, m: float(r[m])} for r in recs if r.get(m) is not None]
            cells.append(_cell(sel, m, intervals(sel, (m,))) + f" (n={len(sel)})" if sel else "-")
        lines.append(f"| `{m}` | " + " | ".join(cells) + " |")
    return lines


def steps(runs: list[Run]) -> list[str]:
    """What each run's subtasks cost in steps: the episodes' steps over the subtasks they closed (SUBTASK_STOP
    included; the steps after the last one, to a STOP or the limit, count too)."""
    lines = ["| run | episodes | steps | subtasks closed | steps per closed subtask |", "|---|---|---|---|---|"]
    for _, label, recs in runs:
        n, closed = sum(int(r["num_steps"]) for r in recs), sum(int(r.get("subtasks_closed") or 0) for r in recs)
        per = f"{n / closed:.1f}" if closed else "-"
        lines.append(f"| {label} | {len(recs)} | {n} | {closed} | {per} |")
    return lines


def report(run_dirs: list[str]) -> str:
    scored = [scored_run(d) for d in run_dirs]  # each run's files read once
    runs = [subtask_rows(s) for s in scored]
    indices = sorted({r["index"] for _, rows in runs for r in rows})
    types = [t for t in GOAT_TYPES if any(r["type"] == t for _, rows in runs for r in rows)]
    out = ["### goat-bench's measures, by episode (%)", ""] + measures(scored)
    out += ["", "SR and SPL (%) of each subtask, 95% intervals (two-stage bootstrap: houses, then subtasks).", "",
            "### By position in the episode", ""]
    out += table(runs, "index", indices, lambda k: ORDINALS[k] if k < len(ORDINALS) else str(k + 1))
    out += ["", "### By goal type", ""]
    out += table(runs, "type", types, str)
    out += ["", "### Steps", ""] + steps(scored)
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if not args:
        print("usage: python -m navbench.eval.goat_table RUN_DIR...", file=sys.stderr)
        return 2
    try:
        sys.stdout.write(report(args))
    except (OSError, ValueError, KeyError) as exc:
        print(f"goat_table: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
