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
from pathlib import Path

from navbench.safeio import InputTooLarge, max_input_bytes, read_input, too_large
from navbench.scene.annotations import ObjectAnnotation, RoomAnnotation
from navbench.scene.errors import SceneError
from navbench.scene.mesh_io import read_mesh
from navbench.scene.types import SceneAsset


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
    from navbench.scene.datasets import instances

    if instances.is_scene_instance(path):  # a stage plus object instances (HSSD, ReplicaCAD)
        return instances.load(path)
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
