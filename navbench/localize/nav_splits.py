"""The bundled InstanceImageNav and GOAT-Bench ``val`` splits, in their upstream layouts, on the four val houses.

Regenerate (deterministic for a seed, byte for byte)::

    navbench generate instance_imagenav      # episodes/instance_imagenav/val/
    navbench generate goat                   # episodes/goat/val/

Both draw their goals as the GOAT-style localisation split does (:mod:`navbench.localize.goat`): an
instance is a goal only if a random navigable pose 1-3 m away, facing it and away from the pre-scan's
poses, sees it in the instance-id render (at least 2 % of the image, the object in the centre); that pose
is its goal image's camera (224 x 224, hfov 79, at navbench's camera height), and a description is
:func:`~navbench.localize.describe.describe_with_room`'s, kept only where it names that instance alone.
View points are the ObjectNav generator's (:class:`~navbench.episodes.generate.SceneGoals`), and starts
are drawn as its episodes' are (geodesic 1-20 m to the first goal's view points, Habitat's ratio rule).

* ``instance_imagenav/val``: habitat-lab's ``InstanceImageNavDatasetV1`` layout, an empty ``val.json.gz``
  and ``content/{house}.json.gz`` with ``goals`` keyed ``{house}_{object_id}``; ``per_scene`` episodes
  per house cycling over its goal instances in a shuffled order.
* ``goat/val``: goat-bench's ``GoatDatasetV1`` layout, ``content/{house}.json.gz`` with ``goals`` keyed
  ``{house}.glb_{category}`` (every goal instance of the category, each with its ``lang_desc`` and
  ``image_goals``) and episodes of 5-10 ``tasks``, each an object, description or image subtask drawn
  with equal odds among the types the house has goals for, never the previous subtask's goal again.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from navbench.episodes.generate import SPLIT_VERSION, GeneratorConfig, SceneGoals, _random_yaw_quat, scene_files
from navbench.episodes.io import _r, object_goal_to_json, write_json
from navbench.episodes.types import ObjectGoal
from navbench.localize.describe import describe_with_room
from navbench.localize.goat import GoatConfig, _ViewFinder
from navbench.loop_progress import progress
from navbench.paths import EPISODES_DIR, SCENES_DIR

GOAL_TYPES = ("object", "description", "image")


@dataclass(frozen=True)
class NavSplitPlan:
    instance_imagenav_per_scene: int = 100  # 400 episodes over the 4 val houses: SR within about +-5 points
    goat_per_scene: int = 10  # 40 episodes, about 300 subtasks
    goat_min_subtasks: int = 5
    goat_max_subtasks: int = 10


@dataclass
class _Instance:
    goal: ObjectGoal  # view points, from SceneGoals
    image_goal: dict  # the camera of its goal image (InstanceImageParameters)
    description: str | None


def _instances(sg: SceneGoals, config: GoatConfig, rng: np.random.Generator) -> list[_Instance]:
    """The house's goal instances: reachable view points and a view that sees the instance, in id order."""
    asset = sg.asset
    finder = _ViewFinder(asset, sg.grid, config)
    out = []
    try:
        for obj in (asset.objects[i] for i in sorted(asset.objects)):
            goal = next((g for g in sg.goals(obj.category) if g.object_id == obj.id), None)
            if goal is None:
                continue
            view = finder.find(obj, rng)
            if view is None:
                continue
            cam, rot = view[0], view[1]
            image = {"position": [float(v) for v in cam], "rotation": [float(v) for v in rot],
                     "hfov": config.hfov_deg, "image_dimensions": [config.height, config.width],
                     "frame_coverage": round(float((view[3] == obj.id).mean()), 4), "object_coverage": None}
            desc = describe_with_room(obj, asset.objects)
            out.append(_Instance(goal, _r(image), desc.text() if desc is not None else None))
    finally:
        finder.close()
    return out


def _start(sg: SceneGoals, vps: np.ndarray, rng: np.random.Generator, what: str) -> dict[str, Any]:
    start, geo, euc = sg.draw_start(vps, rng, GeneratorConfig(), what)
    return {"start_position": [float(v) for v in start], "start_rotation": _random_yaw_quat(rng),
            "info": {"geodesic_distance": geo, "euclidean_distance": euc}}


def _houses(scene_dir: Path) -> list[tuple[Path, str]]:
    return [(p, p.name.split(".")[0]) for p in scene_files(scene_dir, "val")]


