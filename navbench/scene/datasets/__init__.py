"""Habitat scene datasets on disk: where an episode's ``scene_id`` lives, the dataset config's stage
attributes, and the annotation readers of HM3D (:mod:`.hm3d`) and MP3D (:mod:`.mp3d`).

Layouts read (as downloaded, unchanged)::

    scene_datasets/hm3d/hm3d_annotated_basis.scene_dataset_config.json
    scene_datasets/hm3d/val/00800-TEEsavR23oF/TEEsavR23oF.basis.glb   (+ .glb, .semantic.glb, .semantic.txt)
    scene_datasets/mp3d/mp3d.scene_dataset_config.json
    scene_datasets/mp3d/17DRP5sb8fy/17DRP5sb8fy.glb                    (+ _semantic.ply, .house)

Episode files name scenes relative to ``scene_datasets/`` (``hm3d/val/00800-.../X.basis.glb``),
sometimes with a ``data/scene_datasets/`` prefix; :func:`resolve_scene` accepts either and also a
``--scene-dir`` pointing at the dataset's own folder. A bare handle (``102344049``) names a scene
instance, ``scenes*/{handle}.scene_instance.json`` in a dataset (:mod:`.instances`).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import trimesh

from navbench.safeio import read_input
from navbench.scene.errors import SceneError

CONFIG_SUFFIX = ".scene_dataset_config.json"
_NAME_TEMPLATE = "%%CONFIG_NAME_AS_ASSET_FILENAME%%"
_PREFIXES = ("data/scene_datasets/", "scene_datasets/", "./data/scene_datasets/")


def scene_name(path: Path) -> str:
    """Habitat's config name of a scene asset: the file name before its first dot."""
    return Path(path).name.split(".")[0]


def resolve_scene(scene_id: str, scene_dir: Path) -> Path:
    """The mesh file an episode's ``scene_id`` names under ``scene_dir``; SceneError listing where it looked."""
    p = Path(scene_id)
    if p.is_absolute():
        if p.is_file():
            return p
        tried = [p]
    else:
        scene_dir = Path(scene_dir)
        rel = scene_id
        for prefix in _PREFIXES:
            if rel.startswith(prefix):
                rel = rel[len(prefix):]
                break
        parts = Path(rel).parts
        # scene_dir may be scene_datasets/ itself, its parent (data/) or one dataset's folder (hm3d/).
        bases = [scene_dir / rel, scene_dir / scene_id, scene_dir / "scene_datasets" / rel]
        bases += [scene_dir / Path(*parts[k:]) for k in range(1, len(parts))]
        tried = []
        for base in bases:
            for cand in _variants(base):
                if cand not in tried:
                    tried.append(cand)
        for cand in tried:
            if cand.is_file():
                return cand
        if "/" not in scene_id and "." not in scene_id:  # a scene instance named by its handle (HSSD)
            name = scene_id + ".scene_instance.json"
            for pattern in (f"scenes*/{name}", f"*/scenes*/{name}", f"*/*/scenes*/{name}"):
                found = sorted(scene_dir.glob(pattern))
                if found:
                    return found[0]
            tried.append(scene_dir / "**" / "scenes*" / name)
    more = f" (also looked for: {', '.join(str(t) for t in tried[1:])})" if len(tried) > 1 else ""
    raise SceneError(f"{tried[0]}: scene file not found{more}")


def _variants(path: Path) -> list[Path]:
    """``X.basis.glb`` and ``X.glb`` stand in for each other (HM3D ships both, episodes name one)."""
    name = path.name
    out = [path]
    if name.endswith(".basis.glb"):
        out.append(path.with_name(name[: -len(".basis.glb")] + ".glb"))
    elif name.endswith(".glb"):
        out.append(path.with_name(name[: -len(".glb")] + ".basis.glb"))
    return out


def find_config(mesh_path: Path, levels: int = 4) -> Path | None:
    """The nearest ``*.scene_dataset_config.json`` in the mesh's folder or up to ``levels`` above it
    (annotated configs first, as habitat-lab's HM3D episodes name them)."""
    d = Path(mesh_path).resolve().parent
    for _ in range(levels + 1):
        found = sorted(d.glob("*" + CONFIG_SUFFIX), key=lambda f: ("annotated" not in f.name, f.name))
        if found:
            return found[0]
        if d.parent == d:
            break
        d = d.parent
    return None


