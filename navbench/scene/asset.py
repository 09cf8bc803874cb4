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

Scans keep their base-colour textures (GLB/glTF, OBJ+MTL; Basis Universal via
:mod:`navbench.scene.textures`) beside the vertex colours, and read their annotations from the
dataset's own files (HM3D ``*.semantic.txt`` + ``*.semantic.glb``, MP3D ``*_semantic.ply`` +
``*.house``; see :mod:`navbench.scene.datasets`) when no ``.semantic.json`` sidecar is present.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from navbench.safeio import InputTooLarge, max_input_bytes, read_input, too_large
from navbench.scene.errors import SceneError

OBJECT_NODE = re.compile(r"^obj_(\d+)$")
STRUCTURE_ID = -1


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
    # Textured scans: per-vertex texture coordinates (OpenGL convention, v up), per-face index into
    # ``textures`` (-1: the face is drawn with its vertex colours) and the RGBA base-colour images
    # (row 0 at the top). None / empty for vertex-coloured scenes.
    uv: np.ndarray | None = None
    face_texture: np.ndarray | None = None
    textures: list[np.ndarray] = field(default_factory=list)

    @property
    def is_textured(self) -> bool:
        return self.face_texture is not None and bool((self.face_texture >= 0).any())

    def objects_of(self, category: str) -> list[ObjectAnnotation]:
        return [o for o in self.objects.values() if o.category == category]

    @property
    def categories(self) -> list[str]:
        return sorted({o.category for o in self.objects.values()})


def semantic_path(mesh_path: Path) -> Path:
    mesh_path = Path(mesh_path)
    return mesh_path.with_name(mesh_path.name.split(".")[0] + ".semantic.json")


def load_scene(path: str | Path) -> SceneAsset:
    """Load a GLB/glTF/OBJ/PLY scene and its annotations (if any) into a :class:`SceneAsset`.

    Annotations come from the ``.semantic.json`` sidecar, else from the dataset files beside the
    mesh (:func:`navbench.scene.datasets.load_annotations`). A ``*.scene_dataset_config.json`` above
    the mesh may declare the mesh's up/front axes; the mesh is then rotated into Habitat's frame.
    """
    from navbench.scene import datasets

    path = Path(path)
    if not path.is_file():
        raise SceneError(f"{path}: scene file not found")
    if path.stat().st_size > max_input_bytes():
        raise SceneError(str(too_large(path, max_input_bytes(), "on disk")))
    stage = datasets.stage_attributes(path)
    mesh, face_ids, uv, face_texture, textures = read_mesh(path)
    frame = datasets.frame_rotation(stage)
    if frame is not None:
        mesh.vertices = mesh.vertices @ frame.T
    if mesh.vertices.ndim != 2 or mesh.vertices.shape[1] != 3:
        raise SceneError(f"{path}: mesh vertices are not 3-D points (shape {mesh.vertices.shape})")

    objects: dict[int, ObjectAnnotation] = {}
    rooms: list[RoomAnnotation] = []
    sem = semantic_path(path)
    scene_id = path.name.split(".")[0]
    if sem.is_file():
        try:
            data = json.loads(read_input(sem, gunzip=False))
            if not isinstance(data, dict) or not all(isinstance(data.get(k, []), list) for k in ("objects", "rooms")):
                raise TypeError("expected an object with 'objects' and 'rooms' lists")
            objects = {o.id: o for o in map(ObjectAnnotation.from_json, data.get("objects", []))}
            rooms = [RoomAnnotation.from_json(r) for r in data.get("rooms", [])]
            scene_id = str(data.get("scene_id", scene_id))
        except InputTooLarge as exc:
            raise SceneError(str(exc)) from None
        except (ValueError, KeyError, TypeError, AttributeError, IndexError, OverflowError, RecursionError) as exc:
            raise SceneError(f"{sem}: corrupt semantic annotation ({type(exc).__name__}: {exc})"[:300]) from None
    else:
        found = datasets.load_annotations(path, mesh, stage)
        if found is not None:
            face_ids, objects, rooms = found
    return SceneAsset(scene_id=scene_id, path=path, mesh=mesh, face_ids=face_ids, objects=objects, rooms=rooms,
                      uv=uv, face_texture=face_texture, textures=textures)


