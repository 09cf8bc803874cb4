"""``habitat_sim.utils.common``: quaternion helpers and the d3 colour palette, as habitat-sim defines them
(``src_python/habitat_sim/utils/common/{common,quaternion_utils}.py``).

Quaternions are ``numpy-quaternion``'s ``np.quaternion(w, x, y, z)``; coefficient lists are ``[x, y, z, w]``;
magnum quaternions are ``(vector, scalar)``.
"""

from __future__ import annotations

import math

import numpy as np

from navbench.habitat_sim import magnum as mn


def _qt():
    import quaternion  # numpy-quaternion: a dependency of navbench-habitat-sim and of habitat-lab

    return quaternion


def quat_from_coeffs(coeffs) -> np.quaternion:
    """``[x, y, z, w]`` -> ``np.quaternion``."""
    c = np.asarray(coeffs, dtype=np.float64).reshape(4)
    return _qt().quaternion(c[3], c[0], c[1], c[2])


def quat_to_coeffs(q) -> np.ndarray:
    """``np.quaternion`` -> ``[x, y, z, w]``."""
    return np.array([q.x, q.y, q.z, q.w])


def quat_from_magnum(q: mn.Quaternion) -> np.quaternion:
    x, y, z, w = q._floats()
    return _qt().quaternion(w, x, y, z)


def quat_to_magnum(q) -> mn.Quaternion:
    return mn.Quaternion((q.x, q.y, q.z), q.w)


def quat_from_angle_axis(theta: float, axis) -> np.quaternion:
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    return _qt().from_rotation_vector(theta * a)


def quat_to_angle_axis(q) -> tuple[float, np.ndarray]:
    q = q.normalized() if hasattr(q, "normalized") else q
    rv = _qt().as_rotation_vector(q)
    theta = float(np.linalg.norm(rv))
    if theta < 1e-8:
        return 0.0, np.array([1.0, 0.0, 0.0])
    return theta, rv / theta


def quat_rotate_vector(q, v) -> np.ndarray:
    """``v`` rotated by the unit quaternion ``q``."""
    vq = _qt().quaternion(0.0, *np.asarray(v, dtype=np.float64).reshape(3))
    return (q * vq * q.inverse()).imag


def quat_from_two_vectors(v0, v1) -> np.quaternion:
    """The shortest rotation taking ``v0`` to ``v1``."""
    a = np.asarray(v0, dtype=np.float64) / np.linalg.norm(v0)
    b = np.asarray(v1, dtype=np.float64) / np.linalg.norm(v1)
    c = float(np.dot(a, b))
    if c < -1.0 + 1e-8:  # opposite: any axis orthogonal to a
        axis = np.cross(a, [1.0, 0.0, 0.0])
        if np.linalg.norm(axis) < 1e-6:
            axis = np.cross(a, [0.0, 1.0, 0.0])
        return quat_from_angle_axis(math.pi, axis)
    axis = np.cross(a, b)
    s = math.sqrt((1.0 + c) * 2.0)
    return _qt().quaternion(s * 0.5, *(axis / s))


def angle_between_quats(q1, q2) -> float:
    """The angle of the rotation between two unit quaternions, in radians."""
    q1_inv = np.conjugate(q1)
    dq = q1_inv * q2
    return 2.0 * math.atan2(float(np.linalg.norm(dq.imag)), abs(dq.real))


def random_quaternion() -> np.quaternion:
    u = np.random.rand(3)
    return _qt().quaternion(math.sqrt(1 - u[0]) * math.sin(2 * math.pi * u[1]),
                            math.sqrt(1 - u[0]) * math.cos(2 * math.pi * u[1]),
                            math.sqrt(u[0]) * math.sin(2 * math.pi * u[2]),
                            math.sqrt(u[0]) * math.cos(2 * math.pi * u[2]))


def orthonormalize_rotation_shear(transformation: mn.Matrix4) -> mn.Matrix4:
    """The transformation with its rotation part orthonormalised (Gram-Schmidt on the columns)."""
    m = np.asarray(transformation, dtype=np.float64)
    r = m[:3, :3]
    c0 = r[:, 0] / np.linalg.norm(r[:, 0])
    c1 = r[:, 1] - np.dot(r[:, 1], c0) * c0
    c1 /= np.linalg.norm(c1)
    c2 = r[:, 2] - np.dot(r[:, 2], c0) * c0 - np.dot(r[:, 2], c1) * c1
    c2 /= np.linalg.norm(c2)
    return mn.Matrix4.from_(np.column_stack([c0, c1, c2]), m[:3, 3])


# habitat-sim src_python/habitat_sim/utils/common/common.py
d3_40_colors_rgb: np.ndarray = np.array(
    [[31, 119, 180], [174, 199, 232], [255, 127, 14], [255, 187, 120], [44, 160, 44], [152, 223, 138],
     [214, 39, 40], [255, 152, 150], [148, 103, 189], [197, 176, 213], [140, 86, 75], [196, 156, 148],
     [227, 119, 194], [247, 182, 210], [127, 127, 127], [199, 199, 199], [188, 189, 34], [219, 219, 141],
     [23, 190, 207], [158, 218, 229], [57, 59, 121], [82, 84, 163], [107, 110, 207], [156, 158, 222],
     [99, 121, 57], [140, 162, 82], [181, 207, 107], [206, 219, 156], [140, 109, 49], [189, 158, 57],
     [231, 186, 82], [231, 203, 148], [132, 60, 57], [173, 73, 74], [214, 97, 107], [231, 150, 156],
     [123, 65, 115], [165, 81, 148], [206, 109, 189], [222, 158, 214]], dtype=np.uint8)
d3_40_colors_hex: list[str] = [f"0x{r:02x}{g:02x}{b:02x}" for r, g, b in d3_40_colors_rgb.tolist()]


def colorize_ids(ids: np.ndarray) -> np.ndarray:
    out = np.zeros((*ids.shape[:2], 3), dtype=np.uint8)
    ok = ids >= 0
    out[ok] = d3_40_colors_rgb[ids[ok] % 40]
    return out
