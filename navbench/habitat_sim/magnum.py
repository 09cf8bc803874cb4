"""The part of Magnum's Python API (``magnum``) that habitat-lab's navigation code uses, with Magnum's semantics.

Vectors and quaternions hold float32 components, as Magnum's ``Vector3`` / ``Quaternion`` do. Matrices are
column-major: ``m[i]`` is column ``i`` and ``m.translation`` is the last column. ``Quaternion.rotation`` takes
an angle (:class:`Deg` or :class:`Rad`) and a normalised axis; a quaternion is ``(vector, scalar)``.
``Vector3.dot()`` with no argument is the squared length (Magnum's ``dot()``). Names habitat-lab only annotates
with (``MutableImageView2D``, ``trade.MeshData``) exist; ``trade.ImporterManager`` exists and loading files
through it is refused, since navbench reads meshes itself.
"""

from __future__ import annotations

import math
import types

import numpy as np

_F = np.float32


class Rad(float):
    """An angle in radians (``float(Rad(Deg(180)))`` is pi)."""

    def __new__(cls, value: float | Deg | Rad = 0.0) -> Rad:
        if isinstance(value, Deg):
            value = math.radians(float(value))
        return super().__new__(cls, float(value))

    def __neg__(self) -> Rad:
        return Rad(-float(self))

    def __add__(self, other):
        return Rad(float(self) + float(Rad(other)))

    def __sub__(self, other):
        return Rad(float(self) - float(Rad(other)))

    def __mul__(self, k):
        return Rad(float(self) * float(k))

    __rmul__ = __mul__

    def __truediv__(self, k):
        if isinstance(k, (Rad, Deg)):
            return float(self) / float(Rad(k))
        return Rad(float(self) / float(k))

    def __repr__(self) -> str:
        return f"Rad({float(self)})"


class Deg(float):
    """An angle in degrees (``float(Deg(Rad(math.pi)))`` is 180)."""

    def __new__(cls, value: float | Deg | Rad = 0.0) -> Deg:
        if isinstance(value, Rad):
            value = math.degrees(float(value))
        return super().__new__(cls, float(value))

    def __neg__(self) -> Deg:
        return Deg(-float(self))

    def __add__(self, other):
        return Deg(float(self) + float(Deg(other)))

    def __sub__(self, other):
        return Deg(float(self) - float(Deg(other)))

    def __mul__(self, k):
        return Deg(float(self) * float(k))

    __rmul__ = __mul__

    def __truediv__(self, k):
        if isinstance(k, (Rad, Deg)):
            return float(self) / float(Deg(k))
        return Deg(float(self) / float(k))

    def __repr__(self) -> str:
        return f"Deg({float(self)})"


def _radians(angle) -> float:
    """Radians of an angle given as Rad, Deg or a plain number (taken as radians, as Magnum's Python does)."""
    return float(Rad(angle)) if isinstance(angle, Deg) else float(angle)


