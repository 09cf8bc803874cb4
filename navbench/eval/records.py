"""The shapes of what a run writes: one :class:`EpisodeRecord` per line of ``episodes.jsonl`` and the
:class:`RunSummary` of ``summary.json`` (what :func:`navbench.evaluate` returns)."""

from __future__ import annotations

import json
import math
from typing import Any, TypedDict


class _EpisodeBase(TypedDict):
    episode_id: str
    scene_id: str
    split: str | None
    task: str
    agent: str
    object_category: str | None


class EpisodeRecord(_EpisodeBase, total=False):
    """One episode's outcome (Habitat's metrics). A skipped episode (no goal reachable from the start)
    has ``skipped``, ``skip_reason`` and no metrics; a failed one ``failed``, ``failure_reason`` and a
    failure's metrics; ``log`` holds the agent's decisions, ``trace`` the path it took."""
    success: float
    spl: float
    soft_spl: float
    distance_to_goal: float
    geodesic_distance: float | None
    path_length: float
    num_steps: int
    stop_called: bool
    collisions: int
    elapsed_s: float  # wall-clock: the one field two runs of the same config may disagree on
    log: dict[str, Any]
    trace: dict[str, Any]
    failed: bool
    failure_reason: str
    skipped: bool
    skip_reason: str


class FailedEpisode(TypedDict):
    scene_id: str
    episode_id: str
    failure_reason: str


class RunSummary(TypedDict, total=False):
    """Metric means over the scored episodes (failed ones count as failures), per object category for
    ObjectNav, and what the run was."""
    num_episodes: int
    num_skipped: int
    success: float
    spl: float
    soft_spl: float
    distance_to_goal: float
    by_object_category: dict[str, dict[str, float]]
    task: str
    split: str | None
    agent: str  # the run's label
    success_distance: float
    seed: int
    complete: bool  # False when the run stopped before every selected episode had a record
    num_failed: int
    failed_episodes: list[FailedEpisode]
    shard: str


def json_ready(value: Any) -> Any:
    """``value`` with every non-finite float (the mean of no episodes) as None, so ``summary.json`` is JSON
    (``json.dumps`` would write ``NaN``, which JSON parsers refuse) with null where a figure is undefined."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: json_ready(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(v) for v in value]
    return value


def summary_text(summary: dict[str, Any]) -> str:
    """``summary.json``'s text: strict JSON (never NaN or Infinity)."""
    return json.dumps(json_ready(summary), indent=1, allow_nan=False) + "\n"
