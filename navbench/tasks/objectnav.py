"""ObjectNav: find any instance of a named category (habitat-lab ``habitat/config/habitat/task/objectnav.yaml``,
``tasks/nav/object_nav_task.py`` ``ObjectGoalSensor``); on HM3D-OVON's files and navbench's own OVON-style
splits, OVON's success distance (naokiyokoyama/ovon ``config/experiments/*.yaml``,
``habitat.task.measurements.success.success_distance``: 0.25 m)."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from navbench.episodes.types import EpisodeDataset, EpisodeError
from navbench.tasks.base import SPL_RULE, GoalContext, GoalSensor, Task

OVON_SUCCESS_DISTANCE = 0.25
SPLITS = ("train", "val_seen", "val_seen_synonyms", "val_unseen")
OVON_SPLITS = SPLITS  # navbench's bundled ObjectNav splits are drawn OVON-style


def category_ids(dataset: EpisodeDataset) -> dict[str, int]:
    """The dataset's ``category_to_task_category_id``; a dataset without one (a hand-written file) gets one
    in sorted category order."""
    if not dataset.category_to_task_category_id:
        dataset.category_to_task_category_id = {
            c: i for i, c in enumerate(sorted({str(e.object_category) for e in dataset.episodes}))}
    return dataset.category_to_task_category_id


def _objectgoal_space(dataset: EpisodeDataset, config) -> spaces.Box:
    return spaces.Box(0, max(category_ids(dataset).values()), (1,), np.int64)


def objectgoal(ctx: GoalContext) -> np.ndarray:
    """The goal category's id in the dataset's ``category_to_task_category_id``."""
    assert ctx.episode is not None  # the env's episode, set by reset()
    cat = ctx.episode.object_category
    cats = ctx.dataset.category_to_task_category_id
    if cat not in cats:
        raise EpisodeError(f"episode {ctx.episode.episode_id}: category {cat!r} is not in "
                           f"category_to_task_category_id")
    return np.array([cats[cat]], np.int64)


def ovon_rule(split: str | None, dataset: EpisodeDataset | None) -> float | None:
    """OVON's 0.25 m for navbench's bundled splits, HM3D-OVON's files and navbench's generated benchmark's
    files (they state the ``split_version`` they were drawn under); None (ObjectNav's 0.1 m) otherwise."""
    if dataset is None:
        return OVON_SUCCESS_DISTANCE if split in OVON_SPLITS else None
    from navbench.episodes.io import is_ovon
    return OVON_SUCCESS_DISTANCE if is_ovon(dataset) or "split_version" in dataset.extra else None


TASK = Task(
    name="objectnav",
    gym_id="navbench/ObjectNav-v0",
    title="find any instance of a named object category (OVON's 0.25 m on OVON-style files)",
    reference="habitat-lab habitat/config/habitat/task/objectnav.yaml, habitat/tasks/nav/object_nav_task.py; "
              "naokiyokoyama/ovon config/experiments/*.yaml",
    goal_sensors=(GoalSensor("objectgoal", _objectgoal_space, objectgoal),),
    episode_format="ObjectNav-v1",
    distance_to="VIEW_POINTS",
    success_distance=0.1,
    success_rule=ovon_rule,
    success_rule_text=f"{OVON_SUCCESS_DISTANCE:g} m on OVON-style files and the bundled splits",
    max_steps=500,
    splits=SPLITS,
    default_split="val_unseen",
    default_agent="memory",
    display_name="ObjectNav",
    rules="The agent is given an object category. An episode succeeds when the agent calls STOP within {sd} m "
          "geodesic distance of the nearest view point of any instance of that category (an instance's own "
          "position where it has no view points), and ends after at most {max_steps} actions; " + SPL_RULE,
    group_by="object_category",
    env_class="navbench.env.objectnav:ObjectNavEnv",
)
