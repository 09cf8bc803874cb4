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
NO_DIRECTION = frozenset({"path_length", "steps_taken"})  # neither more nor less is better
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


def add_intervals(summary: dict[str, Any], records: Iterable[Mapping[str, Any]], by: str | None = None,
                  metrics: Sequence[str] = METRICS) -> None:
    """Put ``ci95`` and ``ci_method`` beside the means of a summary (see :func:`navbench.metrics.aggregate`),
    and ``ci95`` into each group of its ``by_<by>`` breakdown."""
    rows = _scored(records)
    metrics = [m for m in metrics if all(r.get(m) is not None for r in rows)]  # null: not measured
    summary["ci95"], summary["ci_method"] = intervals(rows, metrics), CI_METHOD
    groups: dict[str, list[Mapping[str, Any]]] = {}
    for r in rows:
        groups.setdefault(str(r.get(by)), []).append(r)
    for g, entry in (summary.get(f"by_{by}") or {}).items() if by else ():
        if isinstance(entry, dict):
            entry["ci95"] = intervals(groups.get(g, []), metrics)


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


def _measured(pair_: tuple[Mapping[str, Any], Mapping[str, Any]], metric: str) -> bool:
    return pair_[0].get(metric) is not None and pair_[1].get(metric) is not None


def _paired(pairs: Sequence[tuple[Mapping[str, Any], Mapping[str, Any]]], metrics: Sequence[str]
            ) -> dict[str, dict[str, Any]]:
    b = _matrix([p[0] for p in pairs], metrics)
    o = _matrix([p[1] for p in pairs], metrics)
    diffs = resample_means(o - b, [str(p[0].get("scene_id")) for p in pairs])
    ci = _interval(diffs)
    out = {}
    for j, m in enumerate(metrics):
        sign = -1.0 if m in LOWER_IS_BETTER else 1.0
        d = sign * diffs[:, j]
        out[m] = {
            "base": float(b[:, j].mean()), "other": float(o[:, j].mean()), "diff": float((o - b)[:, j].mean()),
            "ci95": [float(ci[0, j]), float(ci[1, j])],
            "p_better": None if m in NO_DIRECTION else float(np.mean(d > 0) + 0.5 * np.mean(d == 0)),
            "mde": float(MDE_FACTOR * diffs[:, j].std(ddof=1)),
        }
    return out


def compare_records(base: Iterable[Mapping[str, Any]], other: Iterable[Mapping[str, Any]],
                    metrics: Sequence[str] = METRICS) -> dict[str, Any]:
    """Paired comparison on the shared episodes: per metric both means, ``diff`` = OTHER - BASE, its
    two-stage bootstrap ``ci95``, ``p_better`` (the share of resamples whose mean difference favours
    OTHER, ties counted half; for distance_to_goal lower is better; None for a measure with no better
    direction: path length, steps) and ``mde`` (``MDE_FACTOR`` x the bootstrap standard error of the
    difference). A measure some records hold no value of (null: GOAT-Bench's corrected per-type success of
    an episode without that type, nDTW without a gt file) is compared on the pairs where both runs have
    it, from its own draws, and says on how many (``episodes``); one no pair has is listed under
    ``unmeasured``."""
    pairs, dropped = pair(base, other)
    if not pairs:
        raise StatsError("the runs share no scored episode")
    scenes = [str(p[0].get("scene_id")) for p in pairs]
    out: dict[str, Any] = {"episodes": len(pairs), "scenes": len(set(scenes)), "dropped": dropped, "metrics": {}}
    full = [m for m in metrics if all(_measured(p, m) for p in pairs)]
    results = _paired(pairs, full) if full else {}
    unmeasured = []
    for m in metrics:
        if m in results:
            continue
        some = [p for p in pairs if _measured(p, m)]
        if some:
            results[m] = {**_paired(some, [m])[m], "episodes": len(some)}
        else:
            unmeasured.append(m)
    out["metrics"] = {m: results[m] for m in metrics if m in results}
    if unmeasured:
        out["unmeasured"] = unmeasured
    return out


