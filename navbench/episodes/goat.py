"""GOAT-Bench episode files (Ram81/goat-bench ``Goat-v1``), read unchanged, bounded and validated, for
navigation: an episode is a sequence of subtasks, each an object category, a description or an image.

Format (goat-bench ``goat_bench/dataset/goat_dataset.py``, ``GoatDatasetV1.from_json`` L124-221;
episodes ``goat_bench/task/goat_task.py``, ``GoatEpisode``)::

    {split}/{split}.json.gz            {"episodes": []}
    {split}/content/{scene}.json.gz    {"goals": {"{basename(scene_id)}_{category}": [instance, ...]},
                                        "episodes": [{scene_id, start_position, start_rotation, info,
                                                      tasks: [[category, type, instance_id, image_index?]]}]}
    instance: object_category, object_id, position, view_points [{agent_state: {position, rotation}}],
              children_object_categories, lang_desc, image_goals (InstanceImageNav's InstanceImageParameters)

How the reader resolves them, reproduced here (the line numbers are ``goat_dataset.py``'s):

* ``episode_id`` becomes the episode's index in its file (L144); key episodes by (scene, episode_id).
* A subtask's category list is the one goal list whose *first* instance has that ``object_category``
  (L166-170, L190-194; more than one is an error, L207-209); for each of that first instance's
  ``children_object_categories`` whose key ``"{basename(scene_id)}_{child}"`` exists, the child's list
  is appended to the category's list **in place** (L195-205), so a list grows over the file and an
  object subtask's goals (the list itself, L212) are the list as the whole file left it. Appending only
  repeats instances, which no distance or first match depends on; navbench appends each instance once.
* ``object``: every instance of the list is a goal. ``description`` / ``image``: the instances whose
  ``object_id == task[2]`` (L214-219). An image subtask's picture is ``image_goals[task[-1]]`` of the
  first of them (``goat_bench/task/sensors.py`` L676-686), rendered as InstanceImageNav's is.
* A ``description`` subtask whose ``lang_desc`` has more than 55 words (``split(" ")``) is dropped from
  the episode's goals but stays in its ``tasks`` (L160-183): from there on ``goals[k]`` and
  ``tasks[k]`` are out of step (the distance is measured to ``goals[k]``, success is typed by
  ``tasks[k]``) and the episode ends when ``len(goals)`` subtasks are closed. :class:`GoatEpisode`
  keeps both lists as the reader makes them; ``dropped_descriptions`` counts the drops.

Anything the reference would fail on (a missing category, instance, ``lang_desc``, image index, view
points) is one-line :class:`EpisodeError` naming the file, the episode, the subtask and the field.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from navbench.episodes.instance_imagenav import ImageGoal, parse_image_goals, select_episodes, split_files
from navbench.episodes.io import _episode, _vec, read_json
from navbench.episodes.types import Episode, EpisodeDataset, EpisodeError
from navbench.metrics import GOAT_STOP, GoatMeasures
from navbench.safeio import printable

# goat-bench goat_bench/config.py GoatCurrentSubtaskSensorConfig.sub_task_type: current_subtask is the index
# of the active subtask's type, len(GOAL_TYPES) == 3 once every subtask is closed (sensors.py L587-602).
GOAL_TYPES = ("object", "description", "image")
DONE = len(GOAL_TYPES)
MAX_DESCRIPTION_WORDS = 55  # goat_dataset.py L178: kept when len(lang_desc.split(" ")) <= 55
# config/tasks/goat_stretch_hm3d.yaml: measurements.success.success_distance 0.25 (distance_to VIEW_POINTS),
# environment.max_episode_steps 5000 (the whole episode; no per-subtask limit exists in the code).
SUCCESS_DISTANCE = 0.25
MAX_EPISODE_STEPS = 5000
SUBTASK_STOP = 6  # goat_bench/task/actions.py L15: HabitatSimActions._known_actions["subtask_stop"] = 6
MAX_SUBTASKS = 1000  # per episode (published episodes have 5-10)


@dataclass
class GoatGoal:
    """One goal instance of a GOAT-Bench file."""

    object_id: Any  # as the file writes it (matched with == against a subtask's instance id)
    object_category: str
    position: list[float]
    view_points: np.ndarray  # (N, 3) view point positions
    children_object_categories: list[str] = field(default_factory=list)
    lang_desc: str | None = None
    image_goals: list[ImageGoal] = field(default_factory=list)


@dataclass(frozen=True)
class GoatSubtask:
    """One entry of an episode's ``tasks``: ``[category, type, instance_id, image_index]``."""

    category: str
    type: str  # "object" | "description" | "image"
    instance_id: Any = None  # task[2]; unused for object subtasks
    image_index: int | None = None  # task[-1] of an image subtask

    @property
    def current_subtask(self) -> int:
        """habitat's ``current_subtask`` value while this subtask is active: 0, 1 or 2."""
        return GOAL_TYPES.index(self.type)