def stage_attributes(mesh_path: Path) -> dict:
    """The config's ``stages.default_attributes`` for this mesh, templates filled in; {} without a config."""
    cfg = find_config(mesh_path)
    if cfg is None:
        return {}
    try:
        data = json.loads(read_input(cfg, gunzip=False))
        attrs = dict(data.get("stages", {}).get("default_attributes", {}) or {})
    except (OSError, ValueError, AttributeError) as exc:  # JSON, UTF-8 and size errors are ValueErrors
        raise SceneError(f"{cfg}: corrupt scene dataset config ({type(exc).__name__}: {exc})") from None
    name = scene_name(mesh_path)
    out = {}
    for k, v in attrs.items():
        out[k] = v.replace(_NAME_TEMPLATE, name) if isinstance(v, str) else v
    out["__config__"] = str(cfg)
    return out


def frame_rotation(stage: dict) -> np.ndarray | None:
    """3x3 rotation from the asset frame declared by ``up``/``front`` to Habitat's (y up, -z front)."""
    if "up" not in stage and "front" not in stage:
        return None
    up = np.asarray(stage.get("up", [0, 1, 0]), float)
    front = np.asarray(stage.get("front", [0, 0, -1]), float)
    if up.shape != (3,) or front.shape != (3,) or abs(float(up @ front)) > 1e-6 or not (up.any() and front.any()):
        raise SceneError(f"{stage.get('__config__', 'scene dataset config')}: 'up' {up.tolist()} and "
                         f"'front' {front.tolist()} must be orthogonal 3-vectors")
    up, front = up / np.linalg.norm(up), front / np.linalg.norm(front)
    rot = np.stack([np.cross(front, up), up, -front])
    return None if np.allclose(rot, np.eye(3)) else rot


def _asset(mesh_path: Path, stage: dict, key: str, default: str) -> Path:
    value = stage.get(key) or default
    p = Path(value)
    return p if p.is_absolute() else Path(mesh_path).parent / p


def annotation_files(mesh_path: Path, stage: dict) -> tuple[str, Path, Path, np.ndarray | None] | None:
    """(``"hm3d"`` or ``"mp3d"``, descriptor file, semantic mesh, the semantic mesh's frame rotation) of the
    dataset's annotation files beside the mesh, or None if it has none."""
    name = scene_name(mesh_path)
    txt = _asset(mesh_path, stage, "semantic_descriptor_filename", f"{name}.semantic.txt")
    if txt.suffix == ".txt" and txt.is_file():
        sem_mesh = _asset(mesh_path, stage, "semantic_asset", f"{name}.semantic.glb")
        return "hm3d", txt, sem_mesh, frame_rotation(_semantic_frame(stage))
    house = Path(mesh_path).parent / f"{name}.house"
    ply = _asset(mesh_path, stage, "semantic_asset", f"{name}_semantic.ply")
    if house.is_file() or ply.suffix == ".ply" and ply.is_file():
        return "mp3d", house, ply, frame_rotation(_semantic_frame(stage))
    return None


def load_annotations(mesh_path: Path, mesh: trimesh.Trimesh, stage: dict):
    """(face_ids, objects, rooms) from the dataset's annotation files beside the mesh, or None if it has none."""
    from navbench.scene.datasets import hm3d, mp3d

    found = annotation_files(mesh_path, stage)
    if found is None:
        return None
    kind, descriptor, sem_mesh, frame = found
    return (hm3d if kind == "hm3d" else mp3d).load(descriptor, sem_mesh, mesh, frame)


def _semantic_frame(stage: dict) -> dict:
    """The semantic asset's own frame where the config gives one, else the render asset's."""
    out = {k: v for k, v in stage.items() if k in ("up", "front", "__config__")}
    if "semantic_up" in stage:
        out["up"] = stage["semantic_up"]
    if "semantic_front" in stage:
        out["front"] = stage["semantic_front"]
    return out