class _Vector:
    """Fixed-size float32 vector; subclasses set ``_N``."""

    _N = 3
    __slots__ = ("_v",)
    __array_priority__ = 10.0  # ndarray (op) vector defers to the vector's reflected operator

    def __init__(self, *args) -> None:
        n = self._N
        a = args[0] if len(args) == 1 else None
        if isinstance(a, _Vector) and a._N == n:  # the common copies, without numpy's generic conversion
            self._v = a._v.copy()
            return
        if isinstance(a, np.ndarray) and a.shape == (n,):
            self._v = a.astype(_F)
            return
        if not args:
            v = np.zeros(n, _F)
        elif len(args) == 1 and np.ndim(args[0]) == 0:
            v = np.full(n, args[0], _F)
        elif len(args) == 1:
            v = np.asarray(args[0], dtype=_F).reshape(-1).copy()
        elif len(args) == 2 and n == 3 and np.ndim(args[0]) == 1 and len(args[0]) == 2:
            v = np.array([*args[0], args[1]], _F)  # Vector3(Vector2, z)
        elif len(args) == 2 and n == 4 and np.ndim(args[0]) == 1 and len(args[0]) == 3:
            v = np.array([*args[0], args[1]], _F)  # Vector4(Vector3, w)
        else:
            v = np.array(args, dtype=_F)
        if v.shape != (n,):
            raise TypeError(f"{type(self).__name__} takes {n} components, got {np.asarray(args, object).tolist()}")
        self._v = v

    @classmethod
    def _of(cls, arr):
        out = cls.__new__(cls)
        out._v = np.array(arr, dtype=_F).reshape(cls._N)
        return out

    @classmethod
    def zero_init(cls):
        return cls._of(np.zeros(cls._N))

    # numpy interop: np.array(v) is float32
    def __array__(self, dtype=None, copy=None):
        return self._v.copy() if dtype is None else self._v.astype(dtype)

    def __len__(self) -> int:
        return self._N

    def __iter__(self):
        return iter(float(c) for c in self._v)

    def __getitem__(self, i):
        return float(self._v[i])

    def __setitem__(self, i, value) -> None:
        self._v[i] = value

    def __eq__(self, other) -> bool:
        try:
            o = np.asarray(other, dtype=_F).reshape(-1)
        except (TypeError, ValueError):
            return NotImplemented
        return o.shape == (self._N,) and bool(np.all(np.abs(self._v - o) <= 1e-5 * np.maximum(1.0, np.abs(o))))

    def __ne__(self, other) -> bool:
        eq = self.__eq__(other)
        return eq if eq is NotImplemented else not eq

    __hash__ = None  # mutable, as Magnum's vectors are

    def _arg(self, other):
        return other._v if isinstance(other, _Vector) else np.asarray(other, dtype=_F)

    def __add__(self, other):
        return type(self)._of(self._v + self._arg(other))

    def __radd__(self, other):
        return np.asarray(other, dtype=_F) + self._v if isinstance(other, np.ndarray) else self.__add__(other)

    def __sub__(self, other):
        return type(self)._of(self._v - self._arg(other))

    def __rsub__(self, other):
        if isinstance(other, np.ndarray):
            return np.asarray(other, dtype=_F) - self._v
        return type(self)._of(self._arg(other) - self._v)

    def __mul__(self, other):
        return type(self)._of(self._v * self._arg(other))

    def __rmul__(self, other):
        return self.__mul__(other)

    def __truediv__(self, other):
        return type(self)._of(self._v / self._arg(other))

    def __neg__(self):
        return type(self)._of(-self._v)

    def dot(self, other=None) -> float:
        """``dot()``: the squared length; ``dot(other)``: the dot product."""
        o = self._v if other is None else self._arg(other)
        return float(np.dot(self._v, o))

    def length(self) -> float:
        return float(np.sqrt(np.dot(self._v, self._v)))

    def normalized(self):
        return type(self)._of(self._v / _F(self.length()))

    def is_normalized(self) -> bool:
        return abs(self.dot() - 1.0) < 2 * 1e-6 * 8  # Magnum: |1 - dot| < 2 epsilon (float32), loosely

    def __repr__(self) -> str:
        return f"{type(self).__name__}({', '.join(f'{c:g}' for c in self._v)})"


def _component(i: int) -> property:
    return property(lambda self: float(self._v[i]), lambda self, value: self._v.__setitem__(i, value))


class Vector2(_Vector):
    _N = 2
    __slots__ = ()
    x, y = _component(0), _component(1)

    @classmethod
    def x_axis(cls, length: float = 1.0) -> Vector2:
        return cls(length, 0.0)

    @classmethod
    def y_axis(cls, length: float = 1.0) -> Vector2:
        return cls(0.0, length)


class Vector3(_Vector):
    _N = 3
    __slots__ = ()
    x, y, z = _component(0), _component(1), _component(2)
    r, g, b = x, y, z

    @property
    def xy(self) -> Vector2:
        return Vector2._of(self._v[:2])

    @classmethod
    def x_axis(cls, length: float = 1.0) -> Vector3:
        return cls(length, 0.0, 0.0)

    @classmethod
    def y_axis(cls, length: float = 1.0) -> Vector3:
        return cls(0.0, length, 0.0)

    @classmethod
    def z_axis(cls, length: float = 1.0) -> Vector3:
        return cls(0.0, 0.0, length)

    @classmethod
    def x_scale(cls, s: float) -> Vector3:
        return cls(s, 1.0, 1.0)

    @classmethod
    def y_scale(cls, s: float) -> Vector3:
        return cls(1.0, s, 1.0)

    @classmethod
    def z_scale(cls, s: float) -> Vector3:
        return cls(1.0, 1.0, s)


class Vector4(_Vector):
    _N = 4
    __slots__ = ()
    x, y, z, w = _component(0), _component(1), _component(2), _component(3)

    @property
    def xyz(self) -> Vector3:
        return Vector3._of(self._v[:3])


class Color3(Vector3):
    __slots__ = ()


