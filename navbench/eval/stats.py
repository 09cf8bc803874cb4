"""Confidence intervals and paired comparisons of runs, from their per-episode records.

Episodes in one scene are correlated (same layout, same objects), so intervals come from a two-stage
(cluster) bootstrap: resample the scenes with replacement, then the episodes of each drawn scene with
replacement; the statistic is the mean over all drawn episodes. One scene: episodes are resampled alone.
The interval is the 2.5th and 97.5th percentile of ``N_RESAMPLES`` resampled means (numpy's default
linear interpolation).

Draw order (so an independent implementation can reproduce the numbers exactly): records are sorted by
(scene_id, episode_id) and scenes by scene_id; ``rng = numpy.random.default_rng(SEED)``; for each resample,
``rng.integers(0, k, size=k)`` draws the k scenes (skipped with one scene), then one ``rng.random(m)``
call gives a uniform u for each of the m episodes of the drawn scenes, in draw order, and the episode
taken from a drawn scene with n episodes is its ``floor(u * n)``-th. The same draws serve every metric,
and a paired comparison resamples the per-episode differences OTHER - BASE the same way.

Skipped episodes (unreachable goal) are left out, failed ones count as failures, as in the summary.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

METRICS = ("success", "spl", "soft_spl", "distance_to_goal")
LOWER_IS_BETTER = frozenset({"distance_to_goal"})
N_RESAMPLES = 2000
SEED = 0
# Smallest detectable difference: (z_0.975 + z_0.80) x the bootstrap standard error of the mean paired
# difference, i.e. the true difference a two-sided test at alpha 0.05 detects with 80% power.
MDE_FACTOR = 2.8
CI_METHOD = (f"two-stage bootstrap (scenes, then episodes within each drawn scene, with replacement), "
             f"{N_RESAMPLES} resamples, seed {SEED}, percentile 95% interval")


class StatsError(ValueError):
    """Records that cannot be compared (nothing shared, a record without a metric); the message says why."""


def _scored(records: Iterable[Mapping[str, Any]]) -> list[Mapping[str, Any]]:
    rows = [r for r in records if not r.get("skipped")]
    return sorted(rows, key=lambda r: (str(r.get("scene_id", "")), str(r.get("episode_id", ""))))


def _groups(scenes: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """(start offset, size) of each scene's block in ``scenes`` (sorted, so each scene is contiguous)."""
    starts, sizes = [], []
    for i, s in enumerate(scenes):
        if i == 0 or s != scenes[i - 1]:
            starts.append(i)
            sizes.append(0)
        sizes[-1] += 1
    return np.asarray(starts, np.int64), np.asarray(sizes, np.int64)


def resample_means(values: np.ndarray, scenes: Sequence[str], n_resamples: int = N_RESAMPLES,
                   seed: int = SEED) -> np.ndarray:
    """``(n_resamples, n_metrics)`` two-stage bootstrap means of ``values`` (rows sorted by scene, as
    ``scenes`` names them), drawn in the order the module docstring gives."""
    values = np.asarray(values, np.float64)
    if values.ndim == 1:
        values = values[:, None]
    starts, sizes = _groups(list(scenes))
    k = len(starts)
    rng = np.random.default_rng(seed)
    out = np.empty((n_resamples, values.shape[1]))
    for b in range(n_resamples):
        drawn = rng.integers(0, k, size=k) if k > 1 else np.zeros(1, np.int64)
        n = sizes[drawn]
        u = rng.random(int(n.sum()))
        idx = np.repeat(starts[drawn], n) + np.floor(u * np.repeat(n, n)).astype(np.int64)
        out[b] = values[idx].mean(axis=0)
    return out


def _matrix(records: Sequence[Mapping[str, Any]], metrics: Sequence[str]) -> np.ndarray:
    try:
        return np.asarray([[float(r[m]) for m in metrics] for r in records], np.float64).reshape(-1, len(metrics))
    except (KeyError, TypeError, ValueError) as exc:
        raise StatsError(f"a record lacks a numeric metric ({type(exc).__name__}: {exc})") from None


def _interval(means: np.ndarray) -> np.ndarray:
    return np.percentile(means, [2.5, 97.5], axis=0)


def intervals(records: Iterable[Mapping[str, Any]], metrics: Sequence[str] = METRICS) -> dict[str, list[float]] | None:
    """``{metric: [lo, hi]}``: the two-stage bootstrap 95% interval of each metric's mean over the
    scored records; None when there are none."""
    rows = _scored(records)
    if not rows:
        return None
    ci = _interval(resample_means(_matrix(rows, metrics), [str(r.get("scene_id", "")) for r in rows]))
    return {m: [float(ci[0, j]), float(ci[1, j])] for j, m in enumerate(metrics)}