# ------------------------------------------------------------------------------------------ run dirs
def _episode_set(run_dir: Path) -> str:
    """What names a run's episode file: its sha256 from provenance.json; for a run written before
    provenance.json, the sha256 of the file its config.json names (a bundled split as this checkout
    keeps it; only a regular file is read), else its split or file name."""
    from navbench.eval.provenance import sha256
    from navbench.paths import split_file

    sha = doc_get(read_run_doc(run_dir, "provenance.json"), "files", "episodes", "sha256")
    if isinstance(sha, str):
        return sha
    cfg = read_run_doc(run_dir, "config.json")
    if not cfg:
        return "?"
    name = str(cfg.get("split") or Path(str(cfg.get("episodes"))).name)
    if isinstance(cfg.get("benchmark"), dict) and cfg["benchmark"].get("episodes_sha256"):
        return str(cfg["benchmark"]["episodes_sha256"])  # a generated benchmark's file, named relative to it
    try:
        path = split_file(cfg["task"], cfg["split"]) if cfg.get("split") else Path(str(cfg["episodes"]))
        return sha256(path) if path.is_file() else name
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


def read_run_doc(run_dir: Path, name: str) -> dict[str, Any]:
    """A run directory's JSON file as an object, read up to RUN_FILE_CAP; {} when absent or unreadable (what
    it would have said is then unknown, and nothing is claimed about it)."""
    import json

    from navbench.eval.provenance import RUN_FILE_CAP
    from navbench.safeio import read_input

    try:
        doc = json.loads(read_input(run_dir / name, RUN_FILE_CAP, gunzip=False))
    except (OSError, ValueError, RecursionError):
        return {}
    return doc if isinstance(doc, dict) else {}


def doc_get(doc: Any, *keys: str) -> Any:
    """``doc[k1][k2]...``, None where a level is missing or not an object."""
    for k in keys:
        doc = doc.get(k) if isinstance(doc, dict) else None
    return doc


def _shown(v: Any) -> str:
    from navbench.safeio import printable

    return printable("-" if v is None else str(v), 120)


def _file_named(entry: Any, fallback: Any) -> str | None:
    """``path (sha256 0123456789ab)`` of a provenance ``files`` entry, else the path config.json gives."""
    path = doc_get(entry, "path") or fallback
    sha = doc_get(entry, "sha256")
    if path is None and sha is None:
        return None
    return f"{_shown(path)}" + (f" (sha256 {_shown(sha)[:12]})" if isinstance(sha, str) else "")


def _difference(field: str, base: Any, other: Any, line: str, in_protocol: bool = False) -> dict[str, Any]:
    return {"field": field, "in_protocol": in_protocol, "base": base, "other": other, "line": line}


def _split_files(prov: dict[str, Any]) -> dict[str, Any] | None:
    """A run's split as provenance.json records it, ``{name: sha256}`` of every file it was read from (the
    episode file as ``the episode file``); None for a run recorded before its other files were hashed."""
    entry = doc_get(prov, "files", "episodes")
    if not isinstance(doc_get(entry, "split_sha256"), str):
        return None
    files = doc_get(entry, "split_files")
    return {"the episode file": entry.get("sha256"), **(files if isinstance(files, dict) else {})}


def _split_named(entry: Any, fallback: Any) -> str | None:
    """``path (sha256 0123456789ab)`` of the episode file, or ``(split sha256 ...)`` when its split has
    other files too."""
    if isinstance(doc_get(entry, "split_files"), dict) and isinstance(doc_get(entry, "split_sha256"), str):
        return f"{_shown(doc_get(entry, 'path') or fallback)} (split sha256 {_shown(entry['split_sha256'])[:12]})"
    return _file_named(entry, fallback)