class Color4(Vector4):
    __slots__ = ()
    r, g, b, a = Vector4.x, Vector4.y, Vector4.z, Vector4.w

    @property
    def rgb(self) -> Color3:
        return Color3._of(self._v[:3])


class Quaternion:
    """A rotation quaternion ``(vector, scalar)`` in float32; ``q * p`` applies ``p`` first."""

    __slots__ = ("_v", "_s")

    def __init__(self, vector=None, scalar: float | None = None) -> None:
        if vector is None and scalar is None:
            self._v, self._s = np.zeros(3, _F), _F(1.0)
            return
        if scalar is None:  # Quaternion(((x, y, z), w))
            vector, scalar = vector
        v = np.asarray(vector, dtype=_F).reshape(-1).copy()
        if v.shape != (3,):
            raise TypeError(f"Quaternion's vector part takes 3 components, got {np.asarray(vector).tolist()}")
        self._v, self._s = v, _F(scalar)

    @classmethod
    def identity_init(cls) -> Quaternion:
        return cls()

    @classmethod
    def zero_init(cls) -> Quaternion:
        return cls(np.zeros(3), 0.0)

    @classmethod
    def rotation(cls, angle, normalized_axis) -> Quaternion:
        """The rotation by ``angle`` (Deg or Rad) about ``normalized_axis`` (Magnum requires a unit axis)."""
        axis = np.asarray(normalized_axis, dtype=_F).reshape(3)
        if abs(float(np.dot(axis, axis)) - 1.0) > 1e-4:
            raise ValueError(f"Quaternion.rotation: axis {axis.tolist()} is not normalized")
        half = _radians(angle) / 2.0
        return cls(axis * _F(math.sin(half)), math.cos(half))

    @classmethod
    def from_matrix(cls, matrix) -> Quaternion:
        """The quaternion of a 3x3 rotation matrix (Magnum's ``Quaternion.from_matrix``)."""
        m = np.asarray(matrix, dtype=np.float64).reshape(3, 3)  # rows of the numpy view: m[row, col]
        t = np.trace(m)
        if t > 0:
            s = math.sqrt(t + 1.0) * 2
            w, x, y, z = 0.25 * s, (m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s
        elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
            s = math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2]) * 2
            w, x, y, z = (m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s
        elif m[1, 1] > m[2, 2]:
            s = math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2]) * 2
            w, x, y, z = (m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s
        else:
            s = math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1]) * 2
            w, x, y, z = (m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s
        return cls((x, y, z), w)

    @property
    def vector(self) -> Vector3:
        return Vector3._of(self._v)

    @vector.setter
    def vector(self, value) -> None:
        self._v = np.asarray(value, dtype=_F).reshape(3).copy()

    @property
    def scalar(self) -> float:
        return float(self._s)

    @scalar.setter
    def scalar(self, value: float) -> None:
        self._s = _F(value)

    @classmethod
    def _make(cls, x: float, y: float, z: float, w: float) -> Quaternion:
        out = cls.__new__(cls)
        out._v, out._s = np.array((x, y, z), _F), _F(w)
        return out

    def _floats(self) -> tuple[float, float, float, float]:
        x, y, z = self._v.tolist()
        return x, y, z, float(self._s)

    def __mul__(self, other):
        if isinstance(other, Quaternion):
            # Hamilton product in plain floats (numpy's cross and dot cost more than the arithmetic)
            x1, y1, z1, w1 = self._floats()
            x2, y2, z2, w2 = other._floats()
            return Quaternion._make(w1 * x2 + w2 * x1 + (y1 * z2 - z1 * y2), w1 * y2 + w2 * y1 + (z1 * x2 - x1 * z2),
                                    w1 * z2 + w2 * z1 + (x1 * y2 - y1 * x2), w1 * w2 - (x1 * x2 + y1 * y2 + z1 * z2))
        return Quaternion(self._v * _F(other), self._s * _F(other))

    def __rmul__(self, k):
        return Quaternion(self._v * _F(k), self._s * _F(k))

    def __add__(self, other: Quaternion) -> Quaternion:
        return Quaternion(self._v + other._v, self._s + other._s)

    def __sub__(self, other: Quaternion) -> Quaternion:
        return Quaternion(self._v - other._v, self._s - other._s)

    def __neg__(self) -> Quaternion:
        return Quaternion(-self._v, -self._s)

    def __eq__(self, other) -> bool:
        if not isinstance(other, Quaternion):
            return NotImplemented
        return bool(np.allclose(self._v, other._v, atol=1e-5) and abs(self._s - other._s) <= 1e-5)

    __hash__ = None

    def dot(self) -> float:
        return float(np.dot(self._v, self._v) + self._s * self._s)

    def length(self) -> float:
        return math.sqrt(self.dot())

    def is_normalized(self) -> bool:
        return abs(self.dot() - 1.0) < 1e-4

    def normalized(self) -> Quaternion:
        n = _F(self.length())
        return Quaternion(self._v / n, self._s / n)

    def conjugated(self) -> Quaternion:
        return Quaternion(-self._v, self._s)

    def inverted(self) -> Quaternion:
        d = _F(self.dot())
        return Quaternion(-self._v / d, self._s / d)

    def inverted_normalized(self) -> Quaternion:
        return self.conjugated()

    def angle(self) -> Rad:
        """The rotation angle, ``2 acos(scalar)`` (Magnum's ``Quaternion.angle()``)."""
        return Rad(2.0 * math.acos(max(-1.0, min(1.0, float(self._s)))))

    def axis(self) -> Vector3:
        return Vector3._of(self._v / _F(math.sqrt(max(1.0 - float(self._s) ** 2, 0.0)) or 1.0))

    def transform_vector(self, v) -> Vector3:
        """``q v q^-1`` for any quaternion (Magnum's ``transform_vector``)."""
        x, y, z, w = self._floats()
        n = x * x + y * y + z * z + w * w
        return self._rotate(v, x, y, z, w, n)

    def transform_vector_normalized(self, v) -> Vector3:
        x, y, z, w = self._floats()
        return self._rotate(v, x, y, z, w, 1.0)

    @staticmethod
    def _rotate(v, x: float, y: float, z: float, w: float, n: float) -> Vector3:
        # q v q* / |q|^2 = (v (w^2 - u.u) + 2 u (u.v) + 2 w (u x v)) / |q|^2, with u the vector part
        vx, vy, vz = v._v.tolist() if isinstance(v, Vector3) else np.asarray(v, dtype=_F).reshape(3).tolist()
        uv = x * vx + y * vy + z * vz
        k = w * w - (x * x + y * y + z * z)
        cx, cy, cz = y * vz - z * vy, z * vx - x * vz, x * vy - y * vx
        return Vector3._of(((k * vx + 2 * x * uv + 2 * w * cx) / n, (k * vy + 2 * y * uv + 2 * w * cy) / n,
                            (k * vz + 2 * z * uv + 2 * w * cz) / n))

    def to_matrix(self) -> Matrix3x3:
        x, y, z = (float(c) for c in self._v)
        w = float(self._s)
        rows = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                         [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                         [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        return Matrix3x3._of_rows(rows)

    def __repr__(self) -> str:
        return f"Quaternion({{{', '.join(f'{c:g}' for c in self._v)}}}, {float(self._s):g})"


class _Matrix:
    """Square float32 matrix, column-major as Magnum's: ``m[i]`` is column ``i``; subclasses set ``_N``."""

    _N = 4
    __slots__ = ("_m",)  # stored as rows (numpy's view): _m[row, col]

    def __init__(self, *columns) -> None:
        n = self._N
        if not columns:
            self._m = np.eye(n, dtype=_F)
        elif len(columns) == 1 and np.shape(columns[0]) == (n, n):
            self._m = np.asarray(columns[0], dtype=_F).T.copy()  # a tuple of columns
        elif len(columns) == n:
            self._m = np.column_stack([np.asarray(c, dtype=_F).reshape(n) for c in columns]).astype(_F)
        else:
            raise TypeError(f"{type(self).__name__} takes {n} columns of {n} components")

    @classmethod
    def _of_rows(cls, rows):
        out = cls.__new__(cls)
        out._m = np.asarray(rows, dtype=_F).reshape(cls._N, cls._N).copy()
        return out

    @classmethod
    def identity_init(cls, value: float = 1.0):
        return cls._of_rows(np.eye(cls._N) * value)

    @classmethod
    def zero_init(cls):
        return cls._of_rows(np.zeros((cls._N, cls._N)))

    def __array__(self, dtype=None, copy=None):
        # numpy's view has rows: np.array(m)[row, col], the usual matrix layout
        return self._m.copy() if dtype is None else self._m.astype(dtype)

    def __getitem__(self, i):
        col_type = {2: Vector2, 3: Vector3, 4: Vector4}[self._N]
        return col_type._of(self._m[:, i])

    def __setitem__(self, i, column) -> None:
        self._m[:, i] = np.asarray(column, dtype=_F).reshape(self._N)

    def __matmul__(self, other):
        if isinstance(other, _Matrix):
            return type(self)._of_rows(self._m @ other._m)
        return NotImplemented

    __mul__ = __matmul__

    def __eq__(self, other) -> bool:
        if not isinstance(other, _Matrix):
            return NotImplemented
        return self._N == other._N and bool(np.allclose(self._m, other._m, atol=1e-5))

    __hash__ = None

    def transposed(self):
        return type(self)._of_rows(self._m.T)

    def inverted(self):
        return type(self)._of_rows(np.linalg.inv(self._m.astype(np.float64)))

    def determinant(self) -> float:
        return float(np.linalg.det(self._m.astype(np.float64)))

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self._m.tolist()})"


class Matrix3x3(_Matrix):
    _N = 3
    __slots__ = ()

    def transform_vector(self, v) -> Vector3:
        return Vector3._of(self._m @ np.asarray(v, dtype=_F))


class Matrix3(_Matrix):
    """A 2-D homogeneous transform (3x3)."""

    _N = 3
    __slots__ = ()

    @classmethod
    def translation(cls, v) -> Matrix3:
        m = np.eye(3)
        m[:2, 2] = np.asarray(v, dtype=np.float64).reshape(2)
        return cls._of_rows(m)


class Matrix4(_Matrix):
    """A 3-D homogeneous transform (4x4)."""

    _N = 4
    __slots__ = ()

    @classmethod
    def from_(cls, rotation_scaling, translation) -> Matrix4:
        m = np.eye(4)
        m[:3, :3] = np.asarray(rotation_scaling, dtype=np.float64)
        m[:3, 3] = np.asarray(translation, dtype=np.float64).reshape(3)
        return cls._of_rows(m)

    @classmethod
    def rotation_x(cls, angle) -> Matrix4:
        return cls.from_(np.asarray(Quaternion.rotation(angle, Vector3.x_axis()).to_matrix()), np.zeros(3))

    @classmethod
    def rotation_y(cls, angle) -> Matrix4:
        return cls.from_(np.asarray(Quaternion.rotation(angle, Vector3.y_axis()).to_matrix()), np.zeros(3))

    @classmethod
    def rotation_z(cls, angle) -> Matrix4:
        return cls.from_(np.asarray(Quaternion.rotation(angle, Vector3.z_axis()).to_matrix()), np.zeros(3))

    @classmethod
    def scaling(cls, v) -> Matrix4:
        return cls._of_rows(np.diag([*np.asarray(v, dtype=np.float64).reshape(3), 1.0]))

    def rotation_scaling(self) -> Matrix3x3:
        return Matrix3x3._of_rows(self._m[:3, :3])

    def rotation_normalized(self) -> Matrix3x3:
        return self.rotation_scaling()

    def transform_point(self, p) -> Vector3:
        return Vector3._of(self._m[:3, :3] @ np.asarray(p, dtype=_F) + self._m[:3, 3])

    def transform_vector(self, v) -> Vector3:
        return Vector3._of(self._m[:3, :3] @ np.asarray(v, dtype=_F))

    def inverted_rigid(self) -> Matrix4:
        r = self._m[:3, :3].T
        return Matrix4.from_(r, -r @ self._m[:3, 3])


class _MatrixTranslation:
    """``Matrix4.translation``: a class method building a translation, and on an instance its translation column."""

    def __get__(self, obj, cls):
        if obj is None:
            return classmethod(lambda c, v: Matrix4.from_(np.eye(3), v)).__get__(None, cls)
        return Vector3._of(obj._m[:3, 3])


class _MatrixRotation:
    """``Matrix4.rotation``: a class method building a rotation, and on an instance its rotation part."""

    def __get__(self, obj, cls):
        if obj is None:
            def build(angle, normalized_axis) -> Matrix4:
                return Matrix4.from_(np.asarray(Quaternion.rotation(angle, normalized_axis).to_matrix()), np.zeros(3))
            return build
        return lambda: Matrix3x3._of_rows(obj._m[:3, :3])


Matrix4.translation = _MatrixTranslation()  # type: ignore[assignment]
Matrix4.rotation = _MatrixRotation()  # type: ignore[assignment]


class _Range:
    """An axis-aligned box ``[min, max]`` (Magnum's ``Range2D`` / ``Range3D``); subclasses set the vector type."""

    _vec: type[_Vector] = Vector3
    __slots__ = ("min", "max")

    def __init__(self, min=None, max=None) -> None:  # noqa: A002  (Magnum's names)
        if min is not None and max is None:
            min, max = min  # Range3D((min, max))
        self.min = self._vec.zero_init() if min is None else self._vec(min)
        self.max = self._vec.zero_init() if max is None else self._vec(max)

    @classmethod
    def from_size(cls, min, size):  # noqa: A002
        m = cls._vec(min)
        return cls(m, m + cls._vec(size))

    @classmethod
    def from_center(cls, center, half_size):
        c, h = cls._vec(center), cls._vec(half_size)
        return cls(c - h, c + h)

    def size(self):
        return self.max - self.min

    def center(self):
        return (self.min + self.max) * 0.5

    def contains(self, p) -> bool:
        a = np.asarray(p, dtype=_F)
        return bool(np.all(a >= np.asarray(self.min)) and np.all(a < np.asarray(self.max)))

    def __eq__(self, other) -> bool:
        if not isinstance(other, _Range):
            return NotImplemented
        return self.min == other.min and self.max == other.max

    __hash__ = None

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.min!r}, {self.max!r})"


