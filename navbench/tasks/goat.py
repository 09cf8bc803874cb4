"""GOAT-Bench: a sequence of subtasks in one scene, each an object category, a language description or an
image of one instance (Ram81/goat-bench ``goat_bench/task/goat_task.py``, ``goat_bench/measurements/nav.py``,
``config/tasks/goat_stretch_hm3d.yaml``; files read by :mod:`navbench.episodes.goat`).

Action 6, SUBTASK_STOP, closes the active subtask and the next starts at once from the same pose; STOP ends
the episode. Goals are given raw: ``current_subtask`` (habitat's 0/1/2, 3 past the last subtask), the
category, the description text and the goal image (rendered once per subtask), never an embedding.
The env is :class:`navbench.env.goat.GoatEnv`; it keeps the episode's :class:`~navbench.episodes.goat.GoatProgress`.
"""

from __future__ import annotations

import string
from typing import Any

import numpy as np
from gymnasium import spaces

from navbench.episodes.types import EpisodeDataset, EpisodeError
from navbench.tasks.base import IMAGE_GOAL_RULE, MEASURES, NAV_ACTIONS, GoalContext, GoalSensor, Task

# goat-bench config/tasks/goat_stretch_hm3d.yaml: success.success_distance, environment.max_episode_steps; the
# reader and GoatProgress (navbench.episodes.goat) state the same. current_subtask is 0..2, DONE past the last.
SUCCESS_DISTANCE = 0.25
MAX_EPISODE_STEPS = 5000
DONE = 3
ACTIONS = (*NAV_ACTIONS, "LOOK_UP", "LOOK_DOWN", "SUBTASK_STOP")  # goat_stretch_hm3d.yaml; subtask_stop is 6
MAX_TEXT = 4096  # characters of a category or description observation
# goat-bench's measures (nav.py), as its evaluation averages them over episodes, and the corrected figures
GOAT_MEASURES = (
    "partial_success", "composite_success", "task_success", "object_success", "description_success",
    "image_success", "composite_spl", "composite_softspl", "task_success_corrected", "object_success_corrected",
    "description_success_corrected", "image_success_corrected",
)
# what goat-bench's evaluation logs first (ppo_trainer_no_2d.py): success over subtasks and of all of them, SPL,
# success by goal type; task_success is always 0 there and composite_softspl is no headline
GOAT_HEADLINE = ("partial_success", "composite_success", "composite_spl", "object_success", "description_success",
                 "image_success")
# navbench table's columns from the summary, by goat-bench's names (navbench.eval.table adds success and SPL by
# goal type from the records)
GOAT_COLUMNS = (("partial SR", "partial_success", 100), ("composite SR", "composite_success", 100),
                ("composite SPL", "composite_spl", 100))
# per subtask, in each record (goat-bench writes success_by_subtask and spl_by_subtaskl to episode_metrics.json)
GOAT_RECORD_FIELDS = ("subtask_success", "spl_by_subtask", "softspl_by_subtask", "d0_by_subtask", "subtasks_closed")


def read_episodes(path, select=None) -> EpisodeDataset:
    """:func:`navbench.episodes.goat.load_goat` (imported when a file is read)."""
    from navbench.episodes.goat import load_goat
    return load_goat(path, select)


def _progress(ctx: GoalContext) -> Any:
    """The env's :class:`~navbench.episodes.goat.GoatProgress`; None while it starts the episode."""
    from navbench.episodes.goat import GoatEpisode

    if not isinstance(ctx.episode, GoatEpisode):
        raise EpisodeError(f"episode {getattr(ctx.episode, 'episode_id', '?')}: not a GOAT-Bench episode "
                           f"(read its file with the goat task)")
    return getattr(ctx, "goat_progress", None)  # None while the env is starting the episode


def current_subtask(ctx: GoalContext) -> np.ndarray:
    p = _progress(ctx)
    return np.array([p.current_subtask if p is not None else 0], np.int32)


def subtask_category(ctx: GoalContext) -> str:
    p = _progress(ctx)
    return p.goal()[0] if p is not None else ""


def subtask_description(ctx: GoalContext) -> str:
    p = _progress(ctx)
    return p.goal()[1] if p is not None else ""


def _image_size(dataset: EpisodeDataset) -> tuple[int, int]:
    for ep in dataset.episodes:
        for g in getattr(ep, "image_goals", []):
            if g is not None:
                return g.height, g.width
    return 512, 512  # goat-bench's goal images (cache_image_goals.py renders 512 x 512)


def subtask_image(ctx: GoalContext) -> np.ndarray:
    """The active image subtask's goal image (rendered once per subtask); zeros for other subtasks."""
    p = _progress(ctx)
    camera = p.goal()[2] if p is not None else None
    if camera is None:
        return np.zeros((*_image_size(ctx.dataset), 3), np.uint8)
    return ctx.goal_image(camera)  # type: ignore[attr-defined]  (GoatEnv's)


def _text_space(dataset: EpisodeDataset, config) -> spaces.Text:
    return spaces.Text(max_length=MAX_TEXT, min_length=0, charset=string.printable)


TASK = Task(
    name="goat",
    gym_id="navbench/GOAT-v0",
    title="GOAT-Bench: 5-10 subtasks per episode (category, description, image), SUBTASK_STOP (6) between them",
    reference="Ram81/goat-bench goat_bench/task/goat_task.py, goat_bench/measurements/nav.py, "
              "goat_bench/dataset/goat_dataset.py, config/tasks/goat_stretch_hm3d.yaml",
    goal_sensors=(
        GoalSensor("current_subtask", lambda dataset, config: spaces.Box(0, DONE, (1,), np.int32), current_subtask),
        GoalSensor("subtask_category", _text_space, subtask_category),
        GoalSensor("subtask_description", _text_space, subtask_description),
        GoalSensor("subtask_image", lambda dataset, config: spaces.Box(0, 255, (*_image_size(dataset), 3), np.uint8),
                   subtask_image),
    ),
    episode_format="Goat-v1",
    read_episodes=read_episodes,
    actions=ACTIONS,
    measures=MEASURES + GOAT_MEASURES,
    record_fields=GOAT_RECORD_FIELDS,
    headline=GOAT_HEADLINE,
    distance_to="VIEW_POINTS",
    success_distance=SUCCESS_DISTANCE,
    success_rule_text="per subtask, at its SUBTASK_STOP (6); STOP ends the episode",
    max_steps=MAX_EPISODE_STEPS,
    splits=("val",),
    default_split="val",
    default_agent="memory",
    display_name="GOAT-Bench",
    rules="An episode is a sequence of subtasks in one scene, each an object category, a description of one object "
          "instance in words, or an image of one instance; the agent is given the active subtask's goal. It closes "
          "a subtask with SUBTASK_STOP, which succeeds when the agent stands within {sd} m geodesic distance of the "
          "nearest view point of that subtask's goal instances; the next subtask starts at once from the same "
          "pose. The last SUBTASK_STOP, or STOP at any time, ends the episode (subtasks left open fail), which ends "
          "after at most {max_steps} actions in all. A subtask's SPL weighs its success by the shortest path from "
          "where it began over the longer of it and the length walked for it; partial success and composite SPL "
          "average over an episode's subtasks, and success is also reported by goal type (object, description, "
          "image).",
    env_class="navbench.env.goat:GoatEnv",
    goal_images=IMAGE_GOAL_RULE,
    columns=GOAT_COLUMNS,
)
