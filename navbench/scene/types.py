"""The loaded scene every consumer reads: merged mesh, per-face instance ids, semantics and textures."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import trimesh

from navbench.scene.annotations import ObjectAnnotation, RoomAnnotation


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