def _episode_differences(base: Path, other: Path, cfg: dict[Path, Any], prov: dict[Path, Any]
                         ) -> list[dict[str, Any]]:
    """The ``episodes`` difference when the runs read different splits (every file of each, where both runs
    recorded them all; else the episode files), or a ``split_files`` note when only one run recorded the
    split's other files and the episode files agree."""
    names = {d: _split_named(doc_get(prov[d], "files", "episodes"), cfg[d].get("split") or cfg[d].get("episodes"))
             for d in (base, other)}
    splits = {d: _split_files(prov[d]) for d in (base, other)}
    if splits[base] is not None and splits[other] is not None:
        ids = {d: doc_get(prov[d], "files", "episodes", "split_sha256") for d in (base, other)}
        if ids[base] == ids[other]:
            return []
        a, b = splits[base], splits[other]
        differing = [n for n in sorted(set(a) | set(b)) if a.get(n) != b.get(n)]
        shown = ", ".join(_shown(n) for n in differing[:4]) + (f" and {len(differing) - 4} more"
                                                                 if len(differing) > 4 else "")
        return [_difference("episodes", ids[base], ids[other],
                            f"episode file {names[base]} vs {names[other]}: {shown} differ")]
    sets = {d: _episode_set(d) for d in (base, other)}
    if sets[base] != sets[other]:
        return [_difference("episodes", sets[base], sets[other], f"episode file {names[base]} vs {names[other]}")]
    more = {d: len(splits[d]) - 1 if splits[d] is not None else None for d in (base, other)}
    if any(n for n in more.values()):
        unrecorded = " and ".join(w for w, d in (("BASE", base), ("OTHER", other)) if more[d] is None)
        return [_difference("split_files", more[base], more[other],
                            f"split files: {unrecorded} recorded the episode file's sha256 only, not the other "
                            f"files its split is read from (content/, gt): paired on the episode file alone")]
    return []


def run_differences(base: Path, other: Path, base_records: Sequence[Mapping[str, Any]] | None = None,
                    other_records: Sequence[Mapping[str, Any]] | None = None) -> list[dict[str, Any]]:
    """What differs between two runs that can explain a gap in their numbers, each with both values (BASE's
    first) and a ``line`` saying it: the protocol's fields (``in_protocol``), then the split by checksum (the
    episode file and every other file it is read from: habitat-lab's ``content/`` files, VLN-CE's gt file),
    the subset of one file each ran (from their records), the agent and each of its settings (config.json's
    ``agent_options``), the checkpoint and seed, and navbench's version, torch's build and the device. A value
    a run directory does not record shows as ``-``."""
    from navbench.eval.provenance import protocol_differences, protocol_value, recorded_run_on, run_protocol

    out = [_difference(k, a, b, f"{k} {protocol_value(k, a)} vs {protocol_value(k, b)}", True)
           for k, a, b in protocol_differences(run_protocol(base), run_protocol(other))]
    cfg = {d: read_run_doc(d, "config.json") for d in (base, other)}
    prov = {d: read_run_doc(d, "provenance.json") for d in (base, other)}

    def add(field: str, a: Any, b: Any, line: str | None = None) -> None:
        if a != b:
            out.append(_difference(field, a, b, line or f"{field} {_shown(a)} vs {_shown(b)}"))

    episodes = _episode_differences(base, other, cfg, prov)
    out += episodes
    if not any(x["field"] == "episodes" for x in episodes) and base_records is not None \
            and other_records is not None:
        keys = [{_key(r) for r in recs} for recs in (base_records, other_records)]
        common = len(keys[0] & keys[1])
        if keys[0] != keys[1]:
            how = (f"paired on the {common} both ran" if keys[0] <= keys[1] or keys[1] <= keys[0]
                   else f"{common} in common, paired on those")
            add("episode_subset", len(keys[0]), len(keys[1]),
                f"the same episodes file, {len(keys[0])} vs {len(keys[1])} of its episodes: {how}")
    add("agent", cfg[base].get("agent"), cfg[other].get("agent"))
    # each setting by name (--noise, --perception, --decoding...), not the runs' labels; of two agents, the
    # settings both have
    opts = {d: cfg[d].get("agent_options") if isinstance(cfg[d].get("agent_options"), dict) else {}
            for d in (base, other)}
    same_agent = cfg[base].get("agent") == cfg[other].get("agent")
    names = set(opts[base]) | set(opts[other]) if same_agent else set(opts[base]) & set(opts[other])
    for k in sorted(names - {"checkpoint"}):
        add(k, opts[base].get(k), opts[other].get(k))
    ckpt = {d: _file_named(doc_get(prov[d], "files", "checkpoint"), doc_get(cfg[d], "agent_options", "checkpoint"))
            for d in (base, other)}
    if doc_get(prov[base], "files", "checkpoint", "sha256") != doc_get(prov[other], "files", "checkpoint", "sha256") \
            or ckpt[base] != ckpt[other]:
        add("checkpoint", ckpt[base], ckpt[other], f"checkpoint {_shown(ckpt[base])} vs {_shown(ckpt[other])}")
    add("seed", cfg[base].get("seed"), cfg[other].get("seed"))

    def origin(doc: dict[str, Any]) -> str | None:
        n = doc_get(doc, "navbench")
        if not isinstance(n, dict) or n.get("version") is None:
            return None
        commit = n.get("git_commit")
        return f"{n['version']}" + (f" (git {str(commit)[:10]}{', dirty' if n.get('git_dirty') else ''})"
                                    if commit else "")
    add("navbench", origin(prov[base]), origin(prov[other]))
    add("torch", doc_get(prov[base], "versions", "torch"), doc_get(prov[other], "versions", "torch"))
    on = {d: recorded_run_on(d) for d in (base, other)}
    if on[base] != on[other]:
        a, b = (f"{on[d]['device']} {on[d]['precision']}" for d in (base, other))
        same = not any(x["in_protocol"] for x in out)
        noise = ": the same protocol; records differ in float rounding, so a difference includes that noise " \
                "(docs/comparing.md)"
        add("device", a, b, f"run on {a} vs {b}" + (noise if same else ""))
    return out


