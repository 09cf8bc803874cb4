"""GOAT-Bench episode files as localisation subtasks (``navbench localize --episodes FILE --scene-dir DIR``).

The format is Ram81/goat-bench's (``goat_bench/dataset/goat_dataset.py``, ``GoatDatasetV1``; episodes
``goat_bench/task/goat_task.py``, ``GoatEpisode``)::

    {"episodes": [{"episode_id", "scene_id", "start_position", "start_rotation",
                   "tasks": [[category, "object" | "description" | "image", object_id, (image index)], ...]}],
     "goals": {"{basename(scene_id)}_{category}": [{"object_category", "object_id", "position",
               "view_points", "children_object_categories", "lang_desc", "image_goals": [...]}, ...]}}

A split file whose ``episodes`` list is empty keeps them in ``content/{scene}.json(.gz)`` beside it,
each with its own ``goals`` (``content_scenes_path``). As the reader does, a subtask's goals are the
goal list of its category (the ``{scene}_{category}`` key, else the list whose first goal has that
category), extended by those of the first goal's ``children_object_categories``:

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

from navbench.episodes.instance_imagenav import ImageGoal, parse_image_goal
from navbench.localize.goat import GoatSplitError
from navbench.localize.pipeline import Query

MAX_DESCRIPTION_WORDS = 55  # goat_dataset.py's from_json keeps descriptions of at most 55 words
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
    """The distinct subtasks of a GOAT-Bench episode file (and its ``content/`` files when it has no
    episodes of its own); :class:`GoatSplitError` naming the file on anything unreadable."""
    from navbench.episodes.io import read_json
    from navbench.episodes.types import EpisodeError

    path = Path(path)
    files = [path]
    try:
        data = read_json(path)
    except EpisodeError as exc:
        raise GoatSplitError(str(exc)) from None
    if isinstance(data, dict) and data.get("episodes") == [] and (path.parent / "content").is_dir():
        files = sorted(f for f in (path.parent / "content").iterdir() if f.name.endswith((".json", ".json.gz")))
    out: list[GoatBenchSubtask] = []
    seen: set[tuple] = set()
    for f in files:
        try:
            doc = data if f == path else read_json(f)
        except EpisodeError as exc:
            raise GoatSplitError(str(exc)) from None
        try:
            _subtasks(doc, out, seen)
        except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
            raise GoatSplitError(f"{f}: not a GOAT-Bench episode file ({type(exc).__name__}: {exc})"[:300]) from None
    if not out:
        raise GoatSplitError(f"{path}: no GOAT-Bench subtasks (episodes with 'tasks' and top-level 'goals')")
    return out


def _subtasks(doc: dict, out: list[GoatBenchSubtask], seen: set[tuple]) -> None:
    if not isinstance(doc, dict) or not isinstance(doc.get("episodes"), list):
        raise TypeError("expected an object with an 'episodes' list")
    goals = doc.get("goals") or {}
    if not isinstance(goals, dict):
        raise TypeError("'goals' must map '{scene}_{category}' keys to goal lists")
    for ep in doc["episodes"]:
        scene_id = str(ep["scene_id"])
        tasks = ep["tasks"]
        if not isinstance(tasks, list):
            raise TypeError(f"episode {ep.get('episode_id')}: 'tasks' must be a list")
        for n, task in enumerate(tasks):
            if not isinstance(task, list) or len(task) < 3 or task[1] not in TYPES:
                raise ValueError(f"episode {ep.get('episode_id')}: task {n} must be [category, object|description|"
                                 f"image, object_id, ...], got {task!r}"[:200])
            category, kind, inst = str(task[0]), task[1], task[2]
            image_index = task[3] if kind == "image" and len(task) > 3 else None
            key = (scene_id, kind, category, str(inst) if kind != "object" else "", image_index)
            if key in seen:
                continue
            seen.add(key)
            cat_goals = _category_goals(goals, scene_id, category)
            if kind == "object":
                chosen, query = cat_goals, category
            else:
                chosen = [g for g in cat_goals if g.get("object_id") == inst]
                if not chosen:
                    raise ValueError(f"episode {ep.get('episode_id')}: no goal with object_id {inst!r} for "
                                     f"category {category!r}")
                query = str(chosen[0].get("lang_desc") or "") if kind == "description" else None
                if kind == "description" and not query.strip():
                    raise ValueError(f"episode {ep.get('episode_id')}: goal {inst!r} has no lang_desc")
                if kind == "description" and len(query.split(" ")) > MAX_DESCRIPTION_WORDS:
                    continue  # the reader drops these subtasks
            image_goal = None
            if kind == "image":
                if not isinstance(image_index, int) or isinstance(image_index, bool):
                    raise ValueError(f"episode {ep.get('episode_id')}: image task {n} needs an image index "
                                     f"(its 4th element)")
                image_goal = parse_image_goal(chosen[0]["image_goals"][image_index])
            gt = np.array([[float(v) for v in g["position"]] for g in chosen], dtype=np.float64).reshape(-1, 3)
            if not np.isfinite(gt).all():
                raise ValueError(f"episode {ep.get('episode_id')}: goal positions must be finite")
            stem = os.path.basename(scene_id).split(".")[0]
            out.append(GoatBenchSubtask(f"{stem}_{len(out):05d}", scene_id, TYPES[kind], query, category,
                                        tuple(str(g.get("object_id")) for g in chosen), gt, image_goal))


def _category_goals(goals: dict, scene_id: str, category: str) -> list[dict]:
    """The goal list of ``category`` plus its children categories' lists (goat_dataset.py's from_json)."""
    base = os.path.basename(scene_id)
    found = goals.get(f"{base}_{category}")
    if found is None:
        found = next((v for v in goals.values() if v and v[0].get("object_category") == category), None)
    if not found:
        raise ValueError(f"no goals for category {category!r} of scene {base}")
    out = list(found)
    for child in found[0].get("children_object_categories") or []:
        out += goals.get(f"{base}_{child}", [])
    return out
