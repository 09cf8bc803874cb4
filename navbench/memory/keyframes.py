"""Keyframe selection: which frames of a pre-scan trajectory enter the memory bank.

Frame 0 is always kept; after that a frame becomes a keyframe when the camera has moved at least
``translation`` metres or turned at least ``rotation_deg`` degrees since the *last keyframe* (not the
last frame, so slow drift still triggers eventually). Rotations are quaternions stored [x, y, z, w]
(Habitat's order, also scipy's); the rotation between two poses is the angle of the relative
quaternion, whatever its axis.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from navbench.scene.pose import vector_length

# A pose as the selector sees it: (position [x, y, z], rotation [x, y, z, w]).
Pose = tuple[Sequence[float] | np.ndarray, Sequence[float] | np.ndarray]


class PoseError(ValueError):
    """A pose is malformed (wrong shape, non-finite, zero quaternion); the message names the value."""


def _as_pose(position, rotation) -> tuple[np.ndarray, Rotation]:
    p = np.asarray(position, dtype=np.float64)
    q = np.asarray(rotation, dtype=np.float64)
    if p.shape != (3,) or not np.isfinite(p).all():
        raise PoseError(f"position must be 3 finite numbers, got {position!r}")
    if q.shape != (4,) or not np.isfinite(q).all() or np.linalg.norm(q) < 1e-9:
        raise PoseError(f"rotation must be a non-zero [x, y, z, w] quaternion, got {rotation!r}")
    return p, Rotation.from_quat(q)


def rotation_angle_deg(q_a, q_b) -> float:
    """Angle in degrees of the rotation taking orientation ``q_a`` to ``q_b`` (both [x, y, z, w])."""
    _, r_a = _as_pose((0.0, 0.0, 0.0), q_a)
    _, r_b = _as_pose((0.0, 0.0, 0.0), q_b)
    return float(np.degrees((r_a.inv() * r_b).magnitude()))


@dataclass
class KeyframeSelector:
    """Streaming keyframe test; call :meth:`accept` once per frame in trajectory order.

    ``select`` runs the same test over a whole sequence (and resets first).
    """

    translation: float = 0.25  # metres since the last keyframe
    rotation_deg: float = 15.0  # degrees since the last keyframe
    _last: tuple[np.ndarray, Rotation] | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        if not (self.translation > 0 and self.rotation_deg > 0):
            raise ValueError(
                f"keyframe thresholds must be positive, got translation={self.translation}, "
                f"rotation_deg={self.rotation_deg}"
            )

    def reset(self) -> None:
        self._last = None

    def accept(self, position, rotation) -> bool:
        """True if this frame is a keyframe (and it then becomes the reference for the next test)."""
        p, r = _as_pose(position, rotation)
        if self._last is not None:
            last_p, last_r = self._last
            moved = vector_length(p - last_p)
            turned = float(np.degrees((last_r.inv() * r).magnitude()))
            if moved < self.translation and turned < self.rotation_deg:
                return False
        self._last = (p, r)
        return True

    def select(self, poses: Iterable[Pose]) -> list[int]:
        self.reset()
        return [i for i, (position, rotation) in enumerate(poses) if self.accept(position, rotation)]


def select_keyframes(poses: Iterable[Pose], translation: float = 0.25, rotation_deg: float = 15.0) -> list[int]:
    """Indices of the keyframes in ``poses`` (a sequence of (position, rotation xyzw) pairs)."""
    return KeyframeSelector(translation=translation, rotation_deg=rotation_deg).select(poses)
