"""Navigation metrics as pure functions, with Habitat's definitions (a leaf module: the env reports them
running in ``info``, the evaluator aggregates them over per-episode records).

- success  = STOP was called and the geodesic distance to the nearest goal < success distance.
- SPL      = S * d0 / max(d0, path_length)           (Anderson et al. 2018; Habitat's ``SPL``)
- SoftSPL  = max(0, 1 - d / d0) * d0 / max(d0, path_length), no STOP needed (Habitat's ``SoftSPL``)
- distance_to_goal = geodesic distance to the nearest goal (view point) at the end of the episode.

``d0`` is the geodesic distance from the start to the nearest goal, ``path_length`` the sum of the
straight-line lengths of the steps the agent actually made (collisions shorten a step).

Edge cases Habitat leaves undefined (it would divide by zero), decided here:
- d0 == 0 (the agent starts on the goal): the path ratio is 1 when the agent did not move and 0 when
  it did, so SPL = S when it stops at once; soft success is 1 if d == 0 else 0.
- d0 == inf (unreachable goal): never a success and all ratios are 0; the evaluator skips such
  episodes with a recorded reason instead of scoring them.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any


def is_success(stop_called: bool, distance_to_goal: float, success_distance: float) -> bool:
    return bool(stop_called) and math.isfinite(distance_to_goal) and distance_to_goal < success_distance


def path_ratio(d0: float, path_length: float) -> float:
    """d0 / max(d0, path_length) with the d0 == 0 and d0 == inf cases defined (see module docstring)."""
    if not math.isfinite(d0):
        return 0.0
    denom = max(d0, path_length)
    if denom == 0.0:
        return 1.0
    return d0 / denom


def spl(success: bool, d0: float, path_length: float) -> float:
    return float(success) * path_ratio(d0, path_length)


def soft_success(distance_to_goal: float, d0: float) -> float:
    if not (math.isfinite(d0) and math.isfinite(distance_to_goal)):
        return 0.0
    if d0 == 0.0:
        return 1.0 if distance_to_goal == 0.0 else 0.0
    return max(0.0, 1.0 - distance_to_goal / d0)


def soft_spl(distance_to_goal: float, d0: float, path_length: float) -> float:
    return soft_success(distance_to_goal, d0) * path_ratio(d0, path_length)


def episode_metrics(stop_called: bool, distance_to_goal: float, d0: float, path_length: float,
                    success_distance: float) -> dict[str, float]:
    """All per-episode metrics from the four quantities an episode produces."""
    s = is_success(stop_called, distance_to_goal, success_distance)
    return {
        "success": float(s),
        "spl": spl(s, d0, path_length),
        "soft_spl": soft_spl(distance_to_goal, d0, path_length),
        "distance_to_goal": float(distance_to_goal),
    }


METRIC_KEYS = ("success", "spl", "soft_spl", "distance_to_goal")


def aggregate(records: Iterable[Mapping[str, Any]], by: str | None = None,
              keys: tuple[str, ...] = METRIC_KEYS) -> dict[str, Any]:
    """Mean of each metric (``keys``: Habitat's four, and a task's own) over scored records (skipped episodes
    excluded, and counted).

    With ``by`` (e.g. ``"object_category"``) also returns ``{"by_<by>": {value: {...means...}}}``.
    Records are sorted by episode id first so floating-point sums do not depend on finishing order.
    """
    rows = sorted(records, key=lambda r: (str(r.get("scene_id", "")), str(r.get("episode_id", ""))))
    scored = [r for r in rows if not r.get("skipped")]
    out: dict[str, Any] = {"num_episodes": len(scored), "num_skipped": len(rows) - len(scored)}
    for k in keys:
        vals = [float(r[k]) for r in scored]
        out[k] = math.fsum(vals) / len(vals) if vals else float("nan")
    if by is not None:
        groups: dict[str, list[Mapping[str, Any]]] = {}
        for r in scored:
            groups.setdefault(str(r.get(by)), []).append(r)
        out[f"by_{by}"] = {g: {k: v for k, v in aggregate(rs, keys=keys).items() if k != "num_skipped"}
                           for g, rs in sorted(groups.items())}
    return out