class Range2D(_Range):
    _vec = Vector2
    __slots__ = ()


class Range3D(_Range):
    _vec = Vector3
    __slots__ = ()

    def size_x(self) -> float:
        return self.max.x - self.min.x

    def size_y(self) -> float:
        return self.max.y - self.min.y

    def size_z(self) -> float:
        return self.max.z - self.min.z


class MutableImageView2D:
    """Named for annotations in habitat-lab's rearrangement code; images are numpy arrays here."""

    def __init__(self, *args, **kwargs) -> None:
        raise NotImplementedError("magnum.MutableImageView2D: navbench's magnum covers navigation (no image views)")


class _ImporterManager:
    """``trade.ImporterManager``: constructible (habitat-lab makes one at import); loading plugins is refused."""

    def load_and_instantiate(self, name: str):
        raise NotImplementedError(f"magnum.trade importer {name!r}: navbench's magnum covers navigation; "
                                  "navbench reads scene meshes itself")


class _MeshData:
    def __init__(self, *args, **kwargs) -> None:
        raise NotImplementedError("magnum.trade.MeshData: navbench's magnum covers navigation (no mesh data)")


trade = types.ModuleType("magnum.trade", "Magnum's trade library: the names habitat-lab imports.")
trade.ImporterManager = _ImporterManager  # type: ignore[attr-defined]
trade.MeshData = _MeshData  # type: ignore[attr-defined]