def task_metrics(task: str) -> tuple[str, ...]:
    """The measures ``compare`` takes for a task's runs: those its records hold (:attr:`Task.measures`)."""
    from navbench.tasks import TASKS

    known = TASKS.get(task)
    return known.measures if known is not None else METRICS


def headline_metrics(task: str) -> tuple[str, ...]:
    """What ``compare`` reports for a task's runs without ``--metric`` (:attr:`Task.headline_measures`)."""
    from navbench.tasks import TASKS

    known = TASKS.get(task)
    return known.headline_measures if known is not None else METRICS


def choose_metrics(tasks: Sequence[str], metrics: Sequence[str] | None) -> tuple[str, ...]:
    """``metrics``, each checked to be a measure of every task in ``tasks`` (a StatsError naming the valid
    ones); none given: the first task's headline measures that every task has."""
    from navbench.safeio import printable

    if not metrics:
        chosen = tuple(m for m in headline_metrics(tasks[0]) if all(m in task_metrics(t) for t in tasks))
        if not chosen:
            raise StatsError(f"runs of {' and '.join(dict.fromkeys(tasks))} share no measure: name one with --metric")
        return chosen
    for t in dict.fromkeys(tasks):
        valid = task_metrics(t)
        if bad := [m for m in metrics if m not in valid]:
            raise StatsError(f"--metric {printable(bad[0], 60)}: not a measure of {t} runs; choose from "
                             f"{', '.join(valid)}")
    return tuple(dict.fromkeys(metrics))


def compare_runs(base: str | Path, others: Sequence[str | Path], metrics: Sequence[str] | None = None,
                 mix_protocols: bool = False, per_scene: int | None = None) -> list[dict[str, Any]]:
    """:func:`compare_records` of ``base`` with each of ``others`` (run directories), refusing runs under
    another protocol (unless ``mix_protocols``) or on another split (:func:`run_differences`); with
    ``per_scene``, on the first ``per_scene`` episodes of each scene only. ``metrics``: measures of the runs'
    task (:func:`choose_metrics`), by default its headline measures, of which those no paired record has
    (nDTW without a gt file) are left out and listed under ``unmeasured``. Each result's ``differences``
    (:func:`run_differences`) say what differs, in and outside the protocol. The device and precision each
    run used are not part of the protocol: runs on the CPU and on a GPU are compared, and ``run_on`` reports
    both."""
    from navbench.eval.provenance import check_same_protocol, recorded_run_on, run_protocol
    from navbench.eval.rundir import read_records
    from navbench.safeio import printable
    from navbench.tasks import TASKS

    base, others = Path(base), [Path(o) for o in others]
    known = set(METRICS).union(*(task_metrics(t) for t in TASKS))
    if bad := [m for m in metrics or () if m not in known]:  # no task's: refused before any run is read
        raise StatsError(f"--metric {printable(bad[0], 60)}: not a measure of any task; choose from "
                         f"{', '.join(sorted(known))}")
    ids = check_same_protocol([base, *others], allow_mixed=mix_protocols)
    tasks = [str(run_protocol(d).get("task")) for d in (base, *others)]
    chosen = choose_metrics(tasks, metrics)
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
        diffs = run_differences(base, d, records[base], records[d])
        if any(x["field"] == "episodes" for x in diffs):
            why = "; ".join(x["line"] for x in diffs if x["field"] == "episodes")
            raise StatsError(f"{base} vs {d}: scored on different episode files ({why}): nothing to pair"[:1000])
        try:
            res = compare_records(records[base], records[d], chosen)
        except StatsError as exc:
            raise StatsError(f"{base} vs {d}: {exc}") from None
        if metrics and res.get("unmeasured"):
            raise StatsError(f"{base} vs {d}: no episode both runs scored has a value of "
                             f"{', '.join(res['unmeasured'])}")
        out.append({"base_run": str(base), "other_run": str(d), "task": tasks[0], "protocol_id": ids[0],
                    **({"other_protocol_id": pid} if pid != ids[0] else {}),
                    "run_on": {"base": recorded_run_on(base), "other": recorded_run_on(d)},
                    "differences": diffs, **res})
    return out