def write_instance_imagenav_split(out_dir: Path = EPISODES_DIR, scene_dir: Path = SCENES_DIR, seed: int = 0,
                                  per_scene: int = NavSplitPlan().instance_imagenav_per_scene, log=print) -> int:
    """``out_dir/instance_imagenav/val/``; returns the number of episodes."""
    root = Path(out_dir) / "instance_imagenav" / "val"
    total = 0
    for si, (path, house) in enumerate(progress(_houses(scene_dir), desc="instance_imagenav/val: houses")):
        rng = np.random.default_rng([seed, 3, si])
        sg = SceneGoals(path, scene_dir)
        insts = _instances(sg, GoatConfig(), rng)
        if not insts:
            raise RuntimeError(f"{path}: no instance is seen from a navigable pose")
        goals = {f"{house}_{i.goal.object_id}": {**object_goal_to_json(i.goal), "object_surface_area": None,
                                                 "image_goals": [i.image_goal]} for i in insts}
        order = rng.permutation(len(insts))
        episodes = []
        for k in range(per_scene):
            inst = insts[int(order[k % len(insts)])]
            ep = _start(sg, inst.goal.view_point_positions(), rng, f"InstanceImageNav episode for {house}")
            episodes.append(_r({"episode_id": str(total + k), "scene_id": sg.scene_id, **ep, "goals": [],
                                "object_category": inst.goal.object_category,
                                "goal_object_id": str(inst.goal.object_id), "goal_image_id": 0}))
        write_json({"goals": goals, "episodes": episodes}, root / "content" / f"{house}.json.gz")
        total += len(episodes)
    write_json({"split_version": SPLIT_VERSION, "episodes": []}, root / "val.json.gz")
    log(f"instance_imagenav/val: {total} episodes")
    return total


def _goat_tasks(insts: list[_Instance], n: int, rng: np.random.Generator) -> list[tuple[list, _Instance | None, str]]:
    """``n`` subtasks ``(task, instance or None, category)``: a type drawn among those the house has goals for,
    then a category (object) or an instance with a description (description) or a goal image (image)."""
    by_cat: dict[str, list[_Instance]] = {}
    for inst in insts:
        by_cat.setdefault(inst.goal.object_category, []).append(inst)
    cats = sorted(by_cat)
    described = [i for i in insts if i.description is not None]
    kinds = [t for t, have in zip(GOAL_TYPES, (cats, described, insts)) if have]
    out: list[tuple[list, _Instance | None, str]] = []
    while len(out) < n:
        kind = kinds[int(rng.integers(len(kinds)))]
        if kind == "object":  # the category's every instance is a goal; the task names one, as goat-bench's do
            cat = cats[int(rng.integers(len(cats)))]
            inst = by_cat[cat][int(rng.integers(len(by_cat[cat])))]
            sub: tuple[list, _Instance | None, str] = ([cat, "object", inst.goal.object_id], None, cat)
        else:
            pool = described if kind == "description" else insts
            inst = pool[int(rng.integers(len(pool)))]
            cat = inst.goal.object_category
            sub = ([cat, kind, inst.goal.object_id] + ([0] if kind == "image" else []), inst, cat)
        if out and (sub[1] or sub[2]) == (out[-1][1] or out[-1][2]):
            continue  # never the goal just closed again: that subtask would start where it ends
        out.append(sub)
    return out


def write_goat_split(out_dir: Path = EPISODES_DIR, scene_dir: Path = SCENES_DIR, seed: int = 0,
                     plan: NavSplitPlan = NavSplitPlan(), log=print) -> int:
    """``out_dir/goat/val/``; returns the number of episodes."""
    root = Path(out_dir) / "goat" / "val"
    total = subtasks = 0
    for si, (path, house) in enumerate(progress(_houses(scene_dir), desc="goat/val: houses")):
        rng = np.random.default_rng([seed, 4, si])
        sg = SceneGoals(path, scene_dir)
        insts = _instances(sg, GoatConfig(), rng)
        if not insts:
            raise RuntimeError(f"{path}: no instance is seen from a navigable pose")
        base = Path(sg.scene_id).name
        by_cat: dict[str, list[_Instance]] = {}
        for inst in insts:
            by_cat.setdefault(inst.goal.object_category, []).append(inst)
        goals = {f"{base}_{cat}": [_r({"object_category": cat, "object_id": i.goal.object_id,
                                       "position": i.goal.position,
                                       "view_points": object_goal_to_json(i.goal)["view_points"],
                                       "children_object_categories": [], "lang_desc": i.description,
                                       "image_goals": [i.image_goal]}) for i in group]
                 for cat, group in sorted(by_cat.items())}
        episodes = []
        for k in range(plan.goat_per_scene):
            n = int(rng.integers(plan.goat_min_subtasks, plan.goat_max_subtasks + 1))
            tasks = _goat_tasks(insts, n, rng)
            first = tasks[0]
            points = (first[1].goal.view_point_positions() if first[1] is not None
                      else np.concatenate([i.goal.view_point_positions() for i in by_cat[first[2]]]))
            ep = _start(sg, points, rng, f"GOAT episode for {house}")
            episodes.append(_r({"episode_id": str(k), "scene_id": sg.scene_id, **ep, "goals": [],
                                "tasks": [t for t, _, _ in tasks]}))
            subtasks += n
        write_json({"goals": goals, "episodes": episodes}, root / "content" / f"{house}.json.gz")
        total += len(episodes)
    write_json({"split_version": SPLIT_VERSION, "episodes": []}, root / "val.json.gz")
    log(f"goat/val: {total} episodes, {subtasks} subtasks")
    return total
