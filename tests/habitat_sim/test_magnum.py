"""navbench.habitat_sim.magnum against Magnum's semantics (float32 components, column-major matrices, dot())."""

import math

import numpy as np
import pytest

from navbench.habitat_sim import magnum as mn


def test_vector3_is_float32_and_interoperates_with_numpy():
    v = mn.Vector3(0.1, 0.9, 0)
    assert np.array(v).dtype == np.float32
    assert v.y == pytest.approx(np.float32(0.9))
    assert (np.array([1.0, 1.0, 1.0]) + v).tolist() == pytest.approx([1.1, 1.9, 1.0])
    assert isinstance(v - np.zeros(3), mn.Vector3)
    assert list(v * 2.0) == pytest.approx([0.2, 1.8, 0.0])
    assert list(-v) == pytest.approx([-0.1, -0.9, 0.0])
    assert v[2] == 0.0 and len(v) == 3


def test_vector3_dot_without_argument_is_squared_length():
    v = mn.Vector3(3.0, 4.0, 0.0)
    assert v.dot() == 25.0
    assert v.length() == 5.0
    assert v.dot(mn.Vector3.x_axis()) == 3.0
    assert list(v.normalized()) == pytest.approx([0.6, 0.8, 0.0])
    assert mn.Vector3.zero_init() == mn.Vector3(0, 0, 0)
    assert list(mn.Vector3.z_axis(2.0)) == [0.0, 0.0, 2.0]


def test_deg_rad_convert():
    assert float(mn.Rad(mn.Deg(180.0))) == pytest.approx(math.pi)
    assert float(mn.Deg(mn.Rad(math.pi / 2))) == pytest.approx(90.0)
    assert float(mn.Deg(30.0)) == 30.0


def test_quaternion_rotation_turns_forward_to_the_left_about_y():
    q = mn.Quaternion.rotation(mn.Deg(90.0), mn.Vector3.y_axis())
    # -z (forward) turned left by 90 degrees about +y faces -x
    assert list(q.transform_vector(mn.Vector3(0, 0, -1))) == pytest.approx([-1.0, 0.0, 0.0], abs=1e-6)
    assert q.scalar == pytest.approx(math.cos(math.pi / 4))
    assert list(q.vector) == pytest.approx([0.0, math.sin(math.pi / 4), 0.0])
    assert float(q.angle()) == pytest.approx(math.pi / 2, abs=1e-6)
    # composition applies the right operand first; the inverse undoes
    q2 = q * mn.Quaternion.rotation(mn.Rad(math.pi / 2), mn.Vector3.x_axis())
    back = q2.inverted() * q2
    assert back == mn.Quaternion()
    with pytest.raises(ValueError, match="normalized"):
        mn.Quaternion.rotation(mn.Deg(10.0), mn.Vector3(0, 2, 0))


def test_quaternion_matrix_round_trip():
    q = (mn.Quaternion.rotation(mn.Deg(30.0), mn.Vector3.y_axis())
         * mn.Quaternion.rotation(mn.Deg(-20.0), mn.Vector3.x_axis()))
    back = mn.Quaternion.from_matrix(q.to_matrix())
    assert back == q or back == -q


def test_matrix4_is_column_major_with_translation_column():
    m = mn.Matrix4.from_(np.eye(3), mn.Vector3(1, 2, 3))
    assert list(m[3]) == [1.0, 2.0, 3.0, 1.0]  # column 3
    assert list(m.translation) == [1.0, 2.0, 3.0]
    assert list(m.transform_point(mn.Vector3(1, 0, 0))) == [2.0, 2.0, 3.0]
    assert list(m.transform_vector(mn.Vector3(1, 0, 0))) == [1.0, 0.0, 0.0]
    r = mn.Matrix4.rotation(mn.Deg(90.0), mn.Vector3.y_axis())
    assert list(r.transform_vector(mn.Vector3(0, 0, -1))) == pytest.approx([-1.0, 0.0, 0.0], abs=1e-6)
    assert mn.Matrix4.identity_init() @ m == m
    assert list(mn.Matrix4.translation(mn.Vector3(4, 5, 6)).translation) == [4.0, 5.0, 6.0]


def test_range3d_center_and_size():
    r = mn.Range3D(mn.Vector3(0, 0, 0), mn.Vector3(2, 4, 6))
    assert list(r.center()) == [1.0, 2.0, 3.0]
    assert list(r.size()) == [2.0, 4.0, 6.0]
    assert not hasattr(r, "sizes")  # Magnum's Range3D has size(), not sizes


def test_import_time_calls_and_refused_loading():
    mn.trade.ImporterManager()
    with pytest.raises(NotImplementedError, match="covers navigation"):
        mn.trade.ImporterManager().load_and_instantiate("GltfImporter")
