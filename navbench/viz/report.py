"""A self-contained HTML report of one or more runs: SR/SPL side by side with their 95% intervals (the
two-stage bootstrap of :mod:`navbench.eval.stats`), per category, failure breakdown, and a gallery of
episodes (map thumbnail, outcome, video) filterable by run, outcome and category.

Everything (styles, script, thumbnails, embedded videos) is inline, so the page works opened from disk
with no server and no network. Every string from a run (labels, ids, categories, reasons) is escaped, and
records are type-checked when the run is loaded, so a hand-edited ``episodes.jsonl`` cannot script the page.
"""

from __future__ import annotations

import base64
import html
import json
import math
from collections import Counter
from pathlib import Path
from typing import Any

import cv2

from navbench.eval.stats import intervals
from navbench.safeio import read_input, safe_name
from navbench.viz.replay import Replayer, ReplayError, Run, outcome

OUTCOMES = ("success", "wrong instance", "stopped early", "stuck", "timeout", "crashed", "skipped")

CSS = """
body{font-family:system-ui,sans-serif;margin:1.5em;color:rgb(34,34,34);background:#fafafa}
h1{font-size:1.4em}h2{font-size:1.15em;margin-top:1.6em}
table{border-collapse:collapse;margin:.5em 0;background:#fff}
th,td{border:1px solid #ccc;padding:3px 8px;text-align:right}th{background:#eee}
td:first-child,th:first-child{text-align:left}
.filters{margin:.8em 0}.filters label{margin-right:1em}
.gallery{display:flex;flex-wrap:wrap;gap:10px}
.card{background:#fff;border:1px solid #ccc;border-radius:4px;padding:6px;width:%(w)dpx;font-size:12px}
.card img{width:%(w)dpx;display:block}.card video{width:%(w)dpx}
.badge{display:inline-block;padding:1px 6px;border-radius:3px;color:#fff;font-weight:600}
.success{background:#2a8a2a}.fail{background:#c0392b}.skip{background:rgb(136,136,136)}
.hidden{display:none}
"""

JS = """
function applyFilters(){
  var run=document.getElementById('f-run').value, out=document.getElementById('f-outcome').value,
      cat=document.getElementById('f-category').value, shown=0;
  document.querySelectorAll('.card').forEach(function(c){
    var ok=(!run||c.dataset.run===run)&&(!out||c.dataset.outcome===out)&&(!cat||c.dataset.category===cat);
    c.classList.toggle('hidden',!ok); if(ok)shown++;});
  document.getElementById('shown').textContent=shown;
}
document.querySelectorAll('.filters select').forEach(function(s){s.addEventListener('change',applyFilters);});
applyFilters();
document.body.dataset.ready='1';
"""


def _pct(v) -> str:
    return "" if v is None or (isinstance(v, float) and math.isnan(v)) else f"{100 * v:.1f}"


def _mean(xs) -> float | None:
    xs = [x for x in xs if x is not None]
    return sum(xs) / len(xs) if xs else None


def _pct_ci(recs, metric: str, ci: dict | None) -> str:
    """The mean in percent with its 95% interval (the two-stage bootstrap of navbench.eval.stats)."""
    mean = _pct(_mean([r.get(metric) for r in recs]))
    return f"{mean} [{100 * ci[metric][0]:.1f}, {100 * ci[metric][1]:.1f}]" if ci and mean else mean


def _table(head: list[str], rows: list[list[Any]]) -> str:
    h = "".join(f"<th>{html.escape(str(c))}</th>" for c in head)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{h}</tr></thead><tbody>{body}</tbody></table>"


def _scored(recs):
    return [r for r in recs if not r.get("skipped") and not r.get("failed")]


def summary_table(runs: list[Run]) -> str:
    rows = []
    for run in runs:
        s = _scored(run.records)
        ci = intervals(s)
        rows.append([run.label, run.cfg.task, run.cfg.split or "", len(s), _pct_ci(s, "success", ci),
                     _pct_ci(s, "spl", ci), _pct_ci(s, "soft_spl", ci),
                     f"{_mean([r.get('num_steps') for r in s]) or 0:.0f}",
                     f"{_mean([r.get('collisions') for r in s]) or 0:.1f}",
                     sum(1 for r in run.records if r.get("skipped"))])
    return _table(["run", "task", "split", "episodes", "SR % [95% CI]", "SPL % [95% CI]", "soft SPL % [95% CI]",
                   "steps", "collisions", "skipped"], rows)


def category_table(runs: list[Run]) -> str:
    cats = sorted({r.get("object_category") or "(point goal)" for run in runs for r in _scored(run.records)})
    head = ["category"] + [f"{run.label} {m}" for run in runs for m in ("n", "SR % [95% CI]", "SPL % [95% CI]")]
    rows = []
    for c in cats:
        row: list[Any] = [c]
        for run in runs:
            s = [r for r in _scored(run.records) if (r.get("object_category") or "(point goal)") == c]
            ci = intervals(s)
            row += [len(s), _pct_ci(s, "success", ci), _pct_ci(s, "spl", ci)]
        rows.append(row)
    return _table(head, rows)


def failure_table(runs: list[Run]) -> str:
    rows = []
    for run in runs:
        k = Counter(outcome(r) for r in run.records)
        rows.append([run.label] + [k.get(o, 0) for o in OUTCOMES])
    return _table(["run"] + list(OUTCOMES), rows)


