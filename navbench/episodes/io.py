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

import codecs
import gzip
import json
import math
import os
import re
import zlib
from collections.abc import Callable, Iterator
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
from navbench.safeio import InputTooLarge, open_input, read_input

_EPISODE_KEYS = {"episode_id", "scene_id", "start_position", "start_rotation", "goals", "info", "object_category"}
_OBJECT_GOAL_KEYS = {"position", "radius", "object_id", "object_category", "object_name", "room_id", "room_name",
                     "view_points"}


def file_split(path: str | Path) -> str:
    """The split name a user's episode file goes by (its name up to the first dot): runs of it are filed
    under ``runs/<task>/<file_split>/`` and tabulated with it."""
    return Path(path).name.split(".")[0]


def goals_key(scene_id: str, category: str) -> str:
    """Habitat's ``goals_by_category`` key: basename of the scene path (with its extension) + category."""
    return f"{os.path.basename(scene_id)}_{category}"


# --------------------------------------------------------------------------------------------- read
_READ_ERRORS = (OSError, EOFError, zlib.error, gzip.BadGzipFile, UnicodeDecodeError, json.JSONDecodeError)
READ_FAILURES = (InputTooLarge, *_READ_ERRORS)  # a JSON(.gz) file too large, unreadable, corrupt or truncated


def read_failure(path: Path, exc: BaseException) -> EpisodeError:
    """The one-line error naming ``path`` for one of :data:`READ_FAILURES`."""
    if isinstance(exc, InputTooLarge):
        return EpisodeError(str(exc))  # it names the file and the cap
    return EpisodeError(f"{path}: corrupt or truncated JSON ({type(exc).__name__}: {exc})")


def read_json(path: str | Path, cap: int | None = None) -> Any:
    """A whole JSON(.gz) file, at most ``cap`` bytes decompressed (default: the input cap of
    :mod:`navbench.safeio`); EpisodeError naming the file otherwise."""
    path = Path(path)
    if not path.is_file():
        raise EpisodeError(f"{path}: file not found")
    try:
        return json.loads(read_input(path, cap))
    except READ_FAILURES as exc:
        raise read_failure(path, exc) from None
    except RecursionError:
        raise EpisodeError(f"{path}: JSON nested too deeply to read") from None


MAX_VALUE_CHARS = 64 << 20  # one episode, one goal list or one other top-level value, held whole
_WS = re.compile(r"[ \t\n\r]*")
_CHUNK = 1 << 20


class _JsonStream:
    """A JSON document read incrementally: its top-level object's members one by one, the elements of an
    array member one by one. At most one value (``MAX_VALUE_CHARS``) is held as text at a time."""

    def __init__(self, fh, max_value: int = MAX_VALUE_CHARS) -> None:
        self.fh, self.max_value = fh, max_value
        self.text = codecs.getincrementaldecoder("utf-8")()
        self.decoder = json.JSONDecoder()
        self.buf, self.pos, self.eof = "", 0, False

    def _more(self, at_least: int = _CHUNK) -> bool:
        if self.eof:
            return False
        parts, got = [self.buf[self.pos:]], 0
        while got < at_least:
            data = self.fh.read(_CHUNK)
            if not data:
                self.eof = True
                parts.append(self.text.decode(b"", final=True))
                break
            got += len(data)
            parts.append(self.text.decode(data))
        self.buf, self.pos = "".join(parts), 0
        return True

    def peek(self) -> str:
        """The next character that is not whitespace ("" at the end)."""
        while True:
            self.pos = _WS.match(self.buf, self.pos).end()
            if self.pos < len(self.buf):
                return self.buf[self.pos]
            if not self._more():
                return ""

    def expect(self, chars: str) -> str:
        c = self.peek()
        if not c or c not in chars:
            raise json.JSONDecodeError(f"expected {' or '.join(map(repr, chars))}", self.buf, self.pos)
        self.pos += 1
        return c

    def value(self) -> Any:
        """The next complete JSON value."""
        self.peek()
        while True:
            try:
                v, end = self.decoder.raw_decode(self.buf, self.pos)
                if end < len(self.buf) or self.eof:  # a number may go on in the next chunk
                    self.pos = end
                    return v
            except json.JSONDecodeError as exc:  # the end of the buffer, or a real error
                if self.eof or not (exc.msg.startswith("Unterminated string") or exc.pos >= len(self.buf) - 16):
                    raise
            held = len(self.buf) - self.pos
            if held > self.max_value:
                raise ValueError(f"a single JSON value longer than {self.max_value >> 20} Mi characters")
            # geometric growth (a long value is parsed O(1) times over), stopping just past the cap
            self._more(max(min(held, self.max_value + 1 - held), _CHUNK))

    def members(self):
        """The top-level object's keys; the caller reads each key's value before asking for the next."""
        self.expect("{")
        if self.peek() == "}":
            self.pos += 1
        else:
            while True:
                key = self.value()
                if not isinstance(key, str):
                    raise json.JSONDecodeError("expected a key", self.buf, self.pos)
                self.expect(":")
                yield key
                if self.expect(",}") == "}":
                    break
        if self.peek():
            raise json.JSONDecodeError("extra data after the document", self.buf, self.pos)

    def elements(self):
        """The elements of the array that comes next."""
        self.expect("[")
        if self.peek() == "]":
            self.pos += 1
            return
        while True:
            yield self.value()
            if self.expect(",]") == "]":
                return

    def items(self):
        """The (key, value) pairs of the object that comes next."""
        self.expect("{")
        if self.peek() == "}":
            self.pos += 1
            return
        while True:
            key = self.value()
            if not isinstance(key, str):
                raise json.JSONDecodeError("expected a key", self.buf, self.pos)
            self.expect(":")
            yield key, self.value()
            if self.expect(",}") == "}":
                return


