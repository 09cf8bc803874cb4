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
from collections.abc import Iterable, Mapping, Sequence
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
        # a measure undefined for an episode (None: GOAT's success of a goal type the episode lacks) is left out
        vals = [float(r[k]) for r in scored if r[k] is not None]
        out[k] = math.fsum(vals) / len(vals) if vals else float("nan")
    if by is not None:
        groups: dict[str, list[Mapping[str, Any]]] = {}
        for r in scored:
            groups.setdefault(str(r.get(by)), []).append(r)
        out[f"by_{by}"] = {g: {k: v for k, v in aggregate(rs, keys=keys).items() if k != "num_skipped"}
                           for g, rs in sorted(groups.items())}
    return out


# ------------------------------------------------------------------------------------------- GOAT-Bench
GOAT_TYPES = ("object", "description", "image")
GOAT_STOP, GOAT_SUBTASK_STOP = 0, 6


def goat_metrics(subtask_types: Sequence[str], steps: Sequence[tuple[int | None, Sequence[float], float]],
                 num_goals: int | None = None, success_distance: float = 0.25,
                 max_steps: int | None = None) -> dict[str, Any]:
    """A GOAT-Bench episode's measures, as goat-bench's ``GoatDistanceToGoal``, ``GoatSuccess``,
    ``GoatSPL`` and ``GoatSoftSPL`` (``goat_bench/measurements/nav.py`` L133-512) compute them, from
    the episode's states: ``steps[0]`` is the state at reset (action None), then one per action.

    A state is ``(action, position, distance)``: the action taken (0 STOP, 6 SUBTASK_STOP, else a
    motion), the agent's position after it, and the geodesic distance from there to the view points of
    the goals of the subtask active after it (``goals[k]``; not read once ``num_goals`` subtasks are
    closed). ``subtask_types`` are the types of the episode's ``tasks``; ``num_goals`` is
    ``len(episode.goals)`` (default: as many as tasks; fewer after a dropped description).

    As the reference code does:

    * SUBTASK_STOP closes subtask k and starts k + 1 at once from the same pose; subtask k succeeds iff
      the distance before the action (at the stopping pose, to goals[k]) is < ``success_distance``.
    * The episode ends at STOP (every subtask not closed scores 0), when ``num_goals`` subtasks are
      closed, or after ``max_steps`` actions.
    * ``spl_k = success_k * d0_k / max(d0_k, L_k)`` and ``softspl_k = max(0, 1 - d_k / d0_k) *
      d0_k / max(d0_k, L_k)``, ``d0_k`` the distance when subtask k started, ``L_k`` the length walked
      since, both taken at its SUBTASK_STOP; ``composite_spl`` / ``composite_softspl`` their sums over all
      tasks, ``partial_success`` the share of tasks that succeeded, ``composite_success`` all of them.
    * ``task_success`` = all succeeded **and** STOP called: never 1, since the last SUBTASK_STOP ends the
      episode. ``{type}_success`` = that type's successes / its tasks, and 0.0 when the episode has no
      success of that type, including when it has no task of that type.

    Beside them, named distinctly: ``task_success_corrected`` (all subtasks succeeded: the episode was
    completed as the task meant), ``{type}_success_corrected`` (NaN when the episode has no subtask of
    that type, so a mean over episodes skips it), ``softspl_by_subtask`` and ``d0_by_subtask``.
    Where the reference divides 0 by 0 (a subtask that starts on a view point and is closed without a
    move: a ZeroDivisionError there), :func:`path_ratio` and :func:`soft_success` decide (1 and 1).
    """
    types = [str(t) for t in subtask_types]
    n = len(types)
    goals = n if num_goals is None else int(num_goals)
    if n == 0 or not 0 < goals <= n or any(t not in GOAT_TYPES for t in types):
        raise ValueError(f"goat_metrics: needs 1 <= num_goals <= len(subtask_types) and types in {GOAT_TYPES}")
    if not steps or steps[0][0] is not None:
        raise ValueError("goat_metrics: steps[0] must be the state at reset (action None)")
    success = [0.0] * n
    spl_k = [0.0] * n
    softspl_k = [0.0] * n
    d0_k = [float("nan")] * n
    k, stopped, ended = 0, False, False
    _, pos, d = steps[0]
    prev_pos = [float(v) for v in pos]
    d = float(d)
    d0_k[0] = d0 = d
    walked = 0.0
    for i, (action, pos, dist) in enumerate(steps[1:], 1):
        if ended:
            raise ValueError(f"goat_metrics: state {i} comes after the episode ended")
        a = int(action)
        closing = a == GOAT_SUBTASK_STOP
        if a == GOAT_STOP:
            stopped = True
        elif closing:
            k += 1
        d_prev = d
        if k < goals:  # GoatDistanceToGoal: the active goal's distance; kept once the episode is over
            d = float(dist)
        pos = [float(v) for v in pos]
        walked += math.sqrt(sum((p - q) ** 2 for p, q in zip(pos, prev_pos, strict=True)))
        prev_pos = pos
        if closing:
            j = k - 1
            success[j] = float(math.isfinite(d_prev) and d_prev < success_distance)
            ratio = path_ratio(d0, walked)
            spl_k[j] = success[j] * ratio
            softspl_k[j] = soft_success(d_prev, d0) * ratio
            if k < n:
                d0_k[k] = d0 = d
            walked = 0.0
        ended = stopped or k >= goals or (max_steps is not None and i >= max_steps)
    out: dict[str, Any] = {
        "partial_success": math.fsum(success) / n,
        "composite_success": float(sum(success) == n),
        "task_success": float(sum(success) == n and stopped),
        "task_success_corrected": float(sum(success) == n),
    }
    for t in GOAT_TYPES:
        count = types.count(t)
        won = math.fsum(s for s, tt in zip(success, types, strict=True) if tt == t)
        out[f"{t}_success"] = won / count if won else 0.0
        out[f"{t}_success_corrected"] = won / count if count else float("nan")
    out.update({
        "composite_spl": math.fsum(spl_k) / n,
        "composite_softspl": math.fsum(softspl_k) / n,
        "subtask_success": success,
        "spl_by_subtask": spl_k,
        "softspl_by_subtask": softspl_k,
        "d0_by_subtask": d0_k,
        "subtasks_closed": min(k, n),
        "stop_called": stopped,
        "distance_to_goal": d,
    })
    return out