def _png_b64(img, width: int) -> str:
    h, w = img.shape[:2]
    small = cv2.resize(img, (width, max(1, round(h * width / w))), interpolation=cv2.INTER_AREA)
    ok, buf = cv2.imencode(".png", small[..., ::-1])
    return base64.b64encode(buf.tobytes()).decode()


def _cards(run: Run, out_dir: Path, thumbs: int, max_episodes: int | None, embed_videos: bool) -> list[str]:
    from navbench.viz.maps import episode_map

    recs = [r for r in run.records if not r.get("failed")]
    recs.sort(key=lambda r: (bool(r.get("success")), bool(r.get("skipped"))))  # failures first
    if max_episodes is not None:
        recs = recs[:max_episodes]
    rp = Replayer(run)
    view = None
    cards = []
    try:
        for r in recs:
            o = outcome(r)
            cls = "success" if o == "success" else "skip" if o == "skipped" else "fail"
            try:
                img = None if r.get("skipped") else episode_map(rp, r, max_side=2 * thumbs, with_legend=False,
                                                                view=view)
            except ReplayError as exc:
                img, note = None, str(exc)
            else:
                note = "" if r.get("trace") else "no trace recorded: start, goals and shortest path only"
            pic = f'<img alt="map of episode {html.escape(str(r["episode_id"]))}" src="data:image/png;base64,' \
                  f'{_png_b64(img, thumbs)}">' if img is not None else ""
            video = Path(run.path) / "videos" / (safe_name(r["episode_id"]) + ".mp4")
            vid = ""
            if video.is_file():
                if embed_videos:
                    b = base64.b64encode(read_input(video, 256 << 20)).decode()
                    vid = f'<video controls preload="none" src="data:video/mp4;base64,{b}"></video>'
                else:
                    rel = Path(_relpath(video, out_dir))
                    vid = f'<a href="{html.escape(rel.as_posix())}">video</a>'
            cat = r.get("object_category") or "(point goal)"
            spl = r.get("spl")
            cards.append(
                f'<div class="card" data-run="{html.escape(run.label)}" data-outcome="{html.escape(o)}" '
                f'data-category="{html.escape(cat)}">{pic}'
                f'<div><span class="badge {cls}">{html.escape(o)}</span> {html.escape(cat)}</div>'
                f'<div>{html.escape(run.label)} · ep {html.escape(str(r["episode_id"]))} · '
                f'{html.escape(Path(r["scene_id"]).stem)}</div>'
                f'<div>{html.escape(str(r.get("num_steps", 0)))} steps · SPL '
                f'{html.escape(str(spl if spl is None else f"{spl:.2f}"))} · '
                f'{html.escape(str(r.get("collisions", 0)))} collisions</div>'
                + (f'<div><i>{html.escape(note)}</i></div>' if note else "") + vid + "</div>")
    finally:
        rp.close()
    return cards


def _relpath(p: Path, start: Path) -> str:
    import os
    return os.path.relpath(p.resolve(), start.resolve())


def _select(name: str, label: str, values) -> str:
    opts = "".join(f'<option value="{html.escape(v)}">{html.escape(v)}</option>' for v in values)
    return f'<label>{label} <select id="f-{name}"><option value="">all</option>{opts}</select></label>'


def write_report(run_dirs: list[Path], out: Path, thumbs: int = 220, max_episodes: int | None = None,
                 embed_videos: bool = False) -> Path:
    runs = [Run.load(d) for d in run_dirs]
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    cards = [c for run in runs for c in _cards(run, out.parent, thumbs, max_episodes, embed_videos)]
    cats = sorted({r.get("object_category") or "(point goal)" for run in runs for r in run.records})
    meta = {run.label: {"path": str(run.path), "episodes": len(run.records)} for run in runs}
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>navbench report</title>
<style>{CSS % {"w": thumbs}}</style></head>
<body>
<h1>navbench report: {html.escape(", ".join(run.label for run in runs))}</h1>
<h2>Success and SPL</h2>
<div id="summary">{summary_table(runs)}</div>
<h2>Per category</h2>
<div id="categories">{category_table(runs)}</div>
<h2>Outcomes and failure kinds (episodes)</h2>
<div id="failures">{failure_table(runs)}</div>
<p>wrong instance: STOP more than 2 m from every goal view point; stopped early: STOP within 2 m but outside the
success distance; stuck: step limit after the agent reported being stuck; timeout: step limit otherwise.</p>
<h2>Episodes</h2>
<div class="filters">{_select("run", "run", [run.label for run in runs])}
{_select("outcome", "outcome", OUTCOMES)}{_select("category", "category", cats)}
<span><span id="shown">{len(cards)}</span> shown</span></div>
<p>Maps: north (-z) up; the path from dark blue (start) to yellow (end); red dots are collisions, the red
square the STOP, the green line the shortest path, green dots the goal's view points, orange diamonds the
memory agent's candidates.</p>
<div class="gallery" id="gallery">
{chr(10).join(cards)}
</div>
<script type="application/json" id="runs">{html.escape(json.dumps(meta))}</script>
<script>{JS}</script>
</body></html>
"""
    out.write_text(page)
    return out