class _Pass:
    """One read of a dataset file (and its ``content/`` files): the episodes' raw dicts in file order,
    and the file's other members collected into ``dataset`` as they go by."""

    def __init__(self, path: Path, cap: int | None) -> None:
        self.path, self.cap, self.dataset = path, cap, EpisodeDataset()
        self._iter = None

    def raw(self):
        """(raw episode, file it is in) for every episode, in file order; one read per pass."""
        if self._iter is None:
            self._iter = self._raw()
        return self._iter

    def close(self) -> None:
        """Close the file of a pass left before its end (a selection that stopped early)."""
        if self._iter is not None:
            self._iter.close()

    def _raw(self):
        n = 0
        for item in self._file(self.path, top=True):
            n += 1
            yield item
        content = self.path.parent / "content"
        if n == 0 and content.is_dir():
            for f in sorted(content.iterdir()):
                if f.name.endswith((".json", ".json.gz")):
                    yield from self._file(f, top=False)

    def _file(self, path: Path, top: bool):
        try:
            with open_input(path, self.cap) as fh:
                stream = _JsonStream(fh)
                if stream.peek() != "{":
                    if top:
                        raise EpisodeError(f"{path}: not a Habitat episode dataset (no top-level 'episodes')")
                    raise TypeError("'episodes' must be a list of episodes")
                seen = False
                for key in stream.members():
                    if key == "episodes":
                        seen = True
                        if stream.peek() != "[":
                            raise TypeError("'episodes' must be a list of episodes")
                        for raw in stream.elements():
                            yield raw, path
                    else:
                        self._member(stream, key)
                if not seen:
                    if top:
                        raise EpisodeError(f"{path}: not a Habitat episode dataset (no top-level 'episodes')")
                    raise TypeError("'episodes' must be a list of episodes")
        except EpisodeError:
            raise
        except READ_FAILURES as exc:
            raise read_failure(path, exc) from None
        except RecursionError:
            raise EpisodeError(f"{path}: JSON nested too deeply to read") from None
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise EpisodeError(f"{path}: malformed dataset ({type(exc).__name__}: {exc})") from None

    def _member(self, stream: _JsonStream, key: str) -> None:
        dataset = self.dataset
        if key == "goals_by_category":
            if stream.peek() != "{":
                value = stream.value()
                if value:
                    raise TypeError(f"'goals_by_category' must be an object, got {type(value).__name__}")
                return
            for k, goals in stream.items():
                if not isinstance(goals, list):
                    raise TypeError(f"goals_by_category[{k!r}] must be a list of goals")
                dataset.goals_by_category[k] = [_object_goal(g) for g in goals]
        elif key in ("category_to_task_category_id", "category_to_scene_annotation_category_id"):
            table = _mapping({key: stream.value()}, key)
            if not all(isinstance(v, int) and not isinstance(v, bool) for v in table.values()):
                raise TypeError(f"{key} must map category names to integer ids")
            getattr(dataset, key).update(table)
        else:
            dataset.extra.setdefault(key, stream.value())


EpisodeStream = Callable[..., Iterator[Episode]]


def load_dataset(path: str | Path,
                 select: Callable[[EpisodeStream], list[Episode]] | None = None,
                 cap: int | None = None, require_goals: bool = True) -> EpisodeDataset:
    """Load a dataset file (and its ``content/`` per-scene files when present), streamed: only the
    episodes kept are held in memory. ``select(stream)`` picks them: ``stream()`` reads the file (again)
    and yields its episodes in file order, ``stream(keys=True)`` only their ``(scene_id, episode_id)``;
    it may stop early. Each file is read at most ``cap`` bytes decompressed (see :mod:`navbench.safeio`).
    ``require_goals=False`` accepts episodes without goals (a VLN-CE test split has none)."""
    path = Path(path)
    if not path.is_file():
        raise EpisodeError(f"{path}: file not found")
    passes: list[_Pass] = []  # the episode passes; the last one's members make the dataset
    opened: list[_Pass] = []  # every pass, to be closed however far it was read

    def stream(keys: bool = False) -> Iterator[Any]:
        p = _Pass(path, cap)
        opened.append(p)
        if not keys:
            passes.append(p)
        return _keys(p.raw()) if keys else _episodes(p.raw())

    episodes = list(stream()) if select is None else list(select(stream))
    last = passes[-1] if passes else _Pass(path, cap)
    for _ in last.raw():  # the members after the episodes (the rest of them only parsed, not kept)
        pass
    for p in opened:
        p.close()
    return _finish(last, episodes, path, require_goals)


