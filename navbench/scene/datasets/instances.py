"""Habitat scene instances (``*.scene_instance.json``): a stage plus object instances, composed into one scene.

This is the layout of ReplicaCAD and HSSD (Habitat's HSSD ObjectNav challenge). The keys read are
habitat-sim's (``src/esp/metadata/managers/SceneInstanceAttributesManager.cpp``, documented in
``docs/pages/attributesJSON.rst``)::

    {"stage_instance": {"template_name": "stages/102344049"},
     "translation_origin": "asset_local",                          # scene default, per instance overridable
     "object_instances": [{"template_name": "1efdc3d3...", "translation": [x, y, z],
                           "rotation": [w, x, y, z], "uniform_scale": 1.0, "non_uniform_scale": [sx, sy, sz],
                           "motion_type": "STATIC", "translation_origin": "COM"}, ...]}

* ``rotation`` is a quaternion written scalar first, ``[w, x, y, z]`` (``src/esp/io/JsonMagnumTypes.cpp``,
  ``fromJsonValue(..., Magnum::Quaternion&)``).
* A ``template_name`` is a handle: ``{name}.stage_config.json`` / ``{name}.object_config.json`` relative
  to the dataset root (the folder of the nearest ``*.scene_dataset_config.json``), else the config
  file of that base name anywhere under the root (HSSD names objects by hash only).
* The object config's ``render_asset`` (relative to the config), ``scale``, ``COM``, ``up``/``front``
  and ``semantic_id`` are used; the instance's scale is ``scale * uniform_scale * non_uniform_scale``.
* Translation origin (``src/esp/physics/PhysicsManager.cpp``, ``addObjectAndSaveAttributes``): an
  instance whose origin is ``asset_local`` (its own, or the scene's when it gives none) is placed by its
  asset's own origin; otherwise (``COM``) ``translation`` is where its centre of mass goes: the config's
  ``COM``, else its bounding-box centre (``src/esp/physics/RigidObject.cpp``, ``finalizeObject``).
* An instance with ``"is_instance_visible": false`` is left out.
* ``motion_type`` does not move anything here: every instance is placed where the file puts it (a
  DYNAMIC object is where physics would start it).
* Semantics, per instance: an object whose config has a ``semantic_id`` > 0 becomes instance
  ``k`` (its index in ``object_instances``), named by the dataset's semantic lexicon (a
  ``*semantic_lexicon*.json`` ``{"classes": [{"name", "id"}]}`` in the root or a folder of it) or ``semantic_{id}``
  without one. The stage is structure (instance id -1). Articulated objects are not composed.
* Rooms: a scene instance names none, so the stage's bounding box is one room (``stage``), which
  the memory pre-scan tours like any other.
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path

import numpy as np
import trimesh

from navbench.scene.annotations import ObjectAnnotation, RoomAnnotation
from navbench.scene.errors import SceneError
from navbench.scene.mesh_io import read_mesh
from navbench.scene.types import SceneAsset

SUFFIX = ".scene_instance.json"


def is_scene_instance(path: Path) -> bool:
    return Path(path).name.endswith(SUFFIX)


def _read(path: Path, what: str) -> dict:
    try:
        data = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise SceneError(f"{path}: unreadable {what} ({type(exc).__name__}: {exc})"[:300]) from None
    if not isinstance(data, dict):
        raise SceneError(f"{path}: a {what} must be a JSON object")
    return data


def dataset_root(path: Path, levels: int = 4) -> Path:
    """The folder of the nearest ``*.scene_dataset_config.json`` above ``path`` (else ``path``'s parent's parent)."""
    d = Path(path).resolve().parent
    for _ in range(levels + 1):
        if any(d.glob("*.scene_dataset_config.json")):
            return d
        if d.parent == d:
            break
        d = d.parent
    return Path(path).resolve().parent.parent


@lru_cache(maxsize=16)
def _index(root: Path, suffix: str) -> dict[str, Path]:
    return {p.name[: -len(suffix)]: p for p in sorted(root.rglob("*" + suffix))}


def _template(root: Path, name: str, suffix: str, where: Path) -> Path:
    direct = root / (name + suffix)
    if direct.is_file():
        return direct
    found = _index(root, suffix).get(Path(name).name)
    if found is None:
        raise SceneError(f"{where}: template '{name}' has no {suffix} under {root}")
    return found


def _vec(v, n: int, what: str, where: Path) -> np.ndarray:
    try:
        out = np.asarray(v, dtype=np.float64).reshape(n)
    except (TypeError, ValueError):
        raise SceneError(f"{where}: {what} must be {n} numbers, got {v!r}"[:200]) from None
    if not np.isfinite(out).all():
        raise SceneError(f"{where}: {what} must be finite, got {v!r}"[:200])
    return out


def _rotation_wxyz(q, where: Path) -> np.ndarray:
    w, x, y, z = _vec(q, 4, "rotation [w, x, y, z]", where)
    norm = np.sqrt(w * w + x * x + y * y + z * z)
    if norm < 1e-8:
        raise SceneError(f"{where}: rotation {list(q)} is not a rotation (zero quaternion)")
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _lexicon(root: Path) -> dict[int, str]:
    for f in sorted(root.glob("*semantic_lexicon*.json")) + sorted(root.glob("*/*semantic_lexicon*.json")):
        data = _read(f, "semantic lexicon")
        try:
            return {int(c["id"]): str(c["name"]) for c in data.get("classes", [])}
        except (KeyError, TypeError, ValueError):
            raise SceneError(f"{f}: semantic lexicon classes must be {{'name', 'id'}} objects") from None
    return {}


def _load_part(config_path: Path, config: dict):
    """(mesh, uv, face_texture, textures) of a stage/object config's render asset in its own frame."""
    from navbench.scene.datasets import frame_rotation

    asset = config.get("render_asset")
    if not isinstance(asset, str) or not asset:
        raise SceneError(f"{config_path}: no 'render_asset'")
    mesh_path = config_path.parent / asset
    if not mesh_path.is_file():
        raise SceneError(f"{config_path}: render_asset not found: {mesh_path}")
    mesh, _, uv, face_tex, textures = read_mesh(mesh_path)
    frame = frame_rotation(dict(config, __config__=str(config_path)))
    if frame is not None:
        mesh.vertices = mesh.vertices @ frame.T
    return mesh, uv, face_tex, textures