def _dot(a, b) -> float:
    return float(np.dot(np.asarray(a, dtype=_F), np.asarray(b, dtype=_F)))


def _cross(a, b) -> Vector3:
    return Vector3._of(np.cross(np.asarray(a, dtype=_F), np.asarray(b, dtype=_F)))


def _angle(a, b) -> Rad:
    """The angle between two normalised vectors or quaternions (Magnum's ``math.angle``)."""
    if isinstance(a, Quaternion):
        d = float(np.dot(a._v, b._v) + a._s * b._s)
        return Rad(math.acos(max(-1.0, min(1.0, abs(d)))))
    return Rad(math.acos(max(-1.0, min(1.0, _dot(a, b)))))


def _lerp(a, b, t: float):
    if isinstance(a, _Vector):
        return type(a)._of(np.asarray(a) * _F(1 - t) + np.asarray(b) * _F(t))
    return a * (1 - t) + b * t


def _slerp(a: Quaternion, b: Quaternion, t: float) -> Quaternion:
    d = float(np.dot(a._v, b._v) + a._s * b._s)
    d = max(-1.0, min(1.0, d))
    theta = math.acos(d)
    if theta < 1e-6:
        return a
    s = math.sin(theta)
    return a * (math.sin((1 - t) * theta) / s) + b * (math.sin(t * theta) / s)


def _clamp(v, lo, hi):
    return min(max(v, lo), hi)


math_ = types.ModuleType("magnum.math", "Magnum's math functions: the ones navigation code calls.")
for _name, _fn in {"dot": _dot, "cross": _cross, "angle": _angle, "lerp": _lerp, "slerp": _slerp,
                   "clamp": _clamp}.items():
    setattr(math_, _name, _fn)
math_.pi = math.pi  # type: ignore[attr-defined]

__all__ = ["Rad", "Deg", "Vector2", "Vector3", "Vector4", "Color3", "Color4", "Quaternion", "Matrix3",
           "Matrix3x3", "Matrix4", "Range2D", "Range3D", "MutableImageView2D", "trade", "math_"]
