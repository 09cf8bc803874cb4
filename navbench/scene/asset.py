"""A scene as every later stage sees it: one merged triangle mesh plus per-object semantics.

Scenes on disk are a mesh file (``.glb`` for ours; any GLB/OBJ/PLY a user brings) and, optionally,
a sidecar ``{stem}.semantic.json`` with the per-object annotations::

    {"scene_id": "house_008",
     "rooms":   [{"name": "kitchen", "aabb": {"min": [x,y,z], "max": [x,y,z]}}, ...],
     "objects": [{"id": 3, "category": "chair", "room": "kitchen", "colour": "blue",
                  "colour_rgb": [40, 60, 200], "aabb": {"min": [...], "max": [...]}}, ...]}

Inside a GLB, geometry belonging to object ``k`` sits under a node named ``obj_{k}``; every other
node is structure (walls, floor, ceiling, door frames) and gets instance id -1.

Coordinates are Habitat's: metres, y up, the floor of a house at y = 0.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

OBJECT_NODE = re.compile(r"^obj_(\d+)$")
STRUCTURE_ID = -1


class SceneError(ValueError):
    """A scene file is missing, unreadable or unusable; the message names the file."""


@dataclass(frozen=True)
class ObjectAnnotation:
    id: int
    category: str
    room: str
    colour: str
    colour_rgb: tuple[int, int, int]
    aabb_min: tuple[float, float, float]
    aabb_max: tuple[float, float, float]

    @property
    def center(self) -> np.ndarray:
        return (np.asarray(self.aabb_min) + np.asarray(self.aabb_max)) / 2.0

    def to_json(self) -> dict:
        return {
            "id": self.id,
            "category": self.category,
            "room": self.room,
            "colour": self.colour,
            "colour_rgb": list(self.colour_rgb),
            "aabb": {"min": [round(v, 5) for v in self.aabb_min], "max": [round(v, 5) for v in self.aabb_max]},
        }

    @classmethod
    def from_json(cls, d: dict) -> "ObjectAnnotation":
        return cls(
            id=int(d["id"]),
            category=str(d["category"]),
            room=str(d.get("room", "")),
            colour=str(d.get("colour", "")),
            colour_rgb=_rgb(d.get("colour_rgb", (128, 128, 128))),
            aabb_min=_xyz(d["aabb"]["min"]),
            aabb_max=_xyz(d["aabb"]["max"]),
        )


@dataclass(frozen=True)
class RoomAnnotation:
    name: str
    aabb_min: tuple[float, float, float]
    aabb_max: tuple[float, float, float]

    def to_json(self) -> dict:
        return {"name": self.name, "aabb": {"min": list(self.aabb_min), "max": list(self.aabb_max)}}

    @classmethod
    def from_json(cls, d: dict) -> "RoomAnnotation":
        return cls(
            name=str(d["name"]),
            aabb_min=_xyz(d["aabb"]["min"]),
            aabb_max=_xyz(d["aabb"]["max"]),
        )


def _xyz(v: object) -> tuple[float, float, float]:
    """Three finite coordinates, or ValueError/TypeError."""
    if not isinstance(v, (list, tuple)) or len(v) != 3 or any(isinstance(x, (str, bool)) for x in v):
        raise ValueError(f"expected 3 numbers, got {v!r}"[:120])
    out = tuple(float(x) for x in v)
    if not all(np.isfinite(out)):
        raise ValueError(f"expected 3 finite numbers, got {v!r}"[:120])
    return out  # type: ignore[return-value]


def _rgb(v: object) -> tuple[int, int, int]:
    if not isinstance(v, (list, tuple)) or len(v) != 3 or any(isinstance(x, (str, bool)) for x in v):
        raise ValueError(f"colour_rgb must be 3 integers, got {v!r}"[:120])
    return tuple(int(c) for c in v)  # type: ignore[return-value]


@dataclass
class SceneAsset:
    """A loaded scene: merged mesh (world frame, RGBA vertex colours), per-face instance ids, semantics."""

    scene_id: str
    path: Path
    mesh: trimesh.Trimesh
    face_ids: np.ndarray  # (F,) int32: object id of each face, -1 for structure
    objects: dict[int, ObjectAnnotation] = field(default_factory=dict)
    rooms: list[RoomAnnotation] = field(default_factory=list)

    def objects_of(self, category: str) -> list[ObjectAnnotation]:
        return [o for o in self.objects.values() if o.category == category]

    @property
    def categories(self) -> list[str]:
        return sorted({o.category for o in self.objects.values()})


def semantic_path(mesh_path: Path) -> Path:
    mesh_path = Path(mesh_path)
    return mesh_path.with_name(mesh_path.name.split(".")[0] + ".semantic.json")


def load_scene(path: str | Path) -> SceneAsset:
    """Load a GLB/OBJ/PLY scene and its sidecar annotations (if any) into a :class:`SceneAsset`."""
    path = Path(path)
    if not path.is_file():
        raise SceneError(f"{path}: scene file not found")
    try:
        loaded = trimesh.load(str(path), force="scene", process=False)
    except Exception as exc:  # trimesh raises many types for a bad file
        raise SceneError(f"{path}: cannot read mesh ({type(exc).__name__}: {exc})") from None
    parts: list[trimesh.Trimesh] = []
    ids: list[np.ndarray] = []
    for node in loaded.graph.nodes_geometry:
        transform, geom_name = loaded.graph[node]
        geom = loaded.geometry[geom_name]
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue
        part = geom.copy()
        part.apply_transform(transform)
        colours = _vertex_colours(part)
        part = trimesh.Trimesh(part.vertices, part.faces, vertex_colors=colours, process=False)
        m = OBJECT_NODE.match(str(node)) or OBJECT_NODE.match(str(geom_name))
        parts.append(part)
        ids.append(np.full(len(part.faces), int(m.group(1)) if m else STRUCTURE_ID, np.int32))
    if not parts:
        raise SceneError(f"{path}: mesh has no triangles")
    mesh = trimesh.util.concatenate(parts) if len(parts) > 1 else parts[0]
    face_ids = np.concatenate(ids)
    if mesh.vertices.ndim != 2 or mesh.vertices.shape[1] != 3:
        raise SceneError(f"{path}: mesh vertices are not 3-D points (shape {mesh.vertices.shape})")
    if not np.isfinite(mesh.vertices).all():
        raise SceneError(f"{path}: mesh has non-finite vertex coordinates")

    objects: dict[int, ObjectAnnotation] = {}
    rooms: list[RoomAnnotation] = []
    sem = semantic_path(path)
    scene_id = path.name.split(".")[0]
    if sem.is_file():
        try:
            data = json.loads(sem.read_bytes())
            if not isinstance(data, dict) or not all(isinstance(data.get(k, []), list) for k in ("objects", "rooms")):
                raise TypeError("expected an object with 'objects' and 'rooms' lists")
            objects = {o.id: o for o in map(ObjectAnnotation.from_json, data.get("objects", []))}
            rooms = [RoomAnnotation.from_json(r) for r in data.get("rooms", [])]
            scene_id = str(data.get("scene_id", scene_id))
        except (ValueError, KeyError, TypeError, AttributeError, IndexError, OverflowError, RecursionError) as exc:
            raise SceneError(f"{sem}: corrupt semantic annotation ({type(exc).__name__}: {exc})"[:300]) from None
    return SceneAsset(scene_id=scene_id, path=path, mesh=mesh, face_ids=face_ids, objects=objects, rooms=rooms)


def _vertex_colours(mesh: trimesh.Trimesh) -> np.ndarray:
    """RGBA uint8 per vertex, whatever the file stored (vertex colours, a material, or nothing)."""
    visual = mesh.visual
    try:
        if visual.kind in ("vertex", "face"):
            # trimesh interpolates face colours onto vertices; our scenes never share a vertex
            # between differently coloured faces, so nothing is blurred.
            return np.asarray(visual.vertex_colors, np.uint8)
        if visual.kind == "texture":
            return np.asarray(visual.to_color().vertex_colors, np.uint8)
    except Exception:
        pass
    return np.tile(np.array([180, 180, 180, 255], np.uint8), (len(mesh.vertices), 1))
