"""Yaw/quaternion helpers in Habitat's convention, shared by the env, the agents and the localiser.

Conventions: y up, quaternions stored ``[x, y, z, w]``, and at identity rotation the agent faces -z.
Yaw is the rotation about +y, counter-clockwise seen from above: a yaw of +30 deg (one TURN_LEFT)
turns the forward vector from -z towards -x, so ``heading_vector(yaw) = (-sin yaw, 0, -cos yaw)``.
"""

from __future__ import annotations

import math

import numpy as np


def _finite(values: np.ndarray, name: str) -> np.ndarray:
    if not np.isfinite(values).all():
        raise ValueError(f"{name} has non-finite values: {values.tolist()}")
    return values


def sum_squares(v) -> float:
    """Sum of the squares of a short vector's entries, left to right in Python floats: the same bits on every
    CPU (numpy's 1-D ``norm`` and ``@`` go through BLAS, whose kernels fuse multiply-adds on some CPUs only)."""
    total = 0.0
    for c in v:
        total += float(c) * float(c)
    return total


def vector_length(v) -> float:
    """Euclidean length of a short vector with the same bits on every CPU (see :func:`sum_squares`)."""
    return math.sqrt(sum_squares(v))


def wrap_angle(angle: float) -> float:
    """Wrap an angle in radians to [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def quat_from_yaw(yaw: float) -> np.ndarray:
    """Quaternion ``[x, y, z, w]`` of a rotation by ``yaw`` radians about +y."""
    if not math.isfinite(yaw):
        raise ValueError(f"yaw must be finite, got {yaw}")
    return np.array([0.0, math.sin(yaw / 2.0), 0.0, math.cos(yaw / 2.0)])


def yaw_from_quat(q_xyzw) -> float:
    """Heading (radians in [-pi, pi)) of a rotation ``[x, y, z, w]``.

    Defined through the rotated forward vector, so it is also meaningful for rotations with some
    pitch or roll (the heading of their forward vector projected onto the floor); it need not be a
    unit quaternion.
    """
    q = _finite(np.asarray(q_xyzw, dtype=float).reshape(-1), "quaternion")
    if q.shape != (4,):
        raise ValueError(f"quaternion must have 4 values [x, y, z, w], got {q.tolist()}")
    n = sum_squares(q)
    if n < 1e-12:
        raise ValueError(f"quaternion has zero norm: {q.tolist()}")
    x, y, z, w = q / math.sqrt(n)
    # R @ (0, 0, -1) is minus the third column of the rotation matrix.
    fx = -(2.0 * (x * z + w * y))
    fz = -(1.0 - 2.0 * (x * x + y * y))
    return wrap_angle(math.atan2(-fx, -fz))


def heading_vector(yaw: float) -> np.ndarray:
    """Unit forward vector ``(x, 0, z)`` of an agent with heading ``yaw``."""
    return np.array([-math.sin(yaw), 0.0, -math.cos(yaw)])


def yaw_towards(source, target) -> float:
    """Heading that makes an agent at ``source`` face ``target`` (xz plane)."""
    s = _finite(np.asarray(source, dtype=float), "source")
    t = _finite(np.asarray(target, dtype=float), "target")
    dx, dz = t[0] - s[0], t[2] - s[2]
    return wrap_angle(math.atan2(-dx, -dz))


def to_agent_frame(vec: np.ndarray, yaw: float) -> tuple[float, float]:
    """World xz offset -> (forward, right) in the frame of an agent with heading ``yaw``."""
    c, s = math.cos(yaw), math.sin(yaw)
    x = c * vec[0] - s * vec[2]  # rotate by -yaw about +y
    z = s * vec[0] + c * vec[2]
    return -z, x


def pointgoal_polar(goal: np.ndarray, position: np.ndarray, yaw: float) -> np.ndarray:
    """[rho, theta] of the goal in the agent frame; theta counter-clockwise positive (Habitat's polar)."""
    fwd, right = to_agent_frame(np.asarray(goal) - np.asarray(position), yaw)
    return np.array([math.hypot(fwd, right), -math.atan2(right, fwd)], np.float32)
