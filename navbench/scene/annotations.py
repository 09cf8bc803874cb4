"""Per-object and per-room annotations of a scene, and building them from per-face labels.

The JSON schema is :mod:`navbench.scene.asset`'s ``.semantic.json`` sidecar. Faces of structure
(walls, floors, ceilings) carry the instance id :data:`STRUCTURE_ID`. Scans label faces instead
(HM3D, MP3D: :mod:`navbench.scene.datasets`); :func:`objects_from_faces` and
:func:`rooms_from_faces` turn such labels into annotations, :func:`transfer_face_labels` carries
labels from an annotation mesh onto the render mesh.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

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
    def from_json(cls, d: dict) -> ObjectAnnotation:
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
    def from_json(cls, d: dict) -> RoomAnnotation:
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



def transfer_face_labels(src_mesh: trimesh.Trimesh, src_labels: np.ndarray, dst_mesh: trimesh.Trimesh) -> np.ndarray:
    """Per-face labels of ``dst_mesh`` from the annotated ``src_mesh``: the same faces when the two
    meshes are one triangulation, else the label of the nearest source face centroid."""
    if len(src_mesh.faces) == len(dst_mesh.faces):
        src_c, dst_c = _centres(src_mesh), _centres(dst_mesh)
        if np.allclose(src_c, dst_c, atol=1e-4):
            return src_labels.astype(np.int32)
    from scipy.spatial import cKDTree

    _, nearest = cKDTree(_centres(src_mesh)).query(_centres(dst_mesh), workers=-1)
    return src_labels[nearest].astype(np.int32)


def _centres(mesh: trimesh.Trimesh) -> np.ndarray:
    """Face centroids without trimesh's cache (which hashes the whole mesh to key them)."""
    v = np.asarray(mesh.vertices)
    f = np.asarray(mesh.faces)
    return (v[f[:, 0]] + v[f[:, 1]] + v[f[:, 2]]) / 3.0


def objects_from_faces(mesh: trimesh.Trimesh, face_ids: np.ndarray, records: dict[int, dict]):
    """ObjectAnnotations (AABB from the object's faces) for the ids that label at least one face."""
    objects = {}
    tri = mesh.triangles
    order = np.argsort(face_ids, kind="stable")
    ids_sorted = face_ids[order]
    uniq, starts = np.unique(ids_sorted, return_index=True)
    ends = np.append(starts[1:], len(ids_sorted))
    for oid, a, b in zip(uniq, starts, ends):
        if oid < 0 or int(oid) not in records:
            continue
        pts = tri[order[a:b]].reshape(-1, 3)
        rec = records[int(oid)]
        objects[int(oid)] = ObjectAnnotation(
            id=int(oid), category=rec["category"], room=rec.get("room", ""), colour="",
            colour_rgb=tuple(rec.get("rgb", (128, 128, 128))),
            aabb_min=tuple(float(v) for v in pts.min(axis=0)), aabb_max=tuple(float(v) for v in pts.max(axis=0)))
    return objects


def rooms_from_faces(mesh: trimesh.Trimesh, face_rooms: np.ndarray, names: dict[int, str]):
    """RoomAnnotations: the AABB of each region's faces."""
    rooms = []
    tri_c = mesh.triangles_center
    for rid in np.unique(face_rooms):
        if rid < 0 or int(rid) not in names:
            continue
        pts = tri_c[face_rooms == rid]
        rooms.append(RoomAnnotation(names[int(rid)], tuple(float(v) for v in pts.min(axis=0)),
                                    tuple(float(v) for v in pts.max(axis=0))))
    return rooms
