"""habitat_sim.physics: VelocityControl's Euler step (habitat-lab's velocity_control action) and the refused rest."""

import math

import numpy as np
import pytest

from navbench.habitat_sim import magnum as mn
from navbench.habitat_sim.physics import ManagedRigidObject, RigidState, VelocityControl


def test_velocity_control_integrates_in_the_body_frame():
    vc = VelocityControl()
    vc.controlling_lin_vel = vc.controlling_ang_vel = True
    vc.lin_vel_is_local = vc.ang_vel_is_local = True
    vc.linear_velocity = mn.Vector3(0.0, 0.0, -1.0)  # forward
    vc.angular_velocity = mn.Vector3(0.0, math.pi / 2, 0.0)  # left, 90 degrees a second
    start = RigidState(mn.Quaternion.rotation(mn.Deg(90.0), mn.Vector3.y_axis()), mn.Vector3(1.0, 0.0, 0.0))
    end = vc.integrate_transform(0.5, start)
    # facing -x, half a metre forward; then turned a further 45 degrees left
    assert list(end.translation) == pytest.approx([0.5, 0.0, 0.0], abs=1e-6)
    assert float(mn.Deg(end.rotation.angle())) == pytest.approx(135.0, abs=1e-4)
    assert np.asarray(end.rotation.vector)[1] > 0
    vc.controlling_ang_vel = False
    assert vc.integrate_transform(0.5, start).rotation == start.rotation


def test_physics_objects_are_refused():
    with pytest.raises(NotImplementedError, match="covers navigation"):
        ManagedRigidObject()