def add_intervals(summary: dict[str, Any], records: Iterable[Mapping[str, Any]], by: str | None = None) -> None:
    """Put ``ci95`` and ``ci_method`` beside the means of a summary (see :func:`navbench.metrics.aggregate`),
    and ``ci95`` into each group of its ``by_<by>`` breakdown."""
    rows = _scored(records)
    summary["ci95"], summary["ci_method"] = intervals(rows), CI_METHOD
    groups: dict[str, list[Mapping[str, Any]]] = {}
    for r in rows:
        groups.setdefault(str(r.get(by)), []).append(r)
    for g, entry in (summary.get(f"by_{by}") or {}).items() if by else ():
        if isinstance(entry, dict):
            entry["ci95"] = intervals(groups.get(g, []))


# --------------------------------------------------------------------------------------- comparison
def _key(r: Mapping[str, Any]) -> tuple[str, str]:
    return str(r.get("scene_id")), str(r.get("episode_id"))


def pair(base: Iterable[Mapping[str, Any]], other: Iterable[Mapping[str, Any]]
         ) -> tuple[list[tuple[Mapping[str, Any], Mapping[str, Any]]], list[dict[str, str]]]:
    """Records of the episodes both runs scored, as (base, other) pairs sorted by (scene, episode), and
    the episodes left out with why (``only in base``, ``only in other``, ``skipped``)."""
    b = {_key(r): r for r in base}
    o = {_key(r): r for r in other}
    pairs, dropped = [], []
    for key in sorted(set(b) | set(o)):
        why = ("only in other" if key not in b else "only in base" if key not in o
               else "skipped" if b[key].get("skipped") or o[key].get("skipped") else None)
        if why:
            dropped.append({"scene_id": key[0], "episode_id": key[1], "reason": why})
        else:
            pairs.append((b[key], o[key]))
    return pairs, dropped


def compare_records(base: Iterable[Mapping[str, Any]], other: Iterable[Mapping[str, Any]],
                    metrics: Sequence[str] = METRICS) -> dict[str, Any]:
    """Paired comparison on the shared episodes: per metric both means, ``diff`` = OTHER - BASE, its
    two-stage bootstrap ``ci95``, ``p_better`` (the share of resamples whose mean difference favours
    OTHER, ties counted half; for distance_to_goal lower is better) and ``mde`` (``MDE_FACTOR`` x the
    bootstrap standard error of the difference)."""
    pairs, dropped = pair(base, other)
    if not pairs:
        raise StatsError("the runs share no scored episode")
    b = _matrix([p[0] for p in pairs], metrics)
    o = _matrix([p[1] for p in pairs], metrics)
    scenes = [str(p[0].get("scene_id")) for p in pairs]
    diffs = resample_means(o - b, scenes)
    ci = _interval(diffs)
    out: dict[str, Any] = {"episodes": len(pairs), "scenes": len(set(scenes)), "dropped": dropped, "metrics": {}}
    for j, m in enumerate(metrics):
        sign = -1.0 if m in LOWER_IS_BETTER else 1.0
        d = sign * diffs[:, j]
        out["metrics"][m] = {
            "base": float(b[:, j].mean()), "other": float(o[:, j].mean()), "diff": float((o - b)[:, j].mean()),
            "ci95": [float(ci[0, j]), float(ci[1, j])],
            "p_better": float(np.mean(d > 0) + 0.5 * np.mean(d == 0)),
            "mde": float(MDE_FACTOR * diffs[:, j].std(ddof=1)),
        }
    return out


# ------------------------------------------------------------------------------------------ run dirs
def _episode_set(run_dir: Path) -> str:
    """What names a run's episode file: its sha256 from provenance.json; for a run written before
    provenance.json, the sha256 of the file its config.json names (a bundled split as this checkout
    keeps it), else its split or file name."""
    import json

    from navbench.eval.provenance import sha256
    from navbench.paths import split_file

    try:
        return json.loads((run_dir / "provenance.json").read_text())["files"]["episodes"]["sha256"]
    except (OSError, ValueError, KeyError, TypeError):
        pass
    try:
        cfg = json.loads((run_dir / "config.json").read_text())
        name = str(cfg.get("split") or Path(str(cfg.get("episodes"))).name)
        if isinstance(cfg.get("benchmark"), dict) and cfg["benchmark"].get("episodes_sha256"):
            return str(cfg["benchmark"]["episodes_sha256"])  # a generated benchmark's file, named relative to it
    except (OSError, ValueError, AttributeError):
        return "?"
    try:
        return sha256(split_file(cfg["task"], cfg["split"]) if cfg.get("split") else Path(str(cfg["episodes"])))
    except (OSError, ValueError, KeyError, TypeError):
        return name


