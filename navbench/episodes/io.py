"""Read and write Habitat episode datasets (PointNav-v1, ObjectNav-v1, OVON-style), ``.json`` or ``.json.gz``.

Layout, as Habitat has it:
- PointNav-v1: ``{"episodes": [{episode_id, scene_id, start_position, start_rotation,
  info: {geodesic_distance, ...}, goals: [{position, radius}]}]}``
- ObjectNav-v1: the same episodes with ``object_category`` and ``goals: []``, plus top-level
  ``goals_by_category`` keyed ``"{basename(scene_id)}_{category}"``, ``category_to_task_category_id``
  and ``category_to_scene_annotation_category_id``. Episode goals are filled from the table at load.
- A split file whose ``episodes`` is empty may keep its episodes in ``content/{scene}.json(.gz)``
  beside it; those are loaded too.
- HM3D-OVON (OVON-v1): ObjectNav-v1's layout, with goal ``object_id``s written as habitat-sim object
  names (``"couch_0"``: ``{raw category}_{index among that category's rows}``, habitat-sim
  ``src/esp/scene/HM3DSemanticScene.cpp``; written by naokiyokoyama/ovon
  ``ovon/dataset/objectnav_generator.py``). As OVON's reader (``ovon/dataset/ovon_dataset.py``) does,
  the number after the last ``_`` becomes the integer ``object_id``; the name is kept as
  ``object_name`` and written back unchanged. :func:`is_ovon` tells such files apart.

Quaternions are [x, y, z, w]; floats are written rounded to 5 decimals; episode ids are kept as given.
"""

from __future__ import annotations

import gzip
import json
import math
import os
import zlib
from pathlib import Path
from typing import Any

from navbench.episodes.types import (
    AgentState,
    Episode,
    EpisodeDataset,
    EpisodeError,
    NavigationGoal,
    ObjectGoal,
    ViewPoint,
)

_EPISODE_KEYS = {"episode_id", "scene_id", "start_position", "start_rotation", "goals", "info", "object_category"}
_OBJECT_GOAL_KEYS = {"position", "radius", "object_id", "object_category", "object_name", "room_id", "room_name",
                     "view_points"}


def goals_key(scene_id: str, category: str) -> str:
    """Habitat's ``goals_by_category`` key: basename of the scene path (with its extension) + category."""
    return f"{os.path.basename(scene_id)}_{category}"