@dataclass
class GoatEpisode(Episode):
    """A GOAT-Bench episode: its subtasks (``tasks``, all of them) and the goals of each subtask the
    reader kept (``subtask_goals``, out of step with ``tasks`` after a dropped description). For each
    subtask, the raw goal an agent is given: the category, the description text, the goal image."""

    tasks: list[GoatSubtask] = field(default_factory=list)
    subtask_goals: list[list[GoatGoal]] = field(default_factory=list)
    descriptions: list[str | None] = field(default_factory=list)  # per task: lang_desc of a description subtask
    image_goals: list[ImageGoal | None] = field(default_factory=list)  # per task: the image subtask's camera
    dropped_descriptions: int = 0

    @property
    def task(self) -> str:
        return "goat"

    @property
    def num_goals(self) -> int:
        """Subtasks the episode can close before it ends (``len(episode.goals)`` in goat-bench)."""
        return len(self.subtask_goals)

    def subtask_goal_positions(self, k: int) -> np.ndarray:
        """The view points distance is measured to while subtask ``k`` is active: those of every goal
        in ``goals[k]`` (``GoatDistanceToGoal``, ``goat_bench/measurements/nav.py`` L195-203)."""
        return np.concatenate([g.view_points for g in self.subtask_goals[k]], axis=0)

    def goal_positions(self) -> np.ndarray:
        return self.subtask_goal_positions(0)


def load_goat(path: str | Path, select: Callable[..., list[Episode]] | None = None,
              cap: int | None = None) -> EpisodeDataset:
    """A GOAT-Bench split file and, when there is a ``content/`` folder beside it, every
    ``content/*.json(.gz)`` in it (its ``content_scenes_path`` is never followed), the episodes ``select``
    keeps (:func:`~navbench.episodes.instance_imagenav.select_episodes`). Each file is read whole, at most
    ``cap`` bytes decompressed."""
    path = Path(path)
    files = split_files(path)
    dataset = EpisodeDataset()
    for f in files:
        dataset.episodes += _read_file(f, read_json(f, cap))
    return select_episodes(dataset, select)


def _read_file(path: Path, doc: Any) -> list[GoatEpisode]:
    if not isinstance(doc, dict) or not isinstance(doc.get("episodes"), list):
        raise EpisodeError(f"{path}: not a GOAT-Bench episode file (no top-level 'episodes' list)")
    if not doc["episodes"]:
        return []  # from_json returns before reading goals (L131-132)
    raw_goals = doc.get("goals")
    if not isinstance(raw_goals, dict):
        raise EpisodeError(f"{path}: 'goals' must be an object keyed '{{scene}}_{{category}}' "
                           f"(got {type(raw_goals).__name__})")
    lists: dict[str, list[GoatGoal]] = {}
    for key, goals in raw_goals.items():
        where = f"{path}: goals[{printable(repr(key), 80)}]"
        if not isinstance(goals, list) or not goals:
            raise EpisodeError(f"{where}: must be a non-empty list of instances")
        parsed = []
        for i, g in enumerate(goals):
            try:
                parsed.append(_goal(g))
            except (KeyError, TypeError, ValueError) as exc:
                why = f"no {exc.args[0]!r}" if isinstance(exc, KeyError) else printable(str(exc), 200)
                raise EpisodeError(f"{where}[{i}]: {why}") from None
        lists[key] = parsed
    return [_episode_of(path, i, raw, lists) for i, raw in enumerate(doc["episodes"])]