_SHOWN = {"success": "SR", "spl": "SPL", "soft_spl": "SoftSPL", "distance_to_goal": "DTG"}
_SCALE = {"distance_to_goal": (1, "m"), "path_length": (1, "m"), "steps_taken": (1, "")}  # else a share, in %


def metric_label(task: str | None, metric: str) -> tuple[str, float, str]:
    """(name, scale, unit) of a measure as compare prints it: the task's column header where its table has
    one (VLN-CE's NE, TL, nDTW...), else SR / SPL / SoftSPL / DTG, else the measure's own name."""
    from navbench.tasks import TASKS

    known = TASKS.get(task or "")
    header = next((h for h, m, _ in known.columns if m == metric), None) if known is not None else None
    k, unit = _SCALE.get(metric, (100, "%"))
    return header or _SHOWN.get(metric, metric), k, unit


def format_comparison(res: dict[str, Any]) -> str:
    """A comparison as text: who, how many episodes, and one line per metric."""
    lines = [f"BASE  {res['base_run']}", f"OTHER {res['other_run']}"]
    if "other_protocol_id" in res:
        lines.append(f"MIXED PROTOCOLS: {res['protocol_id']} vs {res['other_protocol_id']} (not comparable)")
    for x in res.get("differences", ()):
        lines.append(f"{'protocol' if x['in_protocol'] else 'differs'}: {x['line']}")
    dropped = res["dropped"]
    what = "" if not dropped else ": " + ", ".join(
        f"{n} {why}" for why, n in sorted({d["reason"]: sum(x["reason"] == d["reason"] for x in dropped)
                                            for d in dropped}.items()))
    eg = "" if not dropped else f" (e.g. episode {dropped[0]['episode_id']} of {dropped[0]['scene_id']})"
    lines.append(f"paired on {res['episodes']} episodes in {res['scenes']} scenes; dropped {len(dropped)}{what}{eg}")
    labels = {m: metric_label(res.get("task"), m) for m in res["metrics"]}
    heads = {m: (f"{name} {unit}".strip() + (f" (n={r['episodes']})" if "episodes" in r else ""))
             for (m, (name, _, unit)), r in zip(labels.items(), res["metrics"].values())}
    w = max([10, *(len(h) + 1 for h in heads.values())])
    lines.append(f"{'metric':<{w}}{'base':>8}{'other':>8}{'diff':>8}  {'95% CI of diff':<18}{'P(other better)':>16}"
                 f"{'detectable':>12}")
    for m, r in res["metrics"].items():
        _, k, _ = labels[m]
        lo, hi = (k * v for v in r["ci95"])
        better = "-" if r["p_better"] is None else f"{r['p_better']:.3f}"
        lines.append(f"{heads[m]:<{w}}{k * r['base']:>8.1f}{k * r['other']:>8.1f}{k * r['diff']:>+8.1f}  "
                     f"{f'[{lo:+.1f}, {hi:+.1f}]':<18}{better:>16}{k * r['mde']:>12.1f}")
    if res.get("unmeasured"):
        lines.append("not measured in these runs' records: " + ", ".join(
            metric_label(res.get("task"), m)[0] for m in res["unmeasured"]))
    return "\n".join(lines)
