"""Which chunks of a scene a frame draws: the view-frustum test, and occlusion culling for scans.

Frustum culling hides chunks whose bounding box lies entirely outside the view frustum
(conservative test against the six frustum planes). Scenes of :data:`OCCLUSION_MIN_FACES` or more
triangles are cut into chunks of at most :data:`OCCLUSION_CHUNK_FACES` and also skip chunks that
rays cast from the camera's cell never reach (:class:`PotentiallyVisible`).
"""

from __future__ import annotations

import numpy as np
import trimesh

OCCLUSION_MIN_FACES = 200_000  # scenes this large get occlusion culling by default
OCCLUSION_CHUNK_FACES = 8_000  # finer chunks, so walls hide whole chunks
PVS_CELL = 0.5  # metres: camera positions are grouped into cubes of this side
PVS_DIRECTIONS = 16384  # rays per sample point (about 1.6 deg apart)


class PotentiallyVisible:
    """Chunks visible from a camera cell, found by casting rays from the cell's corners.

    The camera's position is put in a cube of side :data:`PVS_CELL`; the first time a cube is
    entered, the chunks seen from each of its 8 corners are the union of the chunks first hit by
    rays in :data:`PVS_DIRECTIONS` directions (Embree) and the chunks whose box holds the corner.
    Corners are shared by neighbouring cubes and computed once. Chunks behind walls are then
    skipped. Sampling, not an exact visibility proof: a chunk seen only through a gap narrower than
    the rays' spacing may be missed, which is why only scan-sized scenes (chunks of thousands of
    triangles, which rays hit many times) use it by default.
    """

    def __init__(self, mesh: trimesh.Trimesh, chunks: list[np.ndarray]) -> None:
        self._mesh = mesh
        self._face_chunk = np.empty(len(mesh.faces), np.int64)
        for k, faces in enumerate(chunks):
            self._face_chunk[faces] = k
        self._n = len(chunks)
        tri = mesh.triangles
        self._lo = np.array([tri[c].reshape(-1, 3).min(axis=0) for c in chunks])
        self._hi = np.array([tri[c].reshape(-1, 3).max(axis=0) for c in chunks])
        i = np.arange(PVS_DIRECTIONS) + 0.5  # Fibonacci sphere: near-uniform directions
        phi = np.arccos(1 - 2 * i / PVS_DIRECTIONS)
        theta = np.pi * (1 + 5 ** 0.5) * i
        self._dirs = np.stack([np.cos(theta) * np.sin(phi), np.cos(phi), np.sin(theta) * np.sin(phi)], axis=1)
        self._cells: dict[tuple[int, int, int], np.ndarray] = {}
        self._corners: dict[tuple[int, int, int], np.ndarray] = {}

    def __call__(self, position: np.ndarray) -> np.ndarray:
        cell = tuple(int(v) for v in np.floor(np.asarray(position) / PVS_CELL))
        vis = self._cells.get(cell)
        if vis is None:
            corners = [(cell[0] + x, cell[1] + y, cell[2] + z) for x in (0, 1) for y in (0, 1) for z in (0, 1)]
            self._add_corners([c for c in corners if c not in self._corners])
            vis = self._cells[cell] = np.logical_or.reduce([self._corners[c] for c in corners])
        return vis

    def _add_corners(self, corners: list[tuple[int, int, int]]) -> None:
        if not corners:
            return
        points = np.asarray(corners, float) * PVS_CELL
        hit = self._mesh.ray.intersects_first(np.repeat(points, len(self._dirs), axis=0),
                                              np.tile(self._dirs, (len(points), 1)))
        hit = hit.reshape(len(points), -1)
        for k, c in enumerate(corners):
            vis = np.all((points[k] >= self._lo - 1e-6) & (points[k] <= self._hi + 1e-6), axis=1)
            h = hit[k]
            vis[self._face_chunk[h[h >= 0]]] = True
            self._corners[c] = vis


def frustum_planes(view_proj: np.ndarray) -> np.ndarray:
    """(6, 4) unit-normal planes ``(a, b, c, d)`` of the clip frustum of a GL view-projection matrix.

    A world point is inside iff ``a x + b y + c z + d >= 0`` for all six (Gribb-Hartmann).
    """
    m = np.asarray(view_proj, dtype=np.float64)
    rows = [m[3] + m[0], m[3] - m[0], m[3] + m[1], m[3] - m[1], m[3] + m[2], m[3] - m[2]]
    planes = np.stack(rows)
    return planes / np.linalg.norm(planes[:, :3], axis=1, keepdims=True)


def boxes_in_frustum(
    planes: np.ndarray, box_min: np.ndarray, box_max: np.ndarray, margin: float = 1e-3
) -> np.ndarray:
    """(N,) bool: False only for axis-aligned boxes certainly outside the frustum (conservative).

    A box is outside when its corner furthest along some plane's normal is still behind that plane;
    boxes straddling a frustum edge outside a corner may be kept, never the reverse.
    """
    n = planes[:, :3]  # (6, 3)
    far_corner = np.where(n[None] >= 0.0, box_max[:, None, :], box_min[:, None, :])  # (N, 6, 3)
    dist = np.einsum("npk,pk->np", far_corner, n) + planes[None, :, 3]
    return (dist >= -margin).all(axis=1)