def _goal(g: Any) -> GoatGoal:
    if not isinstance(g, dict):
        raise TypeError(f"an instance must be an object, got {type(g).__name__}")
    category = g["object_category"]
    if not isinstance(category, str):
        raise TypeError(f"object_category must be a string, got {category!r}"[:200])
    object_id = g["object_id"]
    if not isinstance(object_id, (str, int)) or isinstance(object_id, bool):
        raise TypeError(f"object_id must be a string or an integer, got {object_id!r}"[:200])
    vps = g.get("view_points") or []
    if not isinstance(vps, list):
        raise TypeError("view_points must be a list")
    points = []
    for vp in vps:
        state = vp.get("agent_state") if isinstance(vp, dict) else None
        if not isinstance(state, dict):
            raise TypeError("a view point must be {agent_state: {position, rotation}}")
        points.append(_vec(state.get("position"), 3, "view point position"))
    children = g.get("children_object_categories") or []
    if not isinstance(children, list) or not all(isinstance(c, str) for c in children):
        raise TypeError("children_object_categories must be a list of category names")
    desc = g.get("lang_desc")
    if desc is not None and not isinstance(desc, str):
        raise TypeError(f"lang_desc must be a string, got {type(desc).__name__}")
    images = g.get("image_goals") or []
    if not isinstance(images, list):
        raise TypeError("image_goals must be a list")
    parsed_images = parse_image_goals(images)
    return GoatGoal(object_id, category, _vec(g["position"], 3, "position"),
                    np.array(points, np.float64).reshape(-1, 3), list(children), desc, parsed_images)


def _extend(target: list[GoatGoal], more: list[GoatGoal]) -> None:
    """``target.extend(more)`` (L205), each instance once: repeats change no distance and no first match."""
    have = {id(g) for g in target}
    for g in list(more):
        if id(g) not in have:
            have.add(id(g))
            target.append(g)