def episode_keys(path: str | Path, cap: int | None = None) -> set[tuple[str, str]]:
    """The ``(scene_id, episode_id)`` of every episode in a dataset file, without holding the episodes."""
    keys: set[tuple[str, str]] = set()

    def collect(stream: EpisodeStream) -> list[Episode]:
        keys.update(stream(keys=True))
        return []
    load_dataset(path, collect, cap)
    return keys


def file_task(path: str | Path, cap: int | None = None, habitat_v1: bool = False) -> str | None:
    """The task a file's first episode belongs to when its fields name one: ``"goat"`` for GOAT-Bench's
    ``tasks`` (goat-bench ``GoatEpisode``), ``"instance_imagenav"`` for InstanceImageNav's ``goal_image_id``
    (habitat-lab ``InstanceImageGoalNavEpisode``), ``"rxr_ce"`` / ``"r2r_ce"`` for VLN-CE's ``instruction``
    object (habitat-lab v0.1.7 ``VLNEpisode``; RxR's carries ``language`` and ``instruction_id``, VLN-CE
    ``RxRVLNCEDatasetV1``); None otherwise (PointNav-v1 / ObjectNav-v1: see :attr:`EpisodeDataset.task`), or with
    ``habitat_v1`` ``"objectnav"`` / ``"pointnav"`` by the first episode's ``object_category``. Reads up to the
    first episode (of the ``content/`` files too)."""
    p = _Pass(Path(path), cap)
    try:
        for raw, _ in p.raw():
            if isinstance(raw, dict) and "tasks" in raw:
                return "goat"
            if isinstance(raw, dict) and "goal_image_id" in raw:
                return "instance_imagenav"
            if isinstance(raw, dict) and isinstance(raw.get("instruction"), dict):
                ins = raw["instruction"]
                return "rxr_ce" if "language" in ins or "instruction_id" in ins else "r2r_ce"
            if habitat_v1 and isinstance(raw, dict):
                return "objectnav" if raw.get("object_category") is not None else "pointnav"
            return None
    except EpisodeError:
        return None  # the task's own reader names what is wrong
    finally:
        p.close()
    return None


def _keys(raws) -> Iterator[tuple[str, str]]:
    for raw, _ in raws:
        yield (str(raw.get("scene_id")), _episode_id(raw)) if isinstance(raw, dict) else ("?", "?")


def _episodes(raws) -> Iterator[Episode]:
    for raw, f in raws:
        yield _episode(raw, f)


def _episode_id(raw: Any) -> str:
    return str(raw.get("episode_id", "?"))[:40] if isinstance(raw, dict) else "?"


def _finish(p: _Pass, episodes: list[Episode], path: Path, require_goals: bool = True) -> EpisodeDataset:
    dataset = p.dataset
    dataset.episodes = episodes
    for ep in dataset.episodes:
        if ep.object_category is None and not ep.goals and require_goals:
            raise EpisodeError(f"{path}: episode {ep.episode_id}: no goals and no object_category")
        if ep.object_category is not None and not ep.goals:
            key = goals_key(ep.scene_id, ep.object_category)
            goals = dataset.goals_by_category.get(key)
            if not goals:
                raise EpisodeError(f"{path}: episode {ep.episode_id}: no goals for category "
                                   f"'{ep.object_category}' (key '{key}' missing from goals_by_category)")
            ep.goals = list(goals)
    return dataset


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
    eid = _episode_id(raw)
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
    out: dict[str, Any] = {}
    if "split_version" in dataset.extra:  # first, so a reader finds it without parsing the episodes
        out["split_version"] = dataset.extra["split_version"]
    out["episodes"] = [episode_to_json(e, objectnav) for e in dataset.episodes]
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


def split_version(path: str | Path) -> int | None:
    """The ``split_version`` a navbench-generated file states first (``{"split_version":N,...``), else None.
    Reads at most the first 64 decompressed bytes."""
    try:
        with open_input(path) as fh:
            head = fh.read(64)
    except (OSError, EOFError, ValueError, zlib.error):
        return None
    m = re.match(rb'\{"split_version":(\d{1,6})[,}]', head)
    return int(m.group(1)) if m else None


def save_dataset(dataset: EpisodeDataset, path: str | Path) -> Path:
    """Write ``.json`` or ``.json.gz`` (by suffix); gzip output carries no timestamp so it is byte-stable."""
    return write_json(dataset_to_json(dataset), path)


def write_json(doc: Any, path: str | Path) -> Path:
    """``doc`` as compact JSON, gzipped by a ``.gz`` suffix, without a timestamp (byte-stable), written
    through a temporary file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(doc, separators=(",", ":")).encode()
    tmp = path.with_name(path.name + ".tmp")
    if path.suffix == ".gz":
        tmp.write_bytes(gzip.compress(text, mtime=0))
    else:
        tmp.write_bytes(text)
    tmp.replace(path)
    return path
