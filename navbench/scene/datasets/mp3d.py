"""Matterport3D annotations as Habitat ships them: ``{scan}_semantic.ply`` + ``{scan}.house``.

The PLY stores an ``object_id`` per face (an index into the ``.house`` file's ``O`` records). Records
of the ``.house`` file (ASCII, whitespace-separated, first token the record type) read here:

* ``C category_index category_mapping_index category_mapping_name mpcat40_index mpcat40_name ...``
  (names with ``#`` for spaces);
* ``O object_index region_index category_index px py pz ...`` (centre, then the oriented box);
* ``R region_index level_index 0 0 label px py pz xlo ylo zlo xhi yhi zhi height ...`` with a
  one-letter room label (:data:`REGION_LABELS`).

Other records (``H``, ``L``, ``P``, ``S``, ``V``, ``I``, ``E``) are skipped. An object's category is its
mpcat40 name when that maps to a navbench category, else its raw mapping name.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from navbench.safeio import read_input
from navbench.scene.annotations import objects_from_faces, rooms_from_faces, transfer_face_labels
from navbench.scene.datasets.label_map import RAW_TO_CATEGORY, map_category, normalise
from navbench.scene.errors import SceneError

REGION_LABELS = {
    "a": "bathroom", "b": "bedroom", "c": "closet", "d": "dining_room", "e": "entryway", "f": "family_room",
    "g": "garage", "h": "hallway", "i": "library", "j": "laundry", "k": "kitchen", "l": "living_room",
    "m": "meeting_room", "n": "lounge", "o": "office", "p": "porch", "r": "rec_room", "s": "stairs",
    "t": "toilet", "u": "utility_room", "v": "tv_room", "w": "gym", "x": "outdoor", "y": "balcony",
    "z": "other_room", "B": "bar", "C": "classroom", "D": "dining_booth", "S": "spa", "Z": "junk", "-": "unlabeled",
}


def house_lines(path: Path, version: str = "") -> list[str]:
    """The lines of a Matterport ``.house`` file, read within the input bounds; its first line must start with
    ``ASCII`` (``ASCII {version}`` where a version is asked for)."""
    try:
        lines = read_input(path, gunzip=False).decode().splitlines()
    except (OSError, ValueError) as exc:  # UTF-8 and size errors are ValueErrors
        raise SceneError(f"{path}: cannot read ({exc})") from None
    header = f"ASCII {version}" if version else "ASCII"
    if not lines or not (lines[0].strip() == header if version else lines[0].startswith(header)):
        raise SceneError(f"{path}: not a Matterport .house file (first line must "
                         f"{'be' if version else 'start with'} '{header}')")
    return lines


def read_house(path: Path) -> tuple[dict[int, tuple[str, str]], dict[int, tuple[int, int]], dict[int, str]]:
    """(categories {index: (raw name, mpcat40 name)}, objects {index: (region, category)}, regions {index: label})."""
    cats: dict[int, tuple[str, str]] = {}
    objs: dict[int, tuple[int, int]] = {}
    regions: dict[int, str] = {}
    lines = house_lines(path)
    for n, line in enumerate(lines[1:], start=2):
        t = line.split()
        if not t:
            continue
        try:
            if t[0] == "C":
                cats[int(t[1])] = (t[3].replace("#", " "), t[5].replace("#", " "))
            elif t[0] == "O":
                objs[int(t[1])] = (int(t[2]), int(t[3]))
            elif t[0] == "R":
                regions[int(t[1])] = REGION_LABELS.get(t[5], "other_room")
        except (IndexError, ValueError):
            raise SceneError(f"{path}:{n}: malformed {t[0]} record: {line.strip()!r}") from None
    return cats, objs, regions


def read_face_objects(path: Path) -> tuple[trimesh.Trimesh, np.ndarray]:
    """The semantic PLY's mesh and its per-face ``object_id``."""
    try:
        mesh = trimesh.load(str(path), process=False, force="mesh")
        raw = mesh.metadata["_ply_raw"]["face"]["data"]
        ids = np.asarray(raw["object_id"]).reshape(-1).astype(np.int64)
    except (KeyError, ValueError, TypeError, IndexError):
        raise SceneError(f"{path}: semantic PLY has no per-face 'object_id' property") from None
    except Exception as exc:  # trimesh raises many types for a bad file
        raise SceneError(f"{path}: cannot read mesh ({type(exc).__name__}: {exc})") from None
    if len(ids) != len(mesh.faces):
        raise SceneError(f"{path}: {len(ids)} object ids for {len(mesh.faces)} faces")
    return mesh, ids


def _category(raw: str, mpcat40: str) -> str | None:
    """mpcat40 when it names a navbench category, else the raw name's mapping (None: structure)."""
    if normalise(mpcat40) in RAW_TO_CATEGORY:
        return map_category(mpcat40)
    if map_category(mpcat40) is None and normalise(mpcat40) not in ("misc", "objects", "void", "unlabeled", ""):
        return None
    return map_category(raw)


def face_labels(ply: Path, mesh: trimesh.Trimesh, frame: np.ndarray | None) -> np.ndarray:
    """(F,) int32: the ``.house`` object index of each face of the render ``mesh``, from the semantic PLY."""
    sem, face_obj = read_face_objects(ply)
    if frame is not None:
        sem.vertices = np.asarray(sem.vertices) @ frame.T
    return transfer_face_labels(sem, face_obj, mesh)


def load(house: Path, ply: Path, mesh: trimesh.Trimesh, frame: np.ndarray | None):
    """(face_ids, objects, rooms) for the render ``mesh`` from an MP3D ``.house`` + ``_semantic.ply`` pair."""
    if not house.is_file():
        raise SceneError(f"{ply}: its annotation file is missing: {house}")
    if not ply.is_file():
        raise SceneError(f"{house}: its semantic mesh is missing: {ply}")
    cats, objs, regions = read_house(house)
    labels = face_labels(ply, mesh, frame)
    counts: dict[str, int] = {}
    names: dict[int, str] = {}
    for r, label in sorted(regions.items()):
        counts[label] = counts.get(label, 0) + 1
        names[r] = label if counts[label] == 1 else f"{label}_{counts[label]}"
    info = {}
    for oid, (region, cat) in objs.items():
        raw, mpcat = cats.get(cat, ("", ""))
        mapped = _category(raw, mpcat)
        if mapped is not None:
            info[oid] = {"category": mapped, "room": names.get(region, ""), "raw": raw}
    face_ids = np.where(np.isin(labels, np.fromiter(info, np.int64, len(info))), labels, -1).astype(np.int32)
    region_lut = {oid: r for oid, (r, _) in objs.items()}
    face_rooms = _lookup(labels, region_lut)
    return face_ids, objects_from_faces(mesh, face_ids, info), rooms_from_faces(mesh, face_rooms, names)


def _lookup(labels: np.ndarray, table: dict[int, int]) -> np.ndarray:
    if not table:
        return np.full(len(labels), -1, np.int64)
    lut = np.full(max(max(table), 0) + 2, -1, np.int64)
    for k, v in table.items():
        if k >= 0:
            lut[k + 1] = v
    return lut[np.clip(labels, -1, len(lut) - 2) + 1]
