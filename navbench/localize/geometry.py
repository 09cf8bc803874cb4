"""Pinhole geometry between keyframe pixels and world points (Habitat camera conventions).

Camera frame: looks along -z, +x right, +y up. Depth is the distance along the optical axis (what a
Habitat depth sensor and our renderer return), so a pixel at continuous image coordinates (u, v) with
depth d is the camera-frame point ((u - cx) d / fx, -(v - cy) d / fy, -d).

Pixel convention (the renderer's :func:`navbench.render.camera.intrinsics`, also
:mod:`navbench.memory.store`'s): pixel (column i, row j) has its centre at the integer coordinates
(i, j), so the image spans [-0.5, W - 0.5] x [-0.5, H - 0.5] and a centred camera has
cx = (W - 1) / 2, cy = (H - 1) / 2. :func:`project` returns continuous coordinates; ``rint`` gives
the pixel index.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navbench.render.camera import unproject

PIXEL_CENTRE = 0.0  # offset from a pixel index to its centre in continuous image coordinates (renderer: 0)


@dataclass(frozen=True)
class GeometryConfig:
    min_depth: float = 0.1  # backprojection keeps depths in [min_depth, max_depth] metres
    max_depth: float = 20.0
    max_median_depth: float = 4.0  # views whose median masked depth is farther are dropped


def _valid(depth: np.ndarray, mask: np.ndarray | None, min_depth: float, max_depth: float) -> np.ndarray:
    depth = np.asarray(depth)
    if depth.ndim != 2:
        raise ValueError(f"depth must be an HxW array, got shape {depth.shape}")
    valid = np.isfinite(depth) & (depth >= min_depth) & (depth <= max_depth)
    if mask is not None:
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != depth.shape:
            raise ValueError(f"mask shape {mask.shape} does not match depth shape {depth.shape}")
        valid &= mask
    return valid


def backproject(depth: np.ndarray, mask: np.ndarray | None, K: np.ndarray, cam_to_world: np.ndarray,
                min_depth: float = 0.1, max_depth: float = 20.0) -> np.ndarray:
    """World points (N, 3) of the masked pixels with a depth in [min_depth, max_depth]; mask None = all.
    (:func:`navbench.render.camera.backproject_image` gives a world point per pixel of a whole image.)"""
    valid = _valid(depth, mask, min_depth, max_depth)
    rows, cols = np.nonzero(valid)
    z = np.asarray(depth, dtype=np.float64)[rows, cols]
    return unproject(cols + PIXEL_CENTRE, rows + PIXEL_CENTRE, z, K, cam_to_world)


def project(points: np.ndarray, K: np.ndarray, world_to_cam: np.ndarray, width: int, height: int
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Project world points: (uv (N, 2) continuous pixel coordinates, z (N,) depth along the optical
    axis, in_view (N,) bool: in front of the camera and inside the image)."""
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    T = np.asarray(world_to_cam, dtype=np.float64)
    cam = P @ T[:3, :3].T + T[:3, 3]
    z = -cam[:, 2]
    K = np.asarray(K, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = K[0, 0] * cam[:, 0] / z + K[0, 2]
        v = -K[1, 1] * cam[:, 1] / z + K[1, 2]
    uv = np.stack([u, v], axis=1)
    lo = PIXEL_CENTRE - 0.5  # left/top edge of the image in continuous coordinates
    in_view = (z > 1e-6) & (u >= lo) & (u < width + lo) & (v >= lo) & (v < height + lo)
    return uv, z, in_view


def world_to_camera(cam_to_world: np.ndarray) -> np.ndarray:
    """Inverse of a rigid camera-to-world transform (cheaper and exacter than a general inverse)."""
    T = np.asarray(cam_to_world, dtype=np.float64)
    inv = np.eye(4)
    inv[:3, :3] = T[:3, :3].T
    inv[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return inv


def median_masked_depth(depth: np.ndarray, mask: np.ndarray | None, min_depth: float = 0.1,
                        max_depth: float = 20.0) -> float:
    """Median depth of the masked pixels with a valid depth; NaN when there are none."""
    valid = _valid(depth, mask, min_depth, max_depth)
    return float(np.median(np.asarray(depth)[valid])) if valid.any() else float("nan")


def keep_view(depth: np.ndarray, mask: np.ndarray | None, config: GeometryConfig = GeometryConfig()) -> bool:
    """View filter: a segmented view is used only if its median masked depth is known and <= the limit
    (far masks backproject to sparse, noisy clouds)."""
    median = median_masked_depth(depth, mask, config.min_depth, config.max_depth)
    return bool(np.isfinite(median) and median <= config.max_median_depth)


def _voxel_keys(points: np.ndarray, voxel_size: float) -> np.ndarray:
    """One int per ``voxel_size`` cube for each of ``points`` (N, 3): a 1-D unique is much faster than a 3-D one."""
    cells = np.floor(points / voxel_size).astype(np.int64)
    cells -= cells.min(axis=0)
    return np.ravel_multi_index(cells.T, cells.max(axis=0) + 1)


def voxel_firsts(points: np.ndarray, voxel_size: float) -> np.ndarray:
    """Indices of one point (the first) per occupied ``voxel_size`` cube of ``points``, in order: for
    downsampling a cloud together with what each point carries (labels, colours)."""
    _, first = np.unique(_voxel_keys(points, voxel_size), return_index=True)
    return np.sort(first)


def voxel_downsample(points: np.ndarray, voxel_size: float) -> np.ndarray:
    """One point per occupied ``voxel_size`` cube (the centroid of the points in it), in first-seen
    order; ``voxel_size <= 0`` returns the points unchanged."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if voxel_size <= 0 or len(points) == 0:
        return points
    _, first, inverse, counts = np.unique(_voxel_keys(points, voxel_size), return_index=True, return_inverse=True,
                                          return_counts=True)
    sums = np.zeros((len(counts), 3))
    np.add.at(sums, inverse, points)
    order = np.argsort(first, kind="stable")
    return (sums / counts[:, None])[order]
