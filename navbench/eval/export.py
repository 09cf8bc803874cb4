"""Leaderboard files from a run's records: what VLN-CE's inference writes for the challenge servers
(jacobkrantz/VLN-CE ``vlnce_baselines/common/base_il_trainer.py: BaseVLNCETrainer.inference``, env
``vlnce_baselines/common/environments.py: VLNCEInferenceEnv.get_info``).

- ``r2r-ce`` (``INFERENCE.FORMAT: r2r``, the R2R-CE leaderboard on EvalAI): one JSON object
  ``{episode_id: [{"position": [x, y, z], "heading": h, "stop": bool}, ...]}``, the start state first, then one
  entry per action; ``heading`` as :func:`navbench.env.vlnce.habitat_heading` computes it (radians), written
  with ``indent=2`` as the reference does.
- ``rxr-ce`` (``FORMAT: rxr``, the RxR-Habitat leaderboard): JSON Lines, one ``{"instruction_id": int, "path":
  [[x, y, z], ...]}`` per episode, the positions with consecutive repeats dropped, sorted by ``instruction_id``.
  The challenge takes all three languages of ``test_challenge`` in one file (VLN-CE's
  ``scripts/merge_inference_predictions.py`` joins per-language files).

A leaderboard scores a whole split: a run that covers only part of its episode file (``--limit``,
``--per-scene``, ``--shard``, or a run that stopped early) is refused in one line unless ``partial``, which
writes the file and says in one line how many episodes it lacks.

    navbench export runs/r2r_ce/test/vln_random --format r2r-ce -o predictions.json
    navbench export runs/r2r_ce/val/vln_random --format r2r-ce --partial   # a part of the split, knowingly
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from navbench.eval.rundir import RunError, read_records
from navbench.metrics import ndtw_points
from navbench.safeio import write_private

FORMATS = ("r2r-ce", "rxr-ce")


def _paths(records: list[dict[str, Any]], where: Path) -> list[tuple[dict[str, Any], dict[str, Any]]]:
    out = []
    for r in sorted(records, key=lambda r: (str(r.get("scene_id")), str(r.get("episode_id")))):
        path = r.get("vlnce_path")
        if r.get("skipped") or not isinstance(path, dict) or not isinstance(path.get("positions"), list):
            why = r.get("skip_reason") or r.get("failure_reason") or "no vlnce_path (not a VLN-CE run?)"
            raise RunError(f"{where}: episode {r.get('episode_id')}: has no path to submit ({why})"[:300])
        out.append((r, path))
    if not out:
        raise RunError(f"{where}: no episode records")
    return out


def r2r_predictions(records: list[dict[str, Any]], where: Path = Path("episodes.jsonl")) -> dict[str, list[dict]]:
    """The R2R-CE submission object (module docstring)."""
    out: dict[str, list[dict]] = {}
    for r, path in _paths(records, where):
        out[str(r["episode_id"])] = [{"position": list(p), "heading": float(h), "stop": bool(s)}
                                     for p, h, s in zip(path["positions"], path["headings"], path["stop"])]
    return out


def rxr_predictions(records: list[dict[str, Any]], where: Path = Path("episodes.jsonl")) -> list[dict[str, Any]]:
    """The RxR-CE submission lines (module docstring)."""
    out = []
    for r, path in _paths(records, where):
        iid = path.get("instruction_id")
        if not isinstance(iid, int):
            raise RunError(f"{where}: episode {r.get('episode_id')}: no instruction_id (not an RxR-CE run?)")
        out.append({"instruction_id": iid, "path": ndtw_points(path["positions"])})
    out.sort(key=lambda x: x["instruction_id"])
    return out


def missing_episodes(run_dir: Path, records: list[dict[str, Any]]) -> tuple[int, int, str] | None:
    """``(episodes the records cover, episodes in the file, the file)`` when the run's records do not cover its episode
    file (its bundled split where this checkout has it), else None. A file this machine cannot read is
    judged by config.json: a selection (limit, per-scene, shard) or a run that did not complete is partial."""
    from navbench.eval.config import recorded_paths
    from navbench.paths import split_file
    from navbench.tasks import TASKS

    cfg_path, cfg = run_dir / "config.json", {}
    try:
        cfg = json.loads(cfg_path.read_text())
        task, split = TASKS.get(cfg.get("task")), cfg.get("split")
        bundled = split_file(task.name, split) if task is not None and isinstance(split, str) else None
        episodes = bundled if bundled is not None and bundled.is_file() else Path(recorded_paths(cfg, cfg_path)[0])
        gt = {"gt": cfg["gt"]} if cfg.get("gt") else {}
        keys = {(e.scene_id, str(e.episode_id)) for e in task.read_episodes(episodes, **gt).episodes}
    except (OSError, ValueError, TypeError, AttributeError, RunError):
        cfg = cfg if isinstance(cfg, dict) else {}
        try:
            done = json.loads((run_dir / "summary.json").read_text()).get("complete", True) is not False
        except (OSError, ValueError, AttributeError):
            done = True
        selected = any(cfg.get(k) is not None for k in ("limit", "per_scene", "shard"))
        return (-1, -1, str(cfg.get("episodes") or "its episode file")) if selected or not done else None
    have = {(r.get("scene_id"), str(r.get("episode_id"))) for r in records}
    return (len(keys & have), len(keys), str(episodes)) if keys - have else None


def export_run(run_dir: str | Path, fmt: str, out: str | Path | None = None, partial: bool = False,
               note: Callable[[str], None] | None = None) -> Path:
    """Write ``run_dir``'s leaderboard file in ``fmt`` (default ``RUN/predictions.json`` for r2r-ce,
    ``RUN/predictions.jsonl`` for rxr-ce); RunError (one line) for a run that cannot be submitted, or that
    covers only part of its episode file unless ``partial`` (then ``note`` gets one line saying so)."""
    if fmt not in FORMATS:
        raise RunError(f"--format {fmt!r}: choose from {', '.join(FORMATS)}")
    run_dir = Path(run_dir)
    jsonl = run_dir / "episodes.jsonl"
    if not jsonl.is_file():
        raise RunError(f"{jsonl}: missing (is this a navbench run directory?)")
    records = read_records(jsonl)
    gap = missing_episodes(run_dir, records)
    if gap is not None:
        covered, total, episodes = gap
        what = f"covers {covered} of the {total} episodes of {episodes}" if total >= 0 else \
            f"covers only part of {episodes} (a selection, or a run that stopped early)"
        if not partial:
            raise RunError(f"{run_dir}: {what}; a leaderboard scores the whole split: --partial to write it anyway")
        if note is not None:
            note(f"navbench export: {run_dir} {what}: the file is not a whole split's submission")
    if fmt == "r2r-ce":
        text = json.dumps(r2r_predictions(records, jsonl), indent=2)
        target = Path(out) if out is not None else run_dir / "predictions.json"
    else:
        # jsonlines' Writer: json.dumps with its default separators, one object per line
        text = "".join(json.dumps(x) + "\n" for x in rxr_predictions(records, jsonl))
        target = Path(out) if out is not None else run_dir / "predictions.jsonl"
    write_private(target, text)
    return target
