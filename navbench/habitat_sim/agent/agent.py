"""``habitat_sim.agent.agent``: ``AgentState``, ``SixDOFPose`` and ``Agent`` with habitat-sim's semantics.

``AgentState.position`` is the body's absolute translation (float32 (3,)), ``rotation`` a unit ``np.quaternion``
(y up; the agent faces -z); ``sensor_states`` maps each sensor's uuid to its absolute ``SixDOFPose``.
``set_state`` does not snap to the navigable area; a ``[x, y, z, w]`` rotation is converted; ``reset_sensors``
puts the sensors back at their spec poses (undoing look up / down); with ``infer_sensor_states=False`` the
sensors' local poses are derived from the absolute poses given.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from navbench.habitat_sim.agent.controls import ObjectControls
from navbench.habitat_sim.config import ActionSpec, ActuationSpec, AgentConfiguration
from navbench.habitat_sim.scene import SceneNode, SceneNodeType
from navbench.habitat_sim.utils.common import (
    quat_from_coeffs,
    quat_from_magnum,
    quat_rotate_vector,
    quat_to_magnum,
)

__all__ = ["ActionSpec", "ActuationSpec", "SixDOFPose", "AgentState", "AgentConfiguration", "Agent"]


def _unit_quaternion():
    from navbench.habitat_sim.utils.common import _qt

    return _qt().quaternion(1, 0, 0, 0)


def _check_pose(position, rotation, what: str) -> None:
    # habitat-sim utils/validators.py: all_is_finite, is_unit_length (tolerance 1e-4)
    if not all(map(math.isfinite, np.asarray(position, dtype=np.float64).reshape(-1).tolist())):
        raise ValueError(f"{what}.position must be finite, got {np.asarray(position).tolist()}")
    if isinstance(rotation, (list, tuple, np.ndarray)):
        norm = float(np.linalg.norm(np.asarray(rotation, dtype=np.float64)))
    else:
        norm = float(np.sqrt(rotation.norm())) if hasattr(rotation, "norm") else float("nan")
    if not abs(norm - 1.0) < 1e-4:
        raise ValueError(f"{what}.rotation must have unit length, got {rotation} (length {norm})")


def _unchecked(cls, position, rotation):
    """``cls(position, rotation)`` without the checks: for poses read off the scene graph, whose nodes were set
    from checked states (per-step state reads are habitat-lab's hot path)."""
    obj = object.__new__(cls)
    obj.position, obj.rotation = position, rotation
    return obj


class SixDOFPose:
    __slots__ = ("position", "rotation")

    def __init__(self, position=None, rotation=None) -> None:
        self.position = np.zeros(3) if position is None else position
        self.rotation = _unit_quaternion() if rotation is None else rotation
        _check_pose(self.position, self.rotation, "SixDOFPose")

    def __repr__(self) -> str:
        return f"SixDOFPose(position={self.position!r}, rotation={self.rotation!r})"


class AgentState:
    __slots__ = ("position", "rotation", "sensor_states")

    def __init__(self, position=None, rotation=None, sensor_states: dict[str, SixDOFPose] | None = None) -> None:
        self.position = np.zeros(3) if position is None else position
        self.rotation = _unit_quaternion() if rotation is None else rotation
        self.sensor_states = {} if sensor_states is None else sensor_states
        _check_pose(self.position, self.rotation, "AgentState")

    def __repr__(self) -> str:
        return (f"AgentState(position={self.position!r}, rotation={self.rotation!r}, "
                f"sensor_states={self.sensor_states!r})")


class Agent:
    """An agent: a body node with its sensors' nodes under it, its configuration and its controls."""

    def __init__(self, scene_node: SceneNode, agent_config: AgentConfiguration | None = None,
                 controls: ObjectControls | None = None) -> None:
        self.agent_config = agent_config if agent_config is not None else AgentConfiguration()
        self.controls = controls if controls is not None else ObjectControls()
        self._node = scene_node
        scene_node.type = SceneNodeType.AGENT
        self._sensors: dict[str, Any] = {}  # uuid -> navbench.habitat_sim.sensor.Sensor (the simulator fills it)
        self.initial_state: AgentState | None = None

    @property
    def scene_node(self) -> SceneNode:
        return self._node

    @property
    def sensors(self) -> dict[str, Any]:
        return self._sensors

    def get_sensor(self, uuid: str):
        return self._sensors.get(uuid)

    def act(self, action_id: Any) -> bool:
        """Take the action ``action_id`` of ``agent_config.action_space``; returns whether it collided."""
        if action_id not in self.agent_config.action_space:
            raise KeyError(f"No action {action_id} in action space")
        action = self.agent_config.action_space[action_id]
        if self.controls.is_body_action(action.name):
            return self.controls.action(self._node, action.name, action.actuation, apply_filter=True)
        for sensor in self._sensors.values():
            self.controls.action(sensor.node, action.name, action.actuation, apply_filter=False)
        return False

    def get_state(self) -> AgentState:
        node = self._node
        rotation = node.rotation
        position = node.absolute_translation
        state = _unchecked(AgentState, np.array(position), quat_from_magnum(rotation))
        state.sensor_states = {}
        body_rotation = node.absolute_rotation()
        for uuid, sensor in self._sensors.items():
            s = sensor.node
            # a sensor right under the body: SceneNode.absolute_translation's sum, the body's part computed once
            at = (position + body_rotation.transform_vector(s.translation) if s.parent is node
                  else s.absolute_translation)
            state.sensor_states[uuid] = _unchecked(SixDOFPose, np.array(at), quat_from_magnum(rotation * s.rotation))
        return state

    def set_state(self, state: AgentState, reset_sensors: bool = True, infer_sensor_states: bool = True,
                  is_initial: bool = False) -> None:
        _check_pose(state.position, state.rotation, "AgentState")
        if isinstance(state.rotation, (list, tuple, np.ndarray)):
            state.rotation = quat_from_coeffs(state.rotation)
        node = self._node
        node.reset_transformation()
        node.translate(np.asarray(state.position, dtype=np.float32))
        node.rotation = quat_to_magnum(state.rotation)
        if reset_sensors:
            for sensor in self._sensors.values():
                sensor.set_transformation_from_spec()
        if not infer_sensor_states:
            for uuid, pose in state.sensor_states.items():
                if uuid not in self._sensors:
                    raise KeyError(f"no sensor {uuid!r} on this agent")
                if isinstance(pose.rotation, (list, tuple, np.ndarray)):
                    pose.rotation = quat_from_coeffs(pose.rotation)
                s = self._sensors[uuid].node
                s.reset_transformation()
                s.translate(quat_rotate_vector(state.rotation.inverse(),
                                               np.asarray(pose.position, np.float64)
                                               - np.asarray(state.position, np.float64)))
                s.rotation = quat_to_magnum(state.rotation.inverse() * pose.rotation)
        if is_initial:
            self.initial_state = state

    @property
    def state(self) -> AgentState:
        return self.get_state()

    @state.setter
    def state(self, new_state: AgentState) -> None:
        self.set_state(new_state, reset_sensors=True, infer_sensor_states=True, is_initial=False)

    def close(self) -> None:
        self._sensors = {}

