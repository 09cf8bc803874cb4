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
              keys: Iterable[str] = METRIC_KEYS) -> dict[str, Any]:
    """Mean of each metric (``keys``: a task's measures) over scored records (skipped episodes excluded, and
    counted); a plain mean, as VLN-CE's and Habitat's evaluations take it (an infinite distance makes it inf).

    With ``by`` (e.g. ``"object_category"``) also returns ``{"by_<by>": {value: {...means...}}}``.
    Records are sorted by episode id first so floating-point sums do not depend on finishing order.
    """
    rows = sorted(records, key=lambda r: (str(r.get("scene_id", "")), str(r.get("episode_id", ""))))
    scored = [r for r in rows if not r.get("skipped")]
    out: dict[str, Any] = {"num_episodes": len(scored), "num_skipped": len(rows) - len(scored)}
    keys = tuple(keys)
    for k in keys:
        # a measure undefined for an episode (None: GOAT's success of a goal type the episode lacks) is left
        # out; one measured for none (a split without goals or gt paths) has no mean
        vals = [float(r[k]) for r in scored if r[k] is not None]
        if scored and not vals:
            out[k] = None
            continue
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
    measures = GoatMeasures(subtask_types, num_goals, success_distance, max_steps)
    if not steps:
        raise ValueError("goat_metrics: steps[0] must be the state at reset (action None)")
    measures.reset(steps[0])
    for state in steps[1:]:
        measures.step(state)
    return measures.result()


class GoatMeasures:
    """:func:`goat_metrics` kept up to date one state at a time, O(1) per step: ``GoatMeasures(subtask_types,
    num_goals, success_distance, max_steps)``, then :meth:`reset` with the state at reset, :meth:`step` with
    each later state, and :meth:`result` for the measures so far (``goat_metrics`` runs a whole sequence
    through it)."""

    def __init__(self, subtask_types: Sequence[str], num_goals: int | None = None,
                 success_distance: float = 0.25, max_steps: int | None = None) -> None:
        self.types = [str(t) for t in subtask_types]
        n = len(self.types)
        self.goals = n if num_goals is None else int(num_goals)
        if n == 0 or not 0 < self.goals <= n or any(t not in GOAT_TYPES for t in self.types):
            raise ValueError(f"goat_metrics: needs 1 <= num_goals <= len(subtask_types) and types in {GOAT_TYPES}")
        self.success_distance, self.max_steps = success_distance, max_steps
        self._started = False

    def reset(self, state: tuple[int | None, Sequence[float], float]) -> None:
        action, pos, d = state
        if action is not None:
            raise ValueError("goat_metrics: steps[0] must be the state at reset (action None)")
        n = len(self.types)
        self.success = [0.0] * n
        self.spl_k = [0.0] * n
        self.softspl_k = [0.0] * n
        self.d0_k = [float("nan")] * n
        self.k, self.stopped, self.ended, self.i = 0, False, False, 0
        self.prev_pos = [float(v) for v in pos]
        self.d = float(d)
        self.d0_k[0] = self.d0 = self.d
        self.walked = 0.0
        self._started = True

    def step(self, state: tuple[int | None, Sequence[float], float]) -> None:
        if not self._started:
            raise ValueError("goat_metrics: steps[0] must be the state at reset (action None)")
        action, pos, dist = state
        self.i += 1
        if self.ended:
            raise ValueError(f"goat_metrics: state {self.i} comes after the episode ended")
        a = int(action)  # type: ignore[arg-type]
        closing = a == GOAT_SUBTASK_STOP
        if a == GOAT_STOP:
            self.stopped = True
        elif closing:
            self.k += 1
        d_prev = self.d
        if self.k < self.goals:
            self.d = float(dist)
        pos = [float(v) for v in pos]
        self.walked += math.sqrt(sum((p - q) ** 2 for p, q in zip(pos, self.prev_pos, strict=True)))
        self.prev_pos = pos
        if closing:
            j = self.k - 1
            self.success[j] = float(math.isfinite(d_prev) and d_prev < self.success_distance)
            ratio = path_ratio(self.d0, self.walked)
            self.spl_k[j] = self.success[j] * ratio
            self.softspl_k[j] = soft_success(d_prev, self.d0) * ratio
            if self.k < len(self.types):
                self.d0_k[self.k] = self.d0 = self.d
            self.walked = 0.0
        self.ended = self.stopped or self.k >= self.goals or (self.max_steps is not None and self.i >= self.max_steps)

    def result(self) -> dict[str, Any]:
        if not self._started:
            raise ValueError("goat_metrics: steps[0] must be the state at reset (action None)")
        types, success, n = self.types, self.success, len(self.types)
        out: dict[str, Any] = {
            "partial_success": math.fsum(success) / n,
            "composite_success": float(sum(success) == n),
            "task_success": float(sum(success) == n and self.stopped),
            "task_success_corrected": float(sum(success) == n),
        }
        for t in GOAT_TYPES:
            count = types.count(t)
            won = math.fsum(s for s, tt in zip(success, types, strict=True) if tt == t)
            out[f"{t}_success"] = won / count if won else 0.0
            out[f"{t}_success_corrected"] = won / count if count else float("nan")
        out.update({
            "composite_spl": math.fsum(self.spl_k) / n,
            "composite_softspl": math.fsum(self.softspl_k) / n,
            "subtask_success": list(success),
            "spl_by_subtask": list(self.spl_k),
            "softspl_by_subtask": list(self.softspl_k),
            "d0_by_subtask": list(self.d0_k),
            "subtasks_closed": min(self.k, n),
            "stop_called": self.stopped,
            "distance_to_goal": self.d,
        })
        return out


