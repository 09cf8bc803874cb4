"""HM3D-Semantics v0.2 annotations: ``{name}.semantic.txt`` + ``{name}.semantic.glb``.

``semantic.txt`` is a header line ``HM3D Semantic Annotations`` followed by one CSV line per object,
``object_id,HEX,"raw name",region_id`` (e.g. ``12,9D2A2B,"kitchen cabinet",3``): HEX is the object's
colour in the semantic mesh. The semantic mesh paints each object in its colour, as vertex colours
or (``has_semantic_textures``, the v0.2 release) as a texture; a face takes the colour at its
centroid. Faces are matched to the render mesh by centroid (:func:`transfer_face_labels`).
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import trimesh

from navbench.safeio import read_input
from navbench.scene.annotations import objects_from_faces, rooms_from_faces, transfer_face_labels
from navbench.scene.datasets.label_map import map_category
from navbench.scene.errors import SceneError
from navbench.scene.mesh_io import read_mesh

HEADER = "HM3D Semantic Annotations"


def read_semantic_txt(path: Path) -> list[tuple[int, int, str, int]]:
    """[(object_id, colour as 0xRRGGBB, raw name, region_id)], in file order."""
    try:
        lines = read_input(path, gunzip=False).decode().splitlines()
    except (OSError, ValueError) as exc:  # UTF-8 and size errors are ValueErrors
        raise SceneError(f"{path}: cannot read ({exc})") from None
    if not lines or lines[0].strip() != HEADER:
        raise SceneError(f"{path}: not an HM3D semantic.txt (first line must be {HEADER!r})")
    out = []
    for n, row in enumerate(csv.reader(lines[1:]), start=2):
        if not row or not "".join(row).strip():
            continue
        try:
            oid, hexcol, name, region = row
            out.append((int(oid), int(hexcol, 16), name.strip(), int(region)))
        except ValueError:
            raise SceneError(f"{path}:{n}: expected 'id,HEX,\"name\",region', got {','.join(row)!r}") from None
    return out


def face_colours(mesh: trimesh.Trimesh, uv: np.ndarray | None, face_texture: np.ndarray | None,
                 textures: list[np.ndarray]) -> np.ndarray:
    """(F,) int 0xRRGGBB colour of each face: the texel at its centroid's UV when textured, else the
    colour of its first vertex (HM3D paints whole objects, so every corner carries the same one)."""
    faces = np.asarray(mesh.faces)
    vc = np.asarray(mesh.visual.vertex_colors, np.int64)[faces[:, 0], :3]
    out = (vc[:, 0] << 16) | (vc[:, 1] << 8) | vc[:, 2]
    if face_texture is None:
        return out
    for t, img in enumerate(textures):
        sel = np.flatnonzero(face_texture == t)
        if len(sel) == 0:
            continue
        c = uv[faces[sel]].mean(axis=1)
        h, w = img.shape[:2]
        col = np.clip((c[:, 0] % 1.0) * w, 0, w - 1).astype(np.int64)
        row = np.clip((1.0 - c[:, 1] % 1.0) * h, 0, h - 1).astype(np.int64)
        px = img[row, col, :3].astype(np.int64)
        out[sel] = (px[:, 0] << 16) | (px[:, 1] << 8) | px[:, 2]
    return out


def face_labels(records: list[tuple[int, int, str, int]], txt: Path, sem_mesh_path: Path, mesh: trimesh.Trimesh,
                frame: np.ndarray | None) -> np.ndarray:
    """(F,) int32: the instance id of each face of the render ``mesh`` (every id of ``records``, the rows of
    ``txt``), from the colours of the semantic mesh; -1 where the colour is not listed."""
    if not sem_mesh_path.is_file():
        raise SceneError(f"{txt}: its semantic mesh is missing: {sem_mesh_path}")
    sem, _, uv, face_tex, textures = read_mesh(sem_mesh_path)
    if frame is not None:
        sem.vertices = sem.vertices @ frame.T
    colour_to_id = {colour: oid for oid, colour, _, _ in records}
    cols = face_colours(sem, uv, face_tex, textures)
    keys = np.array(sorted(colour_to_id), dtype=np.int64)
    vals = np.array([colour_to_id[k] for k in keys], dtype=np.int64)
    sem_ids = np.full(len(cols), -1, np.int64)
    if len(keys):
        pos = np.clip(np.searchsorted(keys, cols), 0, len(keys) - 1)
        sem_ids = np.where(keys[pos] == cols, vals[pos], -1)
    return transfer_face_labels(sem, np.asarray(sem_ids, np.int64), mesh)


def load(txt: Path, sem_mesh_path: Path, mesh: trimesh.Trimesh, frame: np.ndarray | None):
    """(face_ids, objects, rooms) for the render ``mesh`` from an HM3D semantic.txt/semantic.glb pair."""
    records = read_semantic_txt(txt)
    info = {}
    region_of = {}
    for oid, colour, name, region in records:
        region_of[oid] = region
        cat = map_category(name)
        if cat is not None:
            info[oid] = {"category": cat, "room": f"region_{region}",
                         "rgb": ((colour >> 16) & 255, (colour >> 8) & 255, colour & 255), "raw": name}
    labels = face_labels(records, txt, sem_mesh_path, mesh, frame)
    rmax = max(region_of.values(), default=-1)
    rlut = np.full(max(max(region_of, default=0), 0) + 2, -1, np.int64)
    for oid, r in region_of.items():
        if oid >= 0:
            rlut[oid + 1] = r
    face_rooms = rlut[np.clip(labels, -1, len(rlut) - 2) + 1]
    # Structure (walls, floors, ceilings) and colours absent from semantic.txt are instance id -1.
    face_ids = np.where(np.isin(labels, np.fromiter(info, np.int64, len(info))), labels, -1).astype(np.int32)
    objects = objects_from_faces(mesh, face_ids, info)
    rooms = rooms_from_faces(mesh, face_rooms, {r: f"region_{r}" for r in range(rmax + 1)})
    return face_ids, objects, rooms
