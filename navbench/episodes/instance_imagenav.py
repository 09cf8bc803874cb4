"""InstanceImageNav episode files (habitat-lab's ``InstanceImageNav-v1``, HM3D v1, v2 and the 2023
challenge's v3), read unchanged, bounded and validated.

Format (habitat-lab ``habitat/datasets/image_nav/instance_image_nav_dataset.py``,
``InstanceImageNavDatasetV1``; episode and goal types in ``habitat/tasks/nav/instance_image_nav_task.py``)::

    {split}/{split}.json.gz            {"episodes": []}   (or episodes of its own, with their "goals")
    {split}/content/{scene}.json.gz    {"goals": {"{scene}_{object_id}": goal, ...}, "episodes": [...]}

    episode: episode_id, scene_id, start_position, start_rotation, info, object_category,
             goal_object_id (str), goal_image_id (int, an index into the goal's image_goals), goals: []
    goal:    position, object_id, object_name, object_category, object_surface_area,
             view_points: [{agent_state: {position, rotation}, iou}],
             image_goals: [{position, rotation [x, y, z, w], hfov (deg), image_dimensions [H, W],
                            frame_coverage, object_coverage}]

An episode's one goal is ``goals["{basename(scene_id) without .glb/.basis}_{goal_object_id}"]``
(``InstanceImageGoalNavEpisode.goal_key``); its goal image is rendered from
``image_goals[goal_image_id]``, a camera pose in world coordinates (``InstanceImageGoalSensor``).
As habitat-lab reads it, a file with no episodes contributes no goals, and the goals of every file
read so far are one table. The ``content/`` files are those beside the split file (its
``content_scenes_path`` is never followed: a path read from a file is not opened).

Scored as habitat-lab's ``config/habitat/task/instance_imagenav.yaml`` scores it: distance to the
nearest view point of the goal (``distance_to: VIEW_POINTS``), success under 0.1 m after STOP,
SPL and SoftSPL from those distances (:func:`instance_imagenav_metrics`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from navbench.episodes.io import _episode, _object_goal, _vec, read_json
from navbench.episodes.types import Episode, EpisodeDataset, EpisodeError, ObjectGoal
from navbench.metrics import episode_metrics
from navbench.safeio import printable

if TYPE_CHECKING:
    from navbench.scene.asset import SceneAsset

# habitat-lab config/habitat/task/instance_imagenav.yaml: measurements.success.success_distance 0.1,
# measurements.distance_to_goal.distance_to VIEW_POINTS; benchmark yamls: environment.max_episode_steps 1000.
SUCCESS_DISTANCE = 0.1
MAX_EPISODE_STEPS = 1000
MAX_IMAGE_SIDE = 4096  # a goal image's height and width are at most this (published files: 512 x 512)


@dataclass(frozen=True)
class ImageGoal:
    """One ``InstanceImageParameters`` entry (``instance_image_nav_task.py`` L61-72): a pinhole camera at a
    world ``position`` with ``rotation`` [x, y, z, w], ``hfov_deg`` and an image of ``height`` x ``width``
    (``image_dimensions`` is habitat-sim's ``spec.resolution``, [H, W])."""

    position: tuple[float, float, float]
    rotation: tuple[float, float, float, float]
    hfov_deg: float
    height: int
    width: int
    frame_coverage: float | None = None
    object_coverage: float | None = None


def parse_image_goal(p: Any) -> ImageGoal:
    """An ``image_goals`` entry; ValueError/TypeError naming the bad field."""
    if not isinstance(p, dict):
        raise TypeError(f"an image goal must be an object, got {type(p).__name__}")
    for key in ("position", "rotation", "hfov", "image_dimensions"):  # required (not_none_validator)
        if p.get(key) is None:
            raise KeyError(key)
    pos = _vec(p["position"], 3, "image goal position")
    rot = _vec(p["rotation"], 4, "image goal rotation")
    if not math.isclose(math.hypot(*rot), 1.0, abs_tol=1e-3):
        raise ValueError(f"image goal rotation must be a unit quaternion [x, y, z, w], got {rot}")
    hfov = p["hfov"]
    if isinstance(hfov, bool) or not isinstance(hfov, (int, float)) or not 0 < hfov < 180:
        raise ValueError(f"image goal hfov must be a number of degrees in (0, 180), got {hfov!r}"[:200])
    dims = p["image_dimensions"]
    if (not isinstance(dims, list) or len(dims) != 2
            or not all(isinstance(v, int) and not isinstance(v, bool) and 0 < v <= MAX_IMAGE_SIDE for v in dims)):
        raise ValueError(f"image goal image_dimensions must be [height, width], integers in 1..{MAX_IMAGE_SIDE}, "
                         f"got {dims!r}"[:200])
    cover = [p.get(k) for k in ("frame_coverage", "object_coverage")]
    cover = [float(c) if isinstance(c, (int, float)) and not isinstance(c, bool) else None for c in cover]
    return ImageGoal(tuple(pos), tuple(rot), float(hfov), dims[0], dims[1], cover[0], cover[1])

def split_files(path: Path) -> list[Path]:
    """A split file, then every ``content/*.json(.gz)`` beside it, sorted (habitat-lab's per-scene layout)."""
    content = path.parent / "content"
    if not content.is_dir():
        return [path]
    return [path, *sorted(f for f in content.iterdir() if f.name.endswith((".json", ".json.gz")) and f.is_file())]

def parse_image_goals(raw: list) -> list[ImageGoal]:
    """A goal's ``image_goals`` list, each entry by :func:`parse_image_goal`; ValueError naming the entry."""
    out = []
    for i, p in enumerate(raw):
        try:
            out.append(parse_image_goal(p))
        except KeyError as exc:
            raise ValueError(f"image_goals[{i}] has no {exc.args[0]!r}") from None
        except (TypeError, ValueError) as exc:
            raise ValueError(f"image_goals[{i}]: {exc}") from None
    return out


@dataclass
class InstanceImageGoal(ObjectGoal):
    """An ObjectGoal with the camera poses its goal images are rendered from (``InstanceImageGoal``)."""

    image_goals: list[ImageGoal] = field(default_factory=list)
    object_surface_area: float | None = None


@dataclass
class InstanceImageEpisode(Episode):
    """An InstanceImageNav episode: its one goal, and which of the goal's images the agent is shown."""

    goal_object_id: str = ""
    goal_image_id: int = 0

    @property
    def goal_key(self) -> str:
        return instance_goal_key(self.scene_id, self.goal_object_id)

    @property
    def image_goal(self) -> ImageGoal:
        """The camera the goal image is rendered from (``goals[0].image_goals[goal_image_id]``)."""
        goal = self.goals[0]
        assert isinstance(goal, InstanceImageGoal)
        return goal.image_goals[self.goal_image_id]


def instance_goal_key(scene_id: str, goal_object_id: object) -> str:
    """``InstanceImageGoalNavEpisode.goal_key`` (``instance_image_nav_task.py`` L52-58): the scene file's
    name with a trailing ``.glb`` then ``.basis`` removed, ``_``, the goal object id."""
    sid = os.path.basename(scene_id)
    for ext in (".glb", ".basis"):
        sid = sid[: -len(ext)] if sid.endswith(ext) else sid
    return f"{sid}_{goal_object_id}"


def instance_imagegoal_observations(asset: SceneAsset, episode: InstanceImageEpisode,
                                    platform: str = "auto") -> dict[str, np.ndarray]:
    """``{"instance_imagegoal": (H, W, 3) uint8, "instance_imagegoal_hfov": [hfov] float32 degrees}`` of an
    episode (``InstanceImageGoalSensor``, ``InstanceImageGoalHFOVSensor``, L189-249)."""
    from navbench.render.goal_images import render_image_goal

    goal = episode.image_goal
    return {"instance_imagegoal": render_image_goal(asset, goal, platform),
            "instance_imagegoal_hfov": np.array([goal.hfov_deg], np.float32)}


def instance_imagenav_metrics(stop_called: bool, distance_to_view_points: float, d0: float,
                              path_length: float) -> dict[str, float]:
    """success, spl, soft_spl, distance_to_goal of an episode, as habitat-lab's ``Success``, ``SPL`` and
    ``SoftSPL`` (``habitat/tasks/nav/nav.py``) give them with ``distance_to: VIEW_POINTS`` and 0.1 m:
    ``distance_to_view_points`` is the geodesic distance from the final pose to the nearest view point
    of the goal, ``d0`` the same from the start, ``path_length`` the summed step lengths."""
    return episode_metrics(stop_called, distance_to_view_points, d0, path_length, SUCCESS_DISTANCE)


def select_episodes(dataset: EpisodeDataset, select: Callable[..., list[Episode]] | None) -> EpisodeDataset:
    """``dataset`` with the episodes ``select(stream)`` keeps, ``select`` as
    :func:`navbench.episodes.io.load_dataset` takes it (``stream()`` the episodes, ``stream(keys=True)``
    their ``(scene_id, episode_id)``); all of them when ``select`` is None."""
    if select is not None:
        episodes = list(dataset.episodes)

        def stream(keys: bool = False) -> Iterator[Any]:
            return iter([(e.scene_id, e.episode_id) for e in episodes] if keys else episodes)
        dataset.episodes = list(select(stream))
    return dataset


def load_instance_imagenav(path: str | Path, select: Callable[..., list[Episode]] | None = None,
                           cap: int | None = None) -> EpisodeDataset:
    """An InstanceImageNav split file and, when it has a ``content/`` folder beside it, every
    ``content/*.json(.gz)`` in it (habitat-lab's ``PointNavDatasetV1.__init__`` reads both), the episodes
    ``select`` keeps (:func:`select_episodes`). Each file is read whole, at most ``cap`` bytes
    decompressed. Anything unusable is one-line :class:`EpisodeError` naming the file, the episode and
    the field."""
    path = Path(path)
    files = split_files(path)
    dataset = EpisodeDataset()
    goals: dict[str, InstanceImageGoal] = {}
    for f in files:
        dataset.episodes += _read_file(f, read_json(f, cap), goals)
    return select_episodes(dataset, select)


def _read_file(path: Path, doc: Any, goals: dict[str, InstanceImageGoal]) -> list[InstanceImageEpisode]:
    """``InstanceImageNavDatasetV1.from_json`` (L67-92): goals first, then the episodes bound to them."""
    if not isinstance(doc, dict) or not isinstance(doc.get("episodes"), list):
        raise EpisodeError(f"{path}: not an InstanceImageNav episode file (no top-level 'episodes' list)")
    if not doc["episodes"]:
        return []
    raw_goals = doc.get("goals")
    if not isinstance(raw_goals, dict):
        raise EpisodeError(f"{path}: 'goals' must be an object keyed '{{scene}}_{{object_id}}' "
                           f"(got {type(raw_goals).__name__})")
    for key, g in raw_goals.items():
        try:
            goals[key] = _goal(g)
        except (KeyError, TypeError, ValueError) as exc:
            raise EpisodeError(f"{path}: goals[{printable(repr(key), 80)}]: {_why(exc)}") from None
    return [_bind(path, raw, goals) for raw in doc["episodes"]]


def _goal(g: Any) -> InstanceImageGoal:
    if not isinstance(g, dict):
        raise TypeError(f"a goal must be an object, got {type(g).__name__}")
    for key in ("position", "object_id", "view_points", "image_goals"):
        if key not in g:
            raise KeyError(key)
    base = _object_goal(g)
    if not base.view_points:  # success is measured to them (distance_to: VIEW_POINTS)
        raise ValueError("view_points is empty")
    raw_images = g["image_goals"]
    if not isinstance(raw_images, list) or not raw_images:
        raise ValueError("image_goals must be a non-empty list")
    images = parse_image_goals(raw_images)
    area = g.get("object_surface_area")
    extra = {k: v for k, v in base.extra.items() if k not in ("image_goals", "object_surface_area")}
    return InstanceImageGoal(**{**vars(base), "extra": extra}, image_goals=images,
                             object_surface_area=float(area) if isinstance(area, (int, float)) else None)


def _bind(path: Path, raw: Any, goals: dict[str, InstanceImageGoal]) -> InstanceImageEpisode:
    ep = _episode(raw, path)  # the fields every Habitat episode has, validated as the other readers do
    where = f"{path}: episode {printable(ep.episode_id, 40)}"
    extra = dict(ep.extra)
    object_id = extra.pop("goal_object_id", None)
    image_id = extra.pop("goal_image_id", None)
    if object_id is None or isinstance(object_id, bool) or not isinstance(object_id, (str, int)):
        raise EpisodeError(f"{where}: goal_object_id must be a string, got {printable(repr(object_id), 60)}")
    if image_id is None or isinstance(image_id, bool) or not isinstance(image_id, int):
        raise EpisodeError(f"{where}: goal_image_id must be an integer, got {printable(repr(image_id), 60)}")
    key = instance_goal_key(ep.scene_id, object_id)
    goal = goals.get(key)
    if goal is None:
        raise EpisodeError(f"{where}: goals has no key {printable(repr(key), 80)} "
                           f"(scene_id's basename + '_' + goal_object_id)")
    if not 0 <= image_id < len(goal.image_goals):
        raise EpisodeError(f"{where}: goal_image_id {image_id} is out of range: "
                           f"goals[{printable(repr(key), 80)}].image_goals has {len(goal.image_goals)} entries")
    fields = {k: v for k, v in vars(ep).items() if k not in ("goals", "extra")}
    return InstanceImageEpisode(**fields, goals=[goal], extra=extra,
                                goal_object_id=str(object_id), goal_image_id=image_id)


def _why(exc: Exception) -> str:
    if isinstance(exc, KeyError):
        return f"no {exc.args[0]!r}"
    return printable(str(exc), 200)
