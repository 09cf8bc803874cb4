"""``habitat_sim.geo``: habitat-sim's frame constants (y up, -z forward, x right) and its oriented box ``OBB``."""

from __future__ import annotations

import numpy as np

from navbench.habitat_sim import magnum as mn

UP = np.array([0.0, 1.0, 0.0])
GRAVITY = np.array([0.0, -1.0, 0.0])
FRONT = np.array([0.0, 0.0, -1.0])
BACK = np.array([0.0, 0.0, 1.0])
LEFT = np.array([-1.0, 0.0, 0.0])
RIGHT = np.array([1.0, 0.0, 0.0])

# habitat-sim's src/esp/geo/OBB.cpp: a box of ``dimensions`` about ``center``, turned by ``rotation``
_CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float64)


class OBB:
    """An oriented box: ``OBB(center, dimensions, rotation)`` (a magnum Quaternion) or ``OBB(range3d)``;
    ``rotation`` reads as ``[x, y, z, w]``, as habitat-sim's binding returns it."""

    def __init__(self, center, dimensions=None, rotation=None) -> None:
        if dimensions is None:  # OBB(Range3D): the box itself, unrotated
            box = center
            center, dimensions, rotation = box.center(), box.size(), mn.Quaternion()
        self._center = np.asarray(center, np.float64).reshape(3)
        self._half = np.asarray(dimensions, np.float64).reshape(3) / 2.0
        self._rotation = mn.Quaternion() if rotation is None else rotation
        self._r = np.asarray(self._rotation.to_matrix(), np.float64)

    @property
    def center(self) -> mn.Vector3:
        return mn.Vector3(self._center)

    @property
    def sizes(self) -> mn.Vector3:
        return mn.Vector3(2.0 * self._half)

    @property
    def half_extents(self) -> mn.Vector3:
        return mn.Vector3(self._half)

    @property
    def volume(self) -> float:
        return float(np.prod(2.0 * self._half))

    @property
    def rotation(self) -> mn.Vector4:
        return mn.Vector4(*np.asarray(self._rotation.vector, np.float64), self._rotation.scalar)

    @property
    def local_to_world(self) -> mn.Matrix4:
        """Box coordinates ([-1, 1] on each axis inside) to world coordinates."""
        return mn.Matrix4.from_(self._r * self._half, self._center)

    @property
    def world_to_local(self) -> mn.Matrix4:
        with np.errstate(divide="ignore", invalid="ignore"):  # a flat box: inf, as habitat-sim's float division
            inv = (self._r / self._half).T
            return mn.Matrix4.from_(inv, -inv @ self._center)

    def to_aabb(self) -> mn.Range3D:
        """The axis-aligned box bounding this one."""
        corners = self._center + (_CORNERS * self._half) @ self._r.T
        return mn.Range3D(corners.min(axis=0), corners.max(axis=0))

    def contains(self, p, epsilon: float = 1e-6) -> bool:
        with np.errstate(divide="ignore", invalid="ignore"):
            local = (np.asarray(p, np.float64) - self._center) @ self._r / self._half
        return not bool(np.any(np.abs(local) > 1.0 + epsilon))  # habitat-sim's test (NaN counts as inside)

    def closest_point(self, p) -> mn.Vector3:
        d = (np.asarray(p, np.float64) - self._center) @ self._r
        return mn.Vector3(self._center + self._r @ np.clip(d, -self._half, self._half))

    def distance(self, p) -> float:
        if self.contains(p):
            return 0.0
        return float(np.linalg.norm(np.asarray(p, np.float64) - np.asarray(self.closest_point(p), np.float64)))

    def rotate(self, rotation: mn.Quaternion) -> OBB:
        self._rotation = rotation * self._rotation
        self._r = np.asarray(self._rotation.to_matrix(), np.float64)
        return self

    def __repr__(self) -> str:
        return f"OBB(center={self._center.tolist()}, sizes={(2 * self._half).tolist()}, rotation={self.rotation!r})"
