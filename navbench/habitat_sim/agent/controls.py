"""``habitat_sim.agent.controls``: the move functions and ``ObjectControls``, as habitat-sim applies them
(``src_python/habitat_sim/agent/controls/{default_controls,object_controls}.py``).

``move_forward`` adds ``-amount`` times the node's rotated z axis to its translation; turns rotate the node about
its own y axis by ``amount`` degrees (left positive) and renormalise; ``look_up`` / ``look_down`` rotate it about
its own x axis (with an ActuationSpec ``constraint``, no further than that many degrees from level). Body actions
pass through the move filter (the path finder's ``try_step``), and the collision flag is habitat-sim's:
``|filtered - start|^2 + 1e-5 < |end - start|^2``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from navbench.habitat_sim import magnum as mn
from navbench.habitat_sim.config import ActuationSpec
from navbench.habitat_sim.scene import SceneNode

_EPS = 1e-5  # object_controls.py: collided when the filter shortens the step by more than this (squared)


def _move_along(node: SceneNode, distance: float, axis: int) -> None:
    ax = np.asarray(node.rotation.to_matrix())[:, axis]  # the node's local axis in its parent's frame
    node.translate(mn.Vector3(ax) * distance)


def _rotate_local(node: SceneNode, theta_deg: float, axis: int, constraint: float | None = None) -> None:
    if constraint is not None:
        # default_controls.py: the look angle (of the node's front about ``axis``) is clamped to +-constraint
        # degrees, the rotation cut short to reach it; only for a node turned about that axis alone
        rotation = node.rotation
        if float(rotation.angle()) > 0 and 1.0 - abs(float(np.asarray(rotation.axis())[axis])) > 1e-3:
            raise RuntimeError("Constrained look only works for a singular look action type")
        look = np.asarray(rotation.transform_vector(mn.Vector3(0.0, 0.0, -1.0)), np.float64)
        if axis == 0:
            look_angle = math.degrees(math.atan2(look[1], -look[2]))
        elif axis == 1:
            look_angle = -math.degrees(math.atan2(look[0], -look[2]))
        else:
            raise NotImplementedError("a constrained rotation about z is not supported (habitat-sim has no look "
                                      "angle about z)")
        if look_angle + theta_deg > constraint:
            theta_deg = constraint - look_angle
        elif look_angle + theta_deg < -constraint:
            theta_deg = -constraint - look_angle
    node.rotate_local(mn.Deg(theta_deg), mn.Vector3(np.eye(3)[axis]))
    node.rotation = node.rotation.normalized()


def move_forward(node: SceneNode, spec: ActuationSpec) -> None:
    _move_along(node, -spec.amount, 2)


def move_backward(node: SceneNode, spec: ActuationSpec) -> None:
    _move_along(node, spec.amount, 2)


def move_left(node: SceneNode, spec: ActuationSpec) -> None:
    _move_along(node, -spec.amount, 0)


def move_right(node: SceneNode, spec: ActuationSpec) -> None:
    _move_along(node, spec.amount, 0)


def turn_left(node: SceneNode, spec: ActuationSpec) -> None:
    _rotate_local(node, spec.amount, 1)


def turn_right(node: SceneNode, spec: ActuationSpec) -> None:
    _rotate_local(node, -spec.amount, 1)


def look_up(node: SceneNode, spec: ActuationSpec) -> None:
    _rotate_local(node, spec.amount, 0, spec.constraint)


def look_down(node: SceneNode, spec: ActuationSpec) -> None:
    _rotate_local(node, -spec.amount, 0, spec.constraint)


# name -> (function, body action); body actions move the agent's node and pass through the move filter
move_func_map: dict[str, tuple[Callable[[SceneNode, ActuationSpec], None], bool]] = {
    "move_forward": (move_forward, True), "move_backward": (move_backward, True),
    "move_left": (move_left, True), "move_right": (move_right, True),
    "turn_left": (turn_left, True), "turn_right": (turn_right, True),
    "look_up": (look_up, False), "look_down": (look_down, False),
}


class ObjectControls:
    """Applies a named action to a scene node; ``move_filter_fn(start, end)`` (the simulator sets it to the path
    finder's ``try_step``) keeps body moves on the navigable area."""

    def __init__(self, move_filter_fn: Callable | None = None) -> None:
        self.move_filter_fn = move_filter_fn if move_filter_fn is not None else (lambda start, end: end)

    @staticmethod
    def is_body_action(action_name: str) -> bool:
        if action_name not in move_func_map:
            raise KeyError(f"no action {action_name!r}: navbench's habitat_sim knows {sorted(move_func_map)}")
        return move_func_map[action_name][1]

    def action(self, obj: SceneNode, action_name: str, actuation_spec: ActuationSpec,
               apply_filter: bool = True) -> bool:
        """Apply the action to ``obj``; returns whether the move filter shortened it (a collision)."""
        if action_name not in move_func_map:
            raise KeyError(f"no action {action_name!r}: navbench's habitat_sim knows {sorted(move_func_map)}")
        start = obj.absolute_translation
        move_func_map[action_name][0](obj, actuation_spec)
        end = obj.absolute_translation
        collided = False
        if apply_filter:
            filtered = mn.Vector3(self.move_filter_fn(start, end))
            obj.translate(filtered - end)
            collided = ((filtered - start).dot() + _EPS) < (end - start).dot()
        return collided

    def __call__(self, obj: SceneNode, name: str, actuation_spec: ActuationSpec, apply_filter: bool = True) -> bool:
        return self.action(obj, name, actuation_spec, apply_filter)