# ------------------------------------------------------------------------------------------- VLN-CE
# The measures of VLN-CE (R2R-CE, RxR-CE) as its reference code computes them: jacobkrantz/VLN-CE
# habitat_extensions/measures.py (PathLength, OracleSuccess, StepsTaken, NDTW, SDTW) and habitat-lab v0.1.7
# habitat/tasks/nav/nav.py (DistanceToGoal, Success, SPL). An episode is its positions p_0 (at reset) ..
# p_T (after each of its T actions, STOP included) and the geodesic distances d_t from p_t to the goal point.
# Habitat holds positions as float32; the functions below take them through float32 as it does.

VLNCE_SUCCESS_DISTANCE = 3.0  # TASK.SUCCESS.SUCCESS_DISTANCE, ORACLE_SUCCESS and NDTW's, in both task yamls
VLNCE_METRIC_KEYS = ("distance_to_goal", "success", "oracle_success", "spl", "path_length", "steps_taken",
                     "ndtw", "sdtw", "ndtw_exact")


def habitat_positions(positions: Iterable[Any]) -> list[list[float]]:
    """Positions as ``sim.get_agent_state().position.tolist()`` gives them: float32 values as Python floats."""
    import numpy as np
    return np.asarray(list(positions), np.float32).reshape(-1, 3).tolist()


def ndtw_points(positions: Iterable[Any]) -> list[list[float]]:
    """The agent path nDTW compares: the start, then each position that differs exactly from the previous
    one kept (consecutive repeats dropped; a revisit of an earlier position is kept), as NDTW.update_metric."""
    out: list[list[float]] = []
    for p in habitat_positions(positions):
        if not out or p != out[-1]:
            out.append(p)
    return out


def vlnce_path_length(positions: Iterable[Any]) -> float:
    """PathLength: the sum of the 3-D Euclidean step lengths (the reference's docstring says geodesic; its code
    is Euclidean). Each step's norm is taken in float32 as numpy does for habitat's float32 positions, and
    summed in float64 (Python 3.6 / NumPy 1.x, the reference's, promotes ``0.0 + float32`` to float64)."""
    import numpy as np
    pts = np.asarray(list(positions), np.float32).reshape(-1, 3)
    total = 0.0
    for a, b in zip(pts[:-1], pts[1:]):
        total += vlnce_step_length(a, b)
    return total


def vlnce_step_length(a: Any, b: Any) -> float:
    """One step's length as PathLength and SPL take it: the float32 norm of the float32 difference."""
    import numpy as np
    return float(np.linalg.norm(np.asarray(b, np.float32) - np.asarray(a, np.float32), ord=2))


def _euclidean(a: Any, b: Any) -> float:
    import numpy as np
    return np.linalg.norm(np.array(b) - np.array(a), ord=2)  # measures.py: euclidean_distance


def fastdtw_distance(path: list[list[float]], reference: list[list[float]]) -> float:
    """The DTW distance the reference's nDTW uses: ``fastdtw.fastdtw`` (its default radius 1, the library and
    version VLN-CE's requirements.txt pins, 0.3.4) with 3-D Euclidean point distances. An approximation of
    DTW; :func:`dtw_distance` is the exact value."""
    try:
        from fastdtw import fastdtw
    except ImportError:
        raise ImportError("nDTW as VLN-CE scores it needs fastdtw (pip install fastdtw==0.3.4)") from None
    return float(fastdtw(path, reference, dist=_euclidean)[0])