def load(path: Path):
    """A :class:`~navbench.scene.types.SceneAsset` composed from a scene instance file."""
    path = Path(path)
    doc = _read(path, "scene instance")
    root = dataset_root(path)
    stage = doc.get("stage_instance")
    if not isinstance(stage, dict) or not isinstance(stage.get("template_name"), str):
        raise SceneError(f"{path}: no 'stage_instance' with a 'template_name' (habitat-sim needs one)")
    scene_origin = str(doc.get("translation_origin", "")).lower()
    parts: list[tuple] = []  # (mesh, uv, face_tex, textures, instance id)
    stage_cfg_path = _template(root, stage["template_name"], ".stage_config.json", path)
    stage_cfg = _read(stage_cfg_path, "stage config")
    mesh, uv, ft, tex = _load_part(stage_cfg_path, stage_cfg)
    _place(mesh, stage, np.asarray(stage_cfg.get("scale", [1, 1, 1]), float), None, path)
    parts.append((mesh, uv, ft, tex, -1))
    lexicon = _lexicon(root)
    records: dict[int, str] = {}
    instances = doc.get("object_instances", []) or []
    if not isinstance(instances, list):
        raise SceneError(f"{path}: 'object_instances' must be a list")
    for k, inst in enumerate(instances):
        if not isinstance(inst, dict) or not isinstance(inst.get("template_name"), str):
            raise SceneError(f"{path}: object instance {k} has no 'template_name'")
        if inst.get("is_instance_visible") is False:
            continue  # habitat-sim draws nothing for it
        cfg_path = _template(root, inst["template_name"], ".object_config.json", path)
        cfg = _read(cfg_path, "object config")
        mesh, uv, ft, tex = _load_part(cfg_path, cfg)
        scale = _vec(cfg.get("scale", [1, 1, 1]), 3, "scale", cfg_path)
        origin = str(inst.get("translation_origin", "") or scene_origin).lower()
        com = None
        if origin != "asset_local":  # COM space: the centre of mass goes to `translation`
            com = (_vec(cfg["COM"], 3, "COM", cfg_path) if "COM" in cfg
                   else (mesh.vertices.min(axis=0) + mesh.vertices.max(axis=0)) / 2.0)
        _place(mesh, inst, scale, com, path)
        sid = cfg.get("semantic_id", 0)
        if isinstance(sid, int) and not isinstance(sid, bool) and sid > 0:
            records[k] = lexicon.get(sid, f"semantic_{sid}")
            parts.append((mesh, uv, ft, tex, k))
        else:
            parts.append((mesh, uv, ft, tex, -1))
    return _compose(path, parts, records)


def _place(mesh: trimesh.Trimesh, inst: dict, scale: np.ndarray, com: np.ndarray | None, where: Path) -> None:
    s = scale * float(inst.get("uniform_scale", 1.0))
    if "non_uniform_scale" in inst:
        s = s * _vec(inst["non_uniform_scale"], 3, "non_uniform_scale", where)
    rot = _rotation_wxyz(inst.get("rotation", [1, 0, 0, 0]), where)
    t = _vec(inst.get("translation", [0, 0, 0]), 3, "translation", where)
    v = np.asarray(mesh.vertices, dtype=np.float64)
    if com is not None:
        v = v - com
    mesh.vertices = (v * s) @ rot.T + t


def _compose(path: Path, parts, records) -> SceneAsset:
    meshes = [p[0] for p in parts]
    mesh = trimesh.util.concatenate(meshes) if len(meshes) > 1 else meshes[0]
    face_ids = np.concatenate([np.full(len(p[0].faces), p[4], np.int32) for p in parts])
    textures: list[np.ndarray] = []
    uv_all, ft_all = [], []
    for m, uv, ft, tex, _ in parts:
        uv_all.append(uv if uv is not None else np.zeros((len(m.vertices), 2), np.float32))
        if ft is None:
            ft_all.append(np.full(len(m.faces), -1, np.int32))
        else:
            ft_all.append(np.where(ft >= 0, ft + len(textures), -1).astype(np.int32))
        textures += list(tex)
    objects = {}
    for k, category in records.items():
        pts = mesh.vertices[np.unique(mesh.faces[face_ids == k])]
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        objects[k] = ObjectAnnotation(k, category, "", "", (128, 128, 128), tuple(float(v) for v in lo),
                                      tuple(float(v) for v in hi))
    scene_id = path.name[: -len(SUFFIX)]
    stage = parts[0][0].vertices
    rooms = [RoomAnnotation("stage", tuple(float(v) for v in stage.min(axis=0)),
                            tuple(float(v) for v in stage.max(axis=0)))]
    if textures:
        return SceneAsset(scene_id, path, mesh, face_ids, objects, rooms, np.concatenate(uv_all),
                          np.concatenate(ft_all), textures)
    return SceneAsset(scene_id, path, mesh, face_ids, objects, rooms)