def read_mesh(path: Path) -> tuple[trimesh.Trimesh, np.ndarray, np.ndarray | None, np.ndarray | None,
                                   list[np.ndarray]]:
    """Merged mesh (vertex colours), per-face ids from ``obj_{k}`` node names, and the texture table.

    Returns ``(mesh, face_ids, uv, face_texture, textures)``; the last three are None, None, [] for a
    scene without textures, which keeps the vertex-colour path exactly as it was.
    """
    from navbench.scene import textures as tx

    suffix = path.suffix.lower()
    source: object = str(path)
    kwargs: dict = {}
    if suffix == ".glb":
        prepared = tx.prepare_glb(path)
        if prepared is not None:
            source, kwargs = trimesh.util.wrap_as_stream(prepared), {"file_type": "glb"}
    elif suffix == ".gltf":
        tx.check_gltf_images(path)
    elif suffix == ".obj":
        tx.check_obj_textures(path)
    try:
        loaded = trimesh.load(source, force="scene", process=False, **kwargs)
        return _merge_parts(path, loaded)
    except SceneError:
        raise
    except Exception as exc:  # trimesh raises many types for a bad file
        raise SceneError(f"{path}: cannot read mesh ({type(exc).__name__}: {exc})") from None
    finally:
        tx.forget_decoded(path)


def _merge_parts(path: Path, loaded: trimesh.Scene):
    from navbench.scene import textures as tx

    parts: list[trimesh.Trimesh] = []
    ids: list[np.ndarray] = []
    part_uv: list[np.ndarray | None] = []
    part_tex: list[int] = []
    images: list[np.ndarray] = []
    image_index: dict[int, int] = {}
    for node in loaded.graph.nodes_geometry:
        transform, geom_name = loaded.graph[node]
        geom = loaded.geometry[geom_name]
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            continue
        part = geom
        if not np.allclose(transform, np.eye(4)):
            part = geom.copy()
            part.apply_transform(transform)
        tex = -1
        uv = None
        colours = None
        if part.visual.kind == "texture":
            material = part.visual.material
            image = getattr(material, "baseColorTexture", None) or getattr(material, "image", None)
            if image is not None and part.visual.uv is not None and len(part.visual.uv) == len(part.vertices):
                key = id(image)
                if key not in image_index:
                    image_index[key] = len(images)
                    images.append(tx.texture_image(part.visual))
                tex = image_index[key]
                uv = np.asarray(part.visual.uv, np.float32)
                # Vertex colours (for consumers of the merged mesh's colours): the texel under each vertex.
                colours = tx.sample(images[tex], uv)
        if colours is None:
            colours = _vertex_colours(part)
        part = trimesh.Trimesh(part.vertices, part.faces, vertex_colors=colours, process=False)
        m = OBJECT_NODE.match(str(node)) or OBJECT_NODE.match(str(geom_name))
        parts.append(part)
        ids.append(np.full(len(part.faces), int(m.group(1)) if m else STRUCTURE_ID, np.int32))
        part_uv.append(uv)
        part_tex.append(tex)
    if not parts:
        raise SceneError(f"{path}: mesh has no triangles")
    mesh = trimesh.util.concatenate(parts) if len(parts) > 1 else parts[0]
    face_ids = np.concatenate(ids)
    if not np.isfinite(mesh.vertices).all():
        raise SceneError(f"{path}: mesh has non-finite vertex coordinates")
    if not images:
        return mesh, face_ids, None, None, []
    uv_all = np.concatenate([u if u is not None else np.zeros((len(p.vertices), 2), np.float32)
                             for u, p in zip(part_uv, parts)])
    face_texture = np.concatenate([np.full(len(p.faces), t, np.int32) for t, p in zip(part_tex, parts)])
    return mesh, face_ids, uv_all, face_texture, images


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