def _episode_of(path: Path, index: int, raw: Any, lists: dict[str, list[GoatGoal]]) -> GoatEpisode:
    eid = str(index)  # L144: the episode's index in its file
    where = f"{path}: episode {eid}"
    if not isinstance(raw, dict):
        raise EpisodeError(f"{where}: must be an object")
    raw_tasks = raw.get("tasks")
    if not isinstance(raw_tasks, list) or not raw_tasks or len(raw_tasks) > MAX_SUBTASKS:
        raise EpisodeError(f"{where}: tasks must be a list of 1..{MAX_SUBTASKS} subtasks")
    tasks = [_subtask(f"{where}: tasks[{n}]", t) for n, t in enumerate(raw_tasks)]
    base = _episode({**raw, "goals": [], "episode_id": eid}, path)  # goals are rebuilt (L141)
    extra = {k: v for k, v in base.extra.items() if k != "tasks"}
    scene_base = base.scene_id.split("/")[-1]  # L200: scene_id.split("/")[-1]

    def category_list(n: int, task: GoatSubtask) -> list[GoatGoal]:
        found = [v for v in lists.values() if v[0].object_category == task.category]  # L166-170
        if len(found) != 1:
            raise EpisodeError(f"{where}: tasks[{n}]: category {printable(repr(task.category), 60)}: "
                               f"{'no goal list' if not found else f'{len(found)} goal lists'} in 'goals' "
                               f"(a list's category is its first instance's object_category)")
        return found[0]

    def instances(n: int, task: GoatSubtask, cat: list[GoatGoal]) -> list[GoatGoal]:
        chosen = [g for g in cat if g.object_id == task.instance_id]
        if not chosen:
            raise EpisodeError(f"{where}: tasks[{n}]: no instance with object_id "
                               f"{printable(repr(task.instance_id), 60)} among the "
                               f"{printable(repr(task.category), 60)} goals")
        return chosen

    # the description filter (L160-183), on the lists as earlier episodes extended them
    kept: list[tuple[int, GoatSubtask]] = []
    descriptions: list[str | None] = [None] * len(tasks)
    for n, task in enumerate(tasks):
        if task.type == "description":
            desc = instances(n, task, category_list(n, task))[0].lang_desc
            if desc is None:
                raise EpisodeError(f"{where}: tasks[{n}]: instance {printable(repr(task.instance_id), 60)} has "
                                   f"no lang_desc")
            descriptions[n] = desc
            if len(desc.split(" ")) > MAX_DESCRIPTION_WORDS:
                continue
        kept.append((n, task))
    if not kept:  # the reference then indexes goals[0] at reset and fails
        raise EpisodeError(f"{where}: every subtask is a description of more than {MAX_DESCRIPTION_WORDS} words, "
                           f"which the reader drops: no goals left")
    goals: list[list[GoatGoal]] = []
    for n, task in kept:  # L185-219
        cat = category_list(n, task)
        for child in cat[0].children_object_categories:
            child_list = lists.get(f"{scene_base}_{child}")
            if child_list is not None:
                _extend(cat, child_list)
        goals.append(cat if task.type == "object" else instances(n, task, cat))
        if not any(len(g.view_points) for g in goals[-1]):
            raise EpisodeError(f"{where}: tasks[{n}]: its goals have no view_points (distance is measured to them)")
    image_goals: list[ImageGoal | None] = [None] * len(tasks)
    for n, task in enumerate(tasks):  # every image subtask's picture, the dropped subtasks' included
        if task.type == "image":
            first = instances(n, task, category_list(n, task))[0]
            if not 0 <= task.image_index < len(first.image_goals):
                raise EpisodeError(f"{where}: tasks[{n}]: image index {task.image_index} is out of range: instance "
                                   f"{printable(repr(task.instance_id), 60)} has {len(first.image_goals)} image_goals")
            image_goals[n] = first.image_goals[task.image_index]
    fields = {k: v for k, v in vars(base).items() if k not in ("goals", "extra")}
    return GoatEpisode(**fields, goals=[], extra=extra, tasks=tasks, subtask_goals=goals,
                       descriptions=descriptions, image_goals=image_goals,
                       dropped_descriptions=len(tasks) - len(kept))


def _subtask(where: str, t: Any) -> GoatSubtask:
    if not isinstance(t, list) or len(t) < 2:
        raise EpisodeError(f"{where}: must be [category, type, instance_id, image_index], got "
                           f"{printable(repr(t), 80)}")
    category, kind = t[0], t[1]
    if not isinstance(category, str):
        raise EpisodeError(f"{where}: category must be a string, got {printable(repr(category), 60)}")
    if kind not in GOAL_TYPES:
        raise EpisodeError(f"{where}: type must be one of {', '.join(GOAL_TYPES)}, got {printable(repr(kind), 60)}")
    if kind == "object":
        return GoatSubtask(category, kind, t[2] if len(t) > 2 else None)
    if len(t) < 3:
        raise EpisodeError(f"{where}: a {kind} subtask needs its instance_id (3rd element)")
    image_index = None
    if kind == "image":
        image_index = t[-1]  # sensors.py L685: curent_task[-1]
        if len(t) < 4 or not isinstance(image_index, int) or isinstance(image_index, bool):
            raise EpisodeError(f"{where}: an image subtask needs its image index (4th element), got "
                               f"{printable(repr(t), 80)}")
    return GoatSubtask(category, kind, t[2], image_index)



