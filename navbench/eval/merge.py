"""Join shard runs (``navbench run --shard I/N``) into one run directory, as one unsharded run would write it.

    navbench merge runs/shards/* --out runs/pointnav/val/pointnav

The shards must share their config apart from the shard itself and how they were run (workers, episodes
per worker, navbench version, as ``--resume`` allows), share their protocol (provenance.json), and together
hold every selected episode of the episode file exactly once; anything else is refused with a one-line error.
The merged ``episodes.jsonl``
lists the records in the episode file's order.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from navbench.episodes.io import load_dataset
from navbench.eval.config import RunConfig, recorded_paths, selector
from navbench.eval.provenance import check_same_protocol, merge_provenance
from navbench.eval.records import summary_text
from navbench.eval.rundir import RunError, RunLock, make_run_dir, read_records, write_atomic
from navbench.eval.runner import config_diff, summarize

# Keys shards may differ in: how each was run, not what it computes.
_MERGE_FREE_KEYS = ("shard", "workers", "envs_per_worker", "navbench_version", "benchmark_dir")


def _config(d: Path) -> dict[str, Any]:
    path = d / "config.json"
    if not path.is_file():
        raise RunError(f"{path}: missing (not a run directory)")
    try:
        cfg = json.loads(path.read_text())
        if not isinstance(cfg, dict):
            raise ValueError
        return cfg
    except ValueError:
        raise RunError(f"{path}: corrupt JSON") from None


def merge(run_dirs: list[Path], out: Path, overwrite: bool = False, note=print) -> dict[str, Any]:
    """Merge ``run_dirs`` into ``out``; returns the merged run's summary."""
    run_dirs = [Path(d) for d in run_dirs]
    out = Path(out)
    if out.resolve() in {d.resolve() for d in run_dirs}:
        raise RunError(f"{out}: the merged run must go to a directory of its own")
    configs = [_config(d) for d in run_dirs]
    first = configs[0]
    for d, c in zip(run_dirs[1:], configs[1:]):
        diff = config_diff(first, c, _MERGE_FREE_KEYS)
        if diff:
            raise RunError(f"{d / 'config.json'}: differs from {run_dirs[0] / 'config.json'} in {', '.join(diff)}")
    check_same_protocol(run_dirs, hint="")
    shards = [c.get("shard") for c in configs]
    seen_shards: dict[str, Path] = {}
    for d, s in zip(run_dirs, shards):
        if s is not None and s in seen_shards:
            raise RunError(f"{d}: shard {s} given twice (also {seen_shards[s]})")
        seen_shards[s] = d
    cfg = RunConfig(**{k: v for k, v in first.items() if k in RunConfig.__dataclass_fields__})
    cfg.shard = None
    cfg.episodes, cfg.scene_dir = recorded_paths(first, run_dirs[0] / "config.json")
    expected = [(e.scene_id, e.episode_id) for e in load_dataset(cfg.episodes, selector(cfg.limit,
                                                                                         cfg.per_scene)).episodes]
    wanted = set(expected)
    by_key: dict[tuple[str, str], dict[str, Any]] = {}
    where: dict[tuple[str, str], Path] = {}
    for d in run_dirs:
        recs = read_records(d / "episodes.jsonl")
        for r in recs:
            key = (r["scene_id"], r["episode_id"])
            if key not in wanted:
                raise RunError(f"{d / 'episodes.jsonl'}: episode {key[1]!r} ({key[0]}) is not among the run's "
                               f"selected episodes of {cfg.episodes}")
            if key in by_key:
                raise RunError(f"{d / 'episodes.jsonl'}: episode {key[1]!r} ({key[0]}) is also in {where[key]}")
            by_key[key], where[key] = r, d / "episodes.jsonl"
    missing = [k for k in expected if k not in by_key]
    if missing:
        raise RunError(f"{len(missing)} of {len(expected)} episodes are in none of the runs, e.g. {missing[0][1]!r} "
                       f"({missing[0][0]}): a shard missing or unfinished (finish it with --resume)")
    make_run_dir(out)
    lock = RunLock(out, note)
    try:
        if not overwrite and ((out / "episodes.jsonl").exists() or (out / "config.json").exists()):
            raise RunError(f"{out} already holds a run: --overwrite to replace it, or another --out")
        records = [by_key[k] for k in expected]
        cfg_json = {k: v for k, v in first.items() if k != "shard"}
        write_atomic(out / "config.json", json.dumps(cfg_json, indent=1) + "\n")
        write_atomic(out / "episodes.jsonl", "".join(json.dumps(r) + "\n" for r in records))
        summary = summarize(records, cfg, complete=True)
        write_atomic(out / "summary.json", summary_text(summary))
        merge_provenance(run_dirs, out)
    finally:
        lock.release()
    return summary