def dtw_distance(path: Iterable[Any], reference: Iterable[Any]) -> float:
    """Exact dynamic time warping distance (3-D Euclidean point distances, steps (1,0), (0,1), (1,1))."""
    import numpy as np
    a = np.asarray(list(path), np.float64).reshape(-1, 3)
    b = np.asarray(list(reference), np.float64).reshape(-1, 3)
    if not len(a) or not len(b):
        raise ValueError("DTW of an empty path")
    cost = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)
    prev = np.cumsum(cost[0])
    for i in range(1, len(a)):
        row = np.empty(len(b))
        row[0] = prev[0] + cost[i, 0]
        diag = np.minimum(prev[1:], prev[:-1])  # from (i-1, j) and (i-1, j-1)
        for j in range(1, len(b)):
            row[j] = cost[i, j] + min(diag[j - 1], row[j - 1])
        prev = row
    return float(prev[-1])


def ndtw(path: list[list[float]], reference: list[list[float]], success_distance: float = VLNCE_SUCCESS_DISTANCE,
         exact: bool = False) -> float:
    """``exp(-DTW(path, reference) / (len(reference) * success_distance))`` (Ilharco et al. 2019, as NDTW
    computes it); ``path`` as :func:`ndtw_points` makes it, ``reference`` the gt file's ``locations``.
    fastdtw as the reference, or exact DTW with ``exact``."""
    d = dtw_distance(path, reference) if exact else fastdtw_distance(path, reference)
    return float(math.exp(-d / (len(reference) * success_distance)))


def habitat_distances(positions: Iterable[Any], geodesic: Any) -> list[float]:
    """d_t for each position as DistanceToGoal gives it: ``geodesic(p)`` recomputed only when the position
    moved beyond ``np.allclose(previous, p, atol=1e-4)`` since the last computation, else the last value."""
    import numpy as np
    out: list[float] = []
    last = None
    for p in np.asarray(list(positions), np.float32).reshape(-1, 3):
        if last is None or not np.allclose(last, p, atol=1e-4):
            d, last = float(geodesic(p)), p
        out.append(d)
    return out


def vlnce_episode_metrics(positions: Iterable[Any], distances: Iterable[float], stop_called: bool,
                          gt_locations: list[list[float]] | None,
                          success_distance: float = VLNCE_SUCCESS_DISTANCE) -> dict[str, float]:
    """An episode's final VLN-CE measures, as the reference reports them (the ``infos`` after its last action).

    Args:
        positions: p_0 (at reset), then the position after each action (STOP included): T + 1 of them.
        distances: d_0 .. d_T, as :func:`habitat_distances` gives them.
        stop_called: whether the last action was STOP (an episode cut at the step limit did not stop).
        gt_locations: the gt file's ``locations``; None: ``ndtw``, ``sdtw`` and ``ndtw_exact`` are NaN.
    Returns:
        distance_to_goal (d_T), success (STOP and d_T < 3.0, strict), oracle_success (any d_t < 3.0, the start
        included), spl (success * d_0 / max(d_0, TL), d_0 at reset), path_length (TL), steps_taken (T), ndtw
        (fastdtw), sdtw (success * ndtw) and ndtw_exact (exact DTW). SPL's d_0 == 0 case, which the reference
        divides by zero on, is :func:`path_ratio`'s.
    """
    pts = list(positions)
    d = [float(x) for x in distances]
    if len(d) != len(pts) or not pts:
        raise ValueError(f"{len(pts)} positions but {len(d)} distances")
    tl = vlnce_path_length(pts)
    s = bool(stop_called) and d[-1] < success_distance
    out = {
        "distance_to_goal": d[-1],
        "success": float(s),
        "oracle_success": float(any(x < success_distance for x in d)),
        "spl": float(s) * path_ratio(d[0], tl),
        "path_length": tl,
        "steps_taken": float(len(pts) - 1),
    }
    if gt_locations is None:
        out.update(ndtw=float("nan"), sdtw=float("nan"), ndtw_exact=float("nan"))
    else:
        path = ndtw_points(pts)
        out["ndtw"] = ndtw(path, gt_locations, success_distance)
        out["sdtw"] = float(s) * out["ndtw"]
        out["ndtw_exact"] = ndtw(path, gt_locations, success_distance, exact=True)
    return out
