"""GOAT-Bench episode files as localisation subtasks (``navbench localize --episodes FILE --scene-dir DIR``).

The format is Ram81/goat-bench's (``goat_bench/dataset/goat_dataset.py``, ``GoatDatasetV1``; episodes
``goat_bench/task/goat_task.py``, ``GoatEpisode``)::

    {"episodes": [{"episode_id", "scene_id", "start_position", "start_rotation",
                   "tasks": [[category, "object" | "description" | "image", object_id, (image index)], ...]}],
     "goals": {"{basename(scene_id)}_{category}": [{"object_category", "object_id", "position",
               "view_points", "children_object_categories", "lang_desc", "image_goals": [...]}, ...]}}

A split file whose ``episodes`` list is empty keeps them in ``content/{scene}.json(.gz)`` beside it,
each with its own ``goals``. The file is read by :func:`navbench.episodes.goat.load_goat`, as
goat-bench's reader reads it: a subtask's goals are the goal list whose first instance has its category,
extended by the lists of that instance's ``children_object_categories``:

* ``object``: every goal of the category is an answer; the query is the category name.
* ``description``: the goal whose ``object_id`` is the task's; the query is its ``lang_desc`` (subtasks
  whose description is longer than 55 words are dropped, as the reader drops them).
* ``image``: that goal; the query image is rendered from ``image_goals[task[3]]`` as habitat-lab's
  ``InstanceImageGoalSensor`` renders it (habitat-lab ``habitat/tasks/nav/instance_image_nav_task.py``,
  ``InstanceImageParameters``): a pinhole camera at world ``position`` with rotation ``[x, y, z, w]``,
  ``hfov`` in degrees, ``image_dimensions`` = (height, width).

Ground truth is the goals' ``position`` (object AABB centres). GOAT-Bench episodes repeat subtasks;
each distinct one (scene, type, category, object, image) is asked once, and SR@K is scored as for
the bundled split (:mod:`navbench.localize.benchmark`; ``description`` is the ``language`` type).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from navbench.episodes.goat import MAX_DESCRIPTION_WORDS
from navbench.episodes.instance_imagenav import ImageGoal
from navbench.localize.goat import GoatSplitError
from navbench.localize.pipeline import Query

TYPES = {"object": "object", "description": "language", "image": "image"}  # GOAT-Bench -> navbench query type


@dataclass(frozen=True)
class GoatBenchSubtask:
    id: str
    scene_id: str  # as the episode names it (resolved under --scene-dir)
    type: str  # navbench's query type: object | language | image
    query: str | None  # category name or description; None for image queries
    category: str
    object_ids: tuple[str, ...]  # the answers' object_ids as the file writes them
    gt_positions: np.ndarray  # (M, 3) goal positions
    image_goal: ImageGoal | None = None

    def to_query(self, asset) -> Query:
        """The localiser's :class:`Query`; an image query is rendered from the scene ``asset``."""
        if self.type != "image":
            return Query(self.type, text=self.query)
        from navbench.render.goal_images import image_goal_camera
        from navbench.render.renderer import Renderer

        g = self.image_goal
        with Renderer(asset, image_goal_camera(g)) as r:
            out = r.render(np.asarray(g.position), np.asarray(g.rotation), rgb=True, depth=False, ids=True)
        return Query("image", image=out.rgb, image_ids=out.ids)


def load_goatbench(path: str | Path) -> list[GoatBenchSubtask]:
    """The distinct subtasks of a GOAT-Bench episode file (and its ``content/`` files), resolved by
    :func:`navbench.episodes.goat.load_goat` as goat-bench's reader resolves them; a description of
    more than 55 words is left out, as the reader leaves it out of the goals. :class:`GoatSplitError`
    naming the file on anything unreadable."""
    from navbench.episodes.goat import load_goat
    from navbench.episodes.types import EpisodeError

    path = Path(path)
    try:
        dataset = load_goat(path)
    except EpisodeError as exc:
        raise GoatSplitError(str(exc)) from None
    out: list[GoatBenchSubtask] = []
    seen: set[tuple] = set()
    for ep in dataset.episodes:
        goals = iter(ep.subtask_goals)
        for n, task in enumerate(ep.tasks):
            desc = ep.descriptions[n]
            if task.type == "description" and len(str(desc).split(" ")) > MAX_DESCRIPTION_WORDS:
                continue  # dropped from the goals (navbench.episodes.goat)
            chosen = next(goals)
            key = (ep.scene_id, task.type, task.category, str(task.instance_id) if task.type != "object" else "",
                   task.image_index)
            if key in seen:
                continue
            seen.add(key)
            query = task.category if task.type == "object" else desc if task.type == "description" else None
            gt = np.array([g.position for g in chosen], dtype=np.float64).reshape(-1, 3)
            stem = os.path.basename(ep.scene_id).split(".")[0]
            out.append(GoatBenchSubtask(f"{stem}_{len(out):05d}", ep.scene_id, TYPES[task.type], query, task.category,
                                        tuple(str(g.object_id) for g in chosen), gt, ep.image_goals[n]))
    if not out:
        raise GoatSplitError(f"{path}: no GOAT-Bench subtasks (episodes with 'tasks' and top-level 'goals')")
    return out