def first_per_scene(run_dir: Path, k: int) -> set[tuple[str, str]]:
    """(scene_id, episode_id) of the first ``k`` episodes of each scene of the run's episode file (file
    order; a bundled split is read where this checkout keeps it)."""
    import json

    from navbench.eval.config import recorded_paths, select_episodes
    from navbench.paths import split_file
    from navbench.tasks import get_task

    cfg = json.loads((run_dir / "config.json").read_text())
    bundled = split_file(cfg["task"], cfg["split"]) if cfg.get("split") else None
    path = bundled if bundled is not None and bundled.is_file() else \
        Path(recorded_paths(cfg)[0])
    dataset = get_task(cfg["task"]).read_episodes(path)  # the task's own reader (an InstanceImageNav file's goals)
    return {(e.scene_id, e.episode_id) for e in select_episodes(dataset, None, per_scene=k)}


def compare_runs(base: str | Path, others: Sequence[str | Path], metrics: Sequence[str] = METRICS,
                 mix_protocols: bool = False, per_scene: int | None = None) -> list[dict[str, Any]]:
    """:func:`compare_records` of ``base`` with each of ``others`` (run directories), refusing runs under
    another protocol (unless ``mix_protocols``) or on another episode file; with ``per_scene``, on the
    first ``per_scene`` episodes of each scene only. The device and precision each run used are not part
    of the protocol: runs on the CPU and on a GPU are compared, and ``run_on`` reports both."""
    from navbench.eval.provenance import check_same_protocol, recorded_run_on
    from navbench.eval.rundir import read_records

    base, others = Path(base), [Path(o) for o in others]
    ids = check_same_protocol([base, *others], allow_mixed=mix_protocols)
    records = {}
    for d in (base, *others):
        if not (d / "episodes.jsonl").is_file():
            raise StatsError(f"{d / 'episodes.jsonl'}: missing (is this a navbench run directory?)")
        records[d] = read_records(d / "episodes.jsonl")
    if per_scene is not None:
        try:
            keep = first_per_scene(base, per_scene)
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise StatsError(f"{base / 'config.json'}: cannot read the run's episode file ({exc})"[:300]) from None
        records = {d: [r for r in recs if (str(r.get("scene_id")), str(r.get("episode_id"))) in keep]
                   for d, recs in records.items()}
    out = []
    for d, pid in zip(others, ids[1:]):
        if _episode_set(d) != _episode_set(base):
            raise StatsError(f"{d}: scored on another episode file than {base} ({_episode_set(d)[:16]} vs "
                             f"{_episode_set(base)[:16]}): nothing to pair")
        try:
            res = compare_records(records[base], records[d], metrics)
        except StatsError as exc:
            raise StatsError(f"{d} vs {base}: {exc}") from None
        out.append({"base_run": str(base), "other_run": str(d), "protocol_id": ids[0],
                    **({"other_protocol_id": pid} if pid != ids[0] else {}),
                    "run_on": {"base": recorded_run_on(base), "other": recorded_run_on(d)}, **res})
    return out


_SHOWN = {"success": ("SR", 100, "%"), "spl": ("SPL", 100, "%"), "soft_spl": ("SoftSPL", 100, "%"),
          "distance_to_goal": ("DTG", 1, "m")}


def format_comparison(res: dict[str, Any]) -> str:
    """A comparison as text: who, how many episodes, and one line per metric."""
    lines = [f"BASE  {res['base_run']}", f"OTHER {res['other_run']}"]
    if "other_protocol_id" in res:
        lines.append(f"MIXED PROTOCOLS: {res['protocol_id']} vs {res['other_protocol_id']} (not comparable)")
    on = res.get("run_on") or {}
    if on and on["base"] != on["other"]:  # not the protocol: compared, and said
        b, o = on["base"], on["other"]
        lines.append(f"run on {b['device']} {b['precision']} vs {o['device']} {o['precision']}: the same protocol; "
                     f"records differ in float rounding, so a difference includes that noise (docs/comparing.md)")
    dropped = res["dropped"]
    what = "" if not dropped else ": " + ", ".join(
        f"{n} {why}" for why, n in sorted({d["reason"]: sum(x["reason"] == d["reason"] for x in dropped)
                                            for d in dropped}.items()))
    eg = "" if not dropped else f" (e.g. episode {dropped[0]['episode_id']} of {dropped[0]['scene_id']})"
    lines.append(f"paired on {res['episodes']} episodes in {res['scenes']} scenes; dropped {len(dropped)}{what}{eg}")
    lines.append(f"{'metric':<10}{'base':>8}{'other':>8}{'diff':>8}  {'95% CI of diff':<18}{'P(other better)':>16}"
                 f"{'detectable':>12}")
    for m, r in res["metrics"].items():
        name, k, unit = _SHOWN[m]
        lo, hi = (k * v for v in r["ci95"])
        lines.append(f"{name + ' ' + unit:<10}{k * r['base']:>8.1f}{k * r['other']:>8.1f}{k * r['diff']:>+8.1f}  "
                     f"{f'[{lo:+.1f}, {hi:+.1f}]':<18}{r['p_better']:>16.3f}{k * r['mde']:>12.1f}")
    return "\n".join(lines)
