"""``habitat_sim.physics``: kinematic velocity control (``VelocityControl``, used by habitat-lab's continuous
``velocity_control`` action) and the names habitat-lab's rearrangement code annotates with.

The other classes exist so that ``import habitat`` works; constructing one raises, since navbench's habitat_sim
covers navigation without physics.
"""

from __future__ import annotations

import enum

from navbench.habitat_sim import magnum as mn
from navbench.habitat_sim._out_of_scope import placeholder


class RigidState:
    """A rigid pose: ``rotation`` (mn.Quaternion) and ``translation`` (mn.Vector3)."""

    def __init__(self, rotation: mn.Quaternion | None = None, translation=None) -> None:
        self.rotation = rotation if rotation is not None else mn.Quaternion()
        self.translation = mn.Vector3() if translation is None else mn.Vector3(translation)


class VelocityControl:
    """Constant linear and angular velocities integrated by one explicit Euler step (habitat-sim
    ``esp::physics::VelocityControl::integrateTransform``): ``t += v dt``, then ``R = rot(|w| dt, w/|w|) R``, each
    velocity in the body frame when its ``*_is_local`` flag is set."""

    def __init__(self) -> None:
        self.linear_velocity = mn.Vector3()
        self.angular_velocity = mn.Vector3()
        self.controlling_lin_vel = False
        self.controlling_ang_vel = False
        self.lin_vel_is_local = False
        self.ang_vel_is_local = False

    def integrate_transform(self, dt: float, rigid_state: RigidState) -> RigidState:
        rotation, translation = rigid_state.rotation, mn.Vector3(rigid_state.translation)
        if self.controlling_lin_vel:
            v = mn.Vector3(self.linear_velocity)
            if self.lin_vel_is_local:
                v = rotation.transform_vector(v)
            translation = translation + v * dt
        if self.controlling_ang_vel:
            w = mn.Vector3(self.angular_velocity)
            if self.ang_vel_is_local:
                w = rotation.transform_vector(w)
            length = w.length()
            if length > 0.0:
                rotation = (mn.Quaternion.rotation(mn.Rad(length * dt), w / length) * rotation).normalized()
        return RigidState(rotation, translation)


class MotionType(enum.Enum):
    UNDEFINED = -1
    STATIC = 0
    KINEMATIC = 1
    DYNAMIC = 2


class RigidConstraintType(enum.Enum):
    PointToPoint = 0
    Fixed = 1


class CollisionGroups(enum.IntFlag):
    Default = 1
    Static = 2
    Kinematic = 4
    Dynamic = 8
    Robot = 16
    Noncollidable = 32
    UserGroup0 = 64


def _physics_only(name: str) -> type:
    return placeholder(f"habitat_sim.physics.{name}", "no physics")


ManagedRigidObject = _physics_only("ManagedRigidObject")
ManagedArticulatedObject = _physics_only("ManagedArticulatedObject")
ManagedBulletArticulatedObject = _physics_only("ManagedBulletArticulatedObject")
ManagedBulletRigidObject = _physics_only("ManagedBulletRigidObject")
JointMotorSettings = _physics_only("JointMotorSettings")
RaycastResults = _physics_only("RaycastResults")
CollisionGroupHelper = _physics_only("CollisionGroupHelper")
RigidConstraintSettings = _physics_only("RigidConstraintSettings")
RigidObjectManager = _physics_only("RigidObjectManager")
ArticulatedObjectManager = _physics_only("ArticulatedObjectManager")
ContactPointData = _physics_only("ContactPointData")
ArticulatedLink = _physics_only("ArticulatedLink")