class GoatProgress:
    """Where a GOAT episode stands, as goat-bench's ``GoatTask`` keeps it (``goat_task.py`` L73-130): the
    active subtask, what the agent is told about it, and the states its measures are computed from.

    ``reset(position, distance)`` with the distance from the start to ``goals[0]``; then ``step(action,
    position, distance_to)`` after each action, the agent already moved, with ``distance_to(k)`` the
    distance from ``position`` to the goals of subtask ``k``. SUBTASK_STOP (6) closes the active subtask
    and the next one starts at once from the same pose; STOP (0) ends the episode; so does closing
    ``num_goals`` subtasks or taking ``max_steps`` actions. :meth:`metrics` gives the measures, kept up to
    date state by state (:class:`~navbench.metrics.GoatMeasures`, equal to ``goat_metrics`` on ``states``)."""

    def __init__(self, episode: GoatEpisode, max_steps: int = MAX_EPISODE_STEPS,
                 success_distance: float = SUCCESS_DISTANCE) -> None:
        self.episode, self.max_steps, self.success_distance = episode, max_steps, success_distance
        self.states: list[tuple[int | None, list[float], float]] = []
        self.active = 0
        self.stop_called = False
        self._measures = GoatMeasures([t.type for t in episode.tasks], episode.num_goals, success_distance,
                                      max_steps)

    def reset(self, position: Sequence[float] | np.ndarray, distance: float) -> None:
        self.states = [(None, [float(v) for v in position], float(distance))]
        self.active = 0
        self.stop_called = False
        self._measures.reset(self.states[0])

    def load(self, states: Sequence[tuple[int | None, Sequence[float], float]], active: int,
             stop_called: bool) -> None:
        """Stand where ``states`` (as :attr:`states` holds them) leave the episode: a snapshot restored."""
        self.states = [(None if a is None else int(a), [float(v) for v in pos], float(d)) for a, pos, d in states]
        self.active, self.stop_called = int(active), bool(stop_called)
        self._measures.reset(self.states[0])
        for state in self.states[1:]:
            self._measures.step(state)

    @property
    def num_steps(self) -> int:
        return len(self.states) - 1

    @property
    def over(self) -> bool:
        return self.stop_called or self.active >= self.episode.num_goals or self.num_steps >= self.max_steps

    def step(self, action: int, position: Sequence[float] | np.ndarray,
             distance_to: Callable[[int], float]) -> None:
        if not self.states or self.over:
            raise RuntimeError("GOAT episode is over (or not started): reset() first")
        action = int(action)
        if action == GOAT_STOP:
            self.stop_called = True
        elif action == SUBTASK_STOP:
            self.active += 1
        d = float(distance_to(self.active)) if self.active < self.episode.num_goals else math.nan
        self.states.append((action, [float(v) for v in position], d))
        self._measures.step(self.states[-1])

    @property
    def distance(self) -> float:
        """The distance to the active subtask's goals (the last one measured once the episode is over)."""
        return next(d for _, _, d in reversed(self.states) if not math.isnan(d))

    @property
    def current_subtask(self) -> int:
        """habitat's ``current_subtask``: 0, 1, 2 for an object, description or image subtask; 3 (``DONE``)
        past the last task (``GoatCurrentSubtaskSensor``, ``sensors.py`` L587-602)."""
        k = self.active
        return self.episode.tasks[k].current_subtask if k < len(self.episode.tasks) else DONE

    def goal(self) -> tuple[str, str, ImageGoal | None]:
        """What the agent is told of the active subtask, raw: its category, its description text ("" unless
        a description subtask) and the camera of its goal image (None unless an image subtask); "" past the
        last task. Taken from ``tasks[k]``, as ``current_subtask`` is."""
        k = self.active
        if self.current_subtask == DONE:
            return "", "", None
        return self.episode.tasks[k].category, self.episode.descriptions[k] or "", self.episode.image_goals[k]

    def metrics(self) -> dict[str, Any]:
        return self._measures.result()