# --------------------------------------------------------------------------------------------- read
def read_json(path: str | Path) -> Any:
    path = Path(path)
    if not path.is_file():
        raise EpisodeError(f"{path}: file not found")
    try:
        raw = path.read_bytes()
        if path.suffix == ".gz":
            raw = gzip.decompress(raw)
        return json.loads(raw)
    except (OSError, EOFError, zlib.error, gzip.BadGzipFile, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise EpisodeError(f"{path}: corrupt or truncated JSON ({type(exc).__name__}: {exc})") from None
    except RecursionError:
        raise EpisodeError(f"{path}: JSON nested too deeply to read") from None


def load_dataset(path: str | Path) -> EpisodeDataset:
    """Load a dataset file (and its ``content/`` per-scene files when present)."""
    path = Path(path)
    data = read_json(path)
    if not isinstance(data, dict) or "episodes" not in data:
        raise EpisodeError(f"{path}: not a Habitat episode dataset (no top-level 'episodes')")
    dataset = EpisodeDataset()
    _merge(dataset, data, path)
    content = path.parent / "content"
    if not data["episodes"] and content.is_dir():
        for f in sorted(content.iterdir()):
            if f.name.endswith((".json", ".json.gz")):
                _merge(dataset, read_json(f), f)
    for ep in dataset.episodes:
        if ep.object_category is None and not ep.goals:
            raise EpisodeError(f"{path}: episode {ep.episode_id}: no goals and no object_category")
        if ep.object_category is not None and not ep.goals:
            key = goals_key(ep.scene_id, ep.object_category)
            goals = dataset.goals_by_category.get(key)
            if not goals:
                raise EpisodeError(f"{path}: episode {ep.episode_id}: no goals for category "
                                   f"'{ep.object_category}' (key '{key}' missing from goals_by_category)")
            ep.goals = list(goals)
    return dataset


def _merge(dataset: EpisodeDataset, data: dict, path: Path) -> None:
    try:
        if not isinstance(data, dict) or not isinstance(data.get("episodes"), list):
            raise TypeError("'episodes' must be a list of episodes")
        for key, goals in _mapping(data, "goals_by_category").items():
            if not isinstance(goals, list):
                raise TypeError(f"goals_by_category[{key!r}] must be a list of goals")
            dataset.goals_by_category[key] = [_object_goal(g) for g in goals]
        for name in ("category_to_task_category_id", "category_to_scene_annotation_category_id"):
            table = _mapping(data, name)
            if not all(isinstance(v, int) and not isinstance(v, bool) for v in table.values()):
                raise TypeError(f"{name} must map category names to integer ids")
            getattr(dataset, name).update(table)
        for k, v in data.items():
            if k not in ("episodes", "goals_by_category", "category_to_task_category_id",
                         "category_to_scene_annotation_category_id"):
                dataset.extra.setdefault(k, v)
        for raw in data["episodes"]:
            dataset.episodes.append(_episode(raw, path))
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        if isinstance(exc, EpisodeError):
            raise
        raise EpisodeError(f"{path}: malformed dataset ({type(exc).__name__}: {exc})") from None


def _mapping(data: dict, key: str) -> dict:
    value = data.get(key) or {}
    if not isinstance(value, dict):
        raise TypeError(f"{key!r} must be an object, got {type(value).__name__}")
    return value


def _dict(v: Any, what: str) -> dict:
    if not isinstance(v, dict):
        raise TypeError(f"{what} must be an object, got {type(v).__name__}")
    return v


def _vec(v: Any, n: int, what: str) -> list[float]:
    # the common case first (tens of thousands of view points per file): a list of n finite numbers
    if type(v) is list and len(v) == n and all(type(x) is float or type(x) is int for x in v):
        out = [float(x) for x in v]
        if all(map(math.isfinite, out)):
            return out
    if not isinstance(v, (list, tuple)) or any(isinstance(x, (str, bool)) for x in v):
        raise ValueError(f"{what} must be {n} finite numbers, got {v!r}"[:200])
    out = [float(x) for x in v]
    if len(out) != n or not all(math.isfinite(x) for x in out):
        raise ValueError(f"{what} must be {n} finite numbers, got {v!r}")
    return out


def _episode(raw: dict, path: Path) -> Episode:
    eid = str(raw.get("episode_id", "?"))[:40] if isinstance(raw, dict) else "?"
    try:
        raw = _dict(raw, "an episode")
        goals: list[NavigationGoal | ObjectGoal] = []
        raw_goals = raw.get("goals", []) or []
        if not isinstance(raw_goals, list):
            raise TypeError(f"goals must be a list, got {type(raw_goals).__name__}")
        for g in raw_goals:
            g = _dict(g, "a goal")
            if "object_id" in g or "view_points" in g:
                goals.append(_object_goal(g))
            else:
                goals.append(NavigationGoal(position=_vec(g["position"], 3, "goal position"),
                                            radius=_radius(g.get("radius")),
                                            extra={k: v for k, v in g.items() if k not in ("position", "radius")}))
        for key in ("episode_id", "scene_id"):
            if not isinstance(raw.get(key), (str, int)) or isinstance(raw.get(key), bool):
                raise TypeError(f"{key} must be a string, got {raw.get(key)!r}"[:200])
        category = raw.get("object_category")
        if category is not None and not isinstance(category, str):
            raise TypeError(f"object_category must be a string, got {category!r}"[:200])
        return Episode(
            episode_id=eid,
            scene_id=str(raw["scene_id"]),
            start_position=_vec(raw["start_position"], 3, "start_position"),
            start_rotation=_vec(raw["start_rotation"], 4, "start_rotation"),
            goals=goals,
            info=dict(_mapping(raw, "info")),
            object_category=category,
            extra={k: v for k, v in raw.items() if k not in _EPISODE_KEYS},
        )
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise EpisodeError(f"{path}: episode {eid}: {type(exc).__name__}: {exc}") from None


def _radius(r: Any) -> float | None:
    """A goal's radius: None (the task's success distance) or a finite non-negative number."""
    if r is None:
        return None
    if isinstance(r, bool) or not isinstance(r, (int, float)) or not math.isfinite(r) or r < 0:
        raise ValueError(f"goal radius must be a finite number >= 0 or null, got {r!r}"[:200])
    return float(r)


def _object_goal(g: dict) -> ObjectGoal:
    g = _dict(g, "an object goal")
    raw_vps = g.get("view_points", []) or []
    if not isinstance(raw_vps, list):
        raise TypeError(f"view_points must be a list, got {type(raw_vps).__name__}")
    vps = []
    for vp in raw_vps:
        state = _dict(_dict(vp, "a view point").get("agent_state"), "a view point's agent_state")
        vps.append(ViewPoint(AgentState(_vec(state["position"], 3, "view point position"),
                                        _vec(state.get("rotation", [0, 0, 0, 1]), 4, "view point rotation")),
                             _number(vp.get("iou", 0.0), "view point iou")))
    extra = {k: v for k, v in g.items() if k not in _OBJECT_GOAL_KEYS}
    raw_id = g.get("object_id", -1)
    name = str(g.get("object_name", ""))
    if isinstance(raw_id, str):
        object_id = ovon_object_index(raw_id)
        extra["object_id"] = raw_id  # written back as it was read
        name = name or raw_id
    else:
        object_id = int(_number(raw_id, "object_id"))
    return ObjectGoal(
        position=_vec(g["position"], 3, "goal position"),
        object_id=object_id,
        object_category=str(g.get("object_category", "")),
        radius=_radius(g.get("radius")),
        object_name=name,
        room_id=g.get("room_id"),
        room_name=g.get("room_name"),
        view_points=vps,
        extra=extra,
    )


def ovon_object_index(object_id: str) -> int:
    """The integer OVON's reader takes from a habitat-sim object name: the number after the last ``_``
    (``"couch_0"`` -> 0; naokiyokoyama/ovon ``ovon/dataset/ovon_dataset.py``); ValueError otherwise."""
    head, sep, tail = object_id.rpartition("_")
    if not sep or not head or not tail.isdigit():
        raise ValueError(f"object_id must be an integer or a habitat-sim object name 'name_N', got {object_id!r}"[:200])
    return int(tail)


def is_ovon(dataset: EpisodeDataset) -> bool:
    """Whether a dataset is in HM3D-OVON's format, read from what OVON's generator writes and
    ObjectNav-v1's never does: goal ``object_id``s as object names, or ``children_object_categories``
    on goals (naokiyokoyama/ovon ``ovon/dataset/objectnav_generator.py``, ``_make_goal``) or episodes
    (``ovon/dataset/ovon_dataset.py``, ``OVONEpisode``)."""
    goals = [g for gs in dataset.goals_by_category.values() for g in gs]
    goals += [g for ep in dataset.episodes for g in ep.goals]
    if any(isinstance(g, ObjectGoal) and (isinstance(g.extra.get("object_id"), str)
                                          or "children_object_categories" in g.extra) for g in goals):
        return True
    return any("children_object_categories" in ep.extra for ep in dataset.episodes)


def _number(v: Any, what: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ValueError(f"{what} must be a finite number, got {v!r}"[:200])
    return float(v)


# -------------------------------------------------------------------------------------------- write
def _r(v: Any) -> Any:
    """Round floats (recursively) to 5 decimals, as Habitat's published files are."""
    if isinstance(v, float):
        return round(v, 5)
    if isinstance(v, (list, tuple)):
        return [_r(x) for x in v]
    if isinstance(v, dict):
        return {k: _r(x) for k, x in v.items()}
    if hasattr(v, "tolist"):
        return _r(v.tolist())
    return v


def object_goal_to_json(g: ObjectGoal) -> dict:
    out = {
        "position": g.position, "radius": g.radius, "object_id": g.object_id, "object_name": g.object_name,
        "object_category": g.object_category, "room_id": g.room_id, "room_name": g.room_name,
        "view_points": [{"agent_state": {"position": vp.agent_state.position, "rotation": vp.agent_state.rotation},
                         "iou": vp.iou} for vp in g.view_points],
    }
    out.update(g.extra)
    return _r(out)


def episode_to_json(ep: Episode, objectnav: bool) -> dict:
    out: dict[str, Any] = {
        "episode_id": ep.episode_id,
        "scene_id": ep.scene_id,
        "start_position": ep.start_position,
        "start_rotation": ep.start_rotation,
        "info": ep.info,
        # ObjectNav-v1 keeps goals in goals_by_category and leaves the episode's list empty.
        "goals": [] if objectnav else [dict({"position": g.position, "radius": g.radius}, **g.extra)
                                       for g in ep.goals],
    }
    if ep.object_category is not None:
        out["object_category"] = ep.object_category
    out.update(ep.extra)
    return _r(out)


def dataset_to_json(dataset: EpisodeDataset) -> dict:
    objectnav = dataset.task == "objectnav"
    out: dict[str, Any] = {"episodes": [episode_to_json(e, objectnav) for e in dataset.episodes]}
    if objectnav:
        gbc = dict(dataset.goals_by_category)
        for ep in dataset.episodes:  # goals attached only to episodes still reach the file
            key = goals_key(ep.scene_id, ep.object_category or "")
            if key not in gbc and ep.goals:
                gbc[key] = [g for g in ep.goals if isinstance(g, ObjectGoal)]
        out["goals_by_category"] = {k: [object_goal_to_json(g) for g in v] for k, v in sorted(gbc.items())}
        out["category_to_task_category_id"] = dataset.category_to_task_category_id
        out["category_to_scene_annotation_category_id"] = dataset.category_to_scene_annotation_category_id
    out.update(dataset.extra)
    return out


def save_dataset(dataset: EpisodeDataset, path: str | Path) -> Path:
    """Write ``.json`` or ``.json.gz`` (by suffix); gzip output carries no timestamp so it is byte-stable."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(dataset_to_json(dataset), separators=(",", ":")).encode()
    tmp = path.with_name(path.name + ".tmp")
    if path.suffix == ".gz":
        tmp.write_bytes(gzip.compress(text, mtime=0))
    else:
        tmp.write_bytes(text)
    tmp.replace(path)
    return path
