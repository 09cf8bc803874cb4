"""The camera of the renderer (pinhole, or orthographic with ``ortho_scale``): its configuration, intrinsics,
poses and the inverse projection.

Conventions (Habitat): metres, y up, a camera with identity rotation looks along -z with +y up (also
OpenGL's camera frame); quaternions are ``[x, y, z, w]``. Images have row 0 at the top. Depth is
linear z-depth along the optical axis (not ray length).

Pixel convention of :func:`intrinsics`: pixel ``(u, v)`` (column, row) has its centre at integer
coordinates, so the image spans ``[-0.5, W - 0.5]`` and the principal point of the symmetric GL
frustum is ``((W - 1) / 2, (H - 1) / 2)``. :func:`unproject` and :func:`backproject_image` use the
same convention.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


class RenderError(ValueError):
    """Bad renderer input (camera config, pose, platform, scene ids); the message names the value."""


@dataclass(frozen=True)
class CameraConfig:
    """Pinhole camera: image size in pixels, horizontal field of view, clip planes in metres.

    With ``ortho_scale`` set the projection is orthographic instead, as habitat-sim's ORTHOGRAPHIC camera
    (``projectionMatrixInternal`` in habitat-sim's ``src/esp/sensor/CameraSensor.cpp``): the image spans
    ``1 / ortho_scale`` metres across and ``height / width / ortho_scale`` metres down, and ``hfov_deg`` is not
    used. Depth stays z-depth in metres.
    """

    width: int = 224
    height: int = 224
    hfov_deg: float = 79.0
    znear: float = 0.05
    zfar: float = 50.0
    ortho_scale: float | None = None

    def __post_init__(self) -> None:
        if self.width <= 0 or self.height <= 0:
            raise RenderError(f"camera size must be positive, got {self.width}x{self.height}")
        if not 0.0 < self.hfov_deg < 180.0:
            raise RenderError(f"camera hfov_deg must be in (0, 180), got {self.hfov_deg}")
        if not 0.0 < self.znear < self.zfar:
            raise RenderError(f"camera needs 0 < znear < zfar, got znear={self.znear} zfar={self.zfar}")
        if self.ortho_scale is not None and not 0.0 < self.ortho_scale < math.inf:
            raise RenderError(f"camera ortho_scale must be positive, got {self.ortho_scale}")

    @property
    def orthographic(self) -> bool:
        return self.ortho_scale is not None

    @property
    def ortho_extent(self) -> tuple[float, float]:
        """(width, height) in metres of an orthographic camera's view."""
        if self.ortho_scale is None:
            raise RenderError("ortho_extent: the camera is a pinhole camera")
        return 1.0 / self.ortho_scale, self.height / self.width / self.ortho_scale

    @property
    def yfov(self) -> float:
        """Vertical field of view in radians (square pixels)."""
        return 2.0 * float(np.arctan(np.tan(np.radians(self.hfov_deg) / 2.0) * self.height / self.width))


def intrinsics(cfg: CameraConfig) -> np.ndarray:
    """3x3 pinhole matrix K for ``cfg`` (OpenCV axes: x right, y down, z forward).

    ``fx = (W / 2) / tan(hfov / 2)``, ``fy = fx`` (square pixels), principal point
    ``((W - 1) / 2, (H - 1) / 2)``: pixel centres sit at integer coordinates (module docstring).
    """
    if cfg.orthographic:
        raise RenderError("intrinsics: an orthographic camera has no pinhole matrix")
    fx = (cfg.width / 2.0) / np.tan(np.radians(cfg.hfov_deg) / 2.0)
    cx, cy = (cfg.width - 1) / 2.0, (cfg.height - 1) / 2.0
    return np.array([[fx, 0.0, cx], [0.0, fx, cy], [0.0, 0.0, 1.0]], dtype=np.float64)


def camera_pose(position: np.ndarray, rotation_xyzw: np.ndarray) -> np.ndarray:
    """4x4 camera-to-world transform from a position ``[x, y, z]`` and a quaternion ``[x, y, z, w]``."""
    p = np.asarray(position, dtype=np.float64)
    q = np.asarray(rotation_xyzw, dtype=np.float64)
    if p.shape != (3,) or not np.isfinite(p).all():
        raise RenderError(f"camera position must be 3 finite numbers, got {np.asarray(position).tolist()}")
    if q.shape != (4,) or not np.isfinite(q).all() or np.linalg.norm(q) < 1e-8:
        raise RenderError(f"camera rotation must be a non-zero [x, y, z, w] quaternion, got {q.tolist()}")
    pose = np.eye(4)
    pose[:3, :3] = _quat_matrix(q)  # normalises q; scalar-last like Habitat
    pose[:3, 3] = p
    return pose


def _quat_matrix(q: np.ndarray) -> np.ndarray:
    """``Rotation.from_quat(q).as_matrix()`` in plain float arithmetic, the same operations in the
    same order (equal to scipy's bit for bit; tests/render checks), at a fifth of its per-call cost."""
    x, y, z, w = (float(v) for v in q)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    x2, y2, z2, w2 = x * x, y * y, z * z, w * w
    xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
    return np.array([[x2 - y2 - z2 + w2, 2 * (xy - zw), 2 * (xz + yw)],
                     [2 * (xy + zw), -x2 + y2 - z2 + w2, 2 * (yz - xw)],
                     [2 * (xz - yw), 2 * (yz + xw), -x2 - y2 + z2 + w2]])


def unproject(u: np.ndarray, v: np.ndarray, depth: np.ndarray, K: np.ndarray, cam_to_world: np.ndarray) -> np.ndarray:
    """World points (N, 3) float64 of image points at continuous pixel coordinates ``(u, v)`` (column,
    row) with z-depth ``depth``, seen by a camera with pinhole matrix ``K`` and pose ``cam_to_world``."""
    z = np.asarray(depth, dtype=np.float64)
    K = np.asarray(K, dtype=np.float64)
    # OpenCV ray (x right, y down, z forward) -> GL/Habitat camera frame (x right, y up, -z forward).
    x = (u - K[0, 2]) * z / K[0, 0]
    y = -(v - K[1, 2]) * z / K[1, 1]
    cam = np.stack([x, y, -z], axis=1)
    T = np.asarray(cam_to_world, dtype=np.float64)
    return cam @ T[:3, :3].T + T[:3, 3]


def backproject_image(
    depth: np.ndarray, cfg: CameraConfig, position: np.ndarray, rotation_xyzw: np.ndarray
) -> np.ndarray:
    """World points (H, W, 3) float32, one per pixel of a depth image rendered from this camera; NaN where
    depth is 0. (:func:`navbench.localize.geometry.backproject` gives the (N, 3) points of masked pixels.)"""
    depth = np.asarray(depth, dtype=np.float32)
    if depth.shape != (cfg.height, cfg.width):
        raise RenderError(f"depth shape {depth.shape} does not match camera {cfg.height}x{cfg.width}")
    v, u = np.mgrid[0 : cfg.height, 0 : cfg.width]
    world = unproject(u.ravel().astype(np.float64), v.ravel().astype(np.float64), depth.ravel(), intrinsics(cfg),
                      camera_pose(position, rotation_xyzw))
    world = world.reshape(cfg.height, cfg.width, 3).astype(np.float32)
    world[depth <= 0] = np.nan
    return world
