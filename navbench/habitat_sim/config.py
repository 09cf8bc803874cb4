"""habitat-sim's configuration objects with its exact field names and defaults.

habitat-lab copies its yaml keys onto these with ``hasattr`` / ``setattr`` (``overwrite_config`` in
``habitat/sims/habitat_simulator/habitat_simulator.py``) and raises when a key has no field, so each class has
exactly habitat-sim's fields (``src_python/habitat_sim/simulator.py``, ``agent/agent.py``,
``src/esp/bindings/{SimBindings,SensorBindings,ShortestPathBindings}.cpp`` at habitat-sim main ``57ee4941``) and
no others: setting an unknown attribute raises AttributeError. Two objects are equal when every field is, which
is how ``Simulator.reconfigure`` decides whether to reload.
"""

from __future__ import annotations

import copy
import enum
from typing import Any

import numpy as np

from navbench.habitat_sim import magnum as mn


class _FieldsMeta(type):
    """Gives each class ``__slots__`` = its ``_defaults`` keys, so an unknown attribute cannot be set."""

    def __new__(mcs, name, bases, namespace):
        namespace["__slots__"] = tuple(namespace.get("_defaults", {}))
        return super().__new__(mcs, name, bases, namespace)


class _Fields(metaclass=_FieldsMeta):
    """A record with a fixed set of fields: ``_defaults`` maps each name to a default or a zero-argument factory."""

    _defaults: dict[str, Any] = {}

    def __init__(self, *args, **kwargs) -> None:
        names = list(self._all_defaults())
        if len(args) > len(names):
            raise TypeError(f"{type(self).__name__} takes at most {len(names)} positional arguments")
        values = dict(zip(names, args))
        for k, v in kwargs.items():
            if k not in names:
                raise TypeError(f"{type(self).__name__} has no field {k!r}")
            values[k] = v
        for name, default in self._all_defaults().items():
            setattr(self, name, values[name] if name in values else (default() if callable(default)
                                                                     else copy.copy(default)))

    @classmethod
    def _all_defaults(cls) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for klass in reversed(cls.__mro__):
            out.update(klass.__dict__.get("_defaults", {}))
        return out

    def _values(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self._all_defaults()}

    def __eq__(self, other) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return all(_equal(a, b) for a, b in zip(self._values().values(), other._values().values()))

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return f"{type(self).__name__}({', '.join(f'{k}={v!r}' for k, v in self._values().items())})"


def _equal(a, b) -> bool:
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if isinstance(a, (np.ndarray, mn._Vector)) or isinstance(b, (np.ndarray, mn._Vector)):
        try:
            return bool(np.array_equal(np.asarray(a, np.float64), np.asarray(b, np.float64)))
        except (TypeError, ValueError):
            return False
    return bool(a == b)


class SensorType(enum.Enum):
    """habitat-sim's ``esp::sensor::SensorType``."""

    NONE = 0
    COLOR = 1
    DEPTH = 2
    NORMAL = 3
    SEMANTIC = 4
    PATH = 5
    GOAL = 6
    FORCE = 7
    TENSOR = 8
    TEXT = 9
    AUDIO = 10


class SensorSubType(enum.Enum):
    NONE = 0
    PINHOLE = 1
    ORTHOGRAPHIC = 2
    FISHEYE = 3
    EQUIRECTANGULAR = 4


class FisheyeSensorModelType(enum.Enum):
    DOUBLE_SPHERE = 0


class SensorSpec(_Fields):
    _defaults = {"uuid": "", "sensor_type": SensorType.NONE, "sensor_subtype": SensorSubType.NONE,
                 "position": lambda: mn.Vector3(0.0, 1.5, 0.0), "orientation": lambda: mn.Vector3(0.0, 0.0, 0.0),
                 "noise_model": "None", "noise_model_kwargs": dict}


class VisualSensorSpec(SensorSpec):
    _defaults = {"resolution": lambda: np.array([128, 128], np.int32), "channels": 4, "near": 0.01,
                 "far": 1000.0, "clear_color": lambda: mn.Color4(0.0, 0.0, 0.0, 1.0), "gpu2gpu_transfer": False}


class CameraSensorSpec(VisualSensorSpec):
    """A pinhole (or orthographic) camera: ``resolution`` [H, W], ``hfov`` in degrees, ``position`` relative to
    the agent's body, ``orientation`` Euler radians (x, then y, then z)."""

    _defaults = {"hfov": lambda: mn.Deg(90.0), "ortho_scale": 0.1}

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.sensor_subtype = kwargs.get("sensor_subtype", SensorSubType.PINHOLE)


class EquirectangularSensorSpec(VisualSensorSpec):
    _defaults = {}

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.sensor_subtype = SensorSubType.EQUIRECTANGULAR


class FisheyeSensorSpec(VisualSensorSpec):
    _defaults = {"focal_length": lambda: mn.Vector2(0.0, 0.0), "principal_point_offset": None,
                 "sensor_model_type": FisheyeSensorModelType.DOUBLE_SPHERE}

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.sensor_subtype = SensorSubType.FISHEYE


class FisheyeSensorDoubleSphereSpec(FisheyeSensorSpec):
    _defaults = {"alpha": 0.59, "xi": -0.18}


class AudioSensorSpec(SensorSpec):
    _defaults = {}


class ActuationSpec(_Fields):
    """The amount of one action: metres for moves, degrees for turns and look up / down."""

    _defaults = {"amount": 0.25, "constraint": None}


class ActionSpec(_Fields):
    """A named action (``move_forward``, ``turn_left``, ...) and its actuation."""

    _defaults = {"name": "", "actuation": None}


def _default_action_space() -> dict[str, ActionSpec]:
    # habitat-sim agent/agent.py: AgentConfiguration.action_space
    return {"move_forward": ActionSpec("move_forward", ActuationSpec(amount=0.25)),
            "turn_left": ActionSpec("turn_left", ActuationSpec(amount=10.0)),
            "turn_right": ActionSpec("turn_right", ActuationSpec(amount=10.0))}


class AgentConfiguration(_Fields):
    _defaults = {"height": 1.5, "radius": 0.1, "sensor_specifications": list, "action_space": _default_action_space,
                 "body_type": "cylinder"}


class NavMeshSettings(_Fields):
    """Recast's build settings (habitat-sim ``esp::nav::NavMeshSettings``); :meth:`set_defaults` restores them."""

    _defaults = {"cell_size": 0.05, "cell_height": 0.2, "agent_height": 1.5, "agent_radius": 0.1,
                 "agent_max_climb": 0.2, "agent_max_slope": 45.0, "region_min_size": 20.0,
                 "region_merge_size": 20.0, "edge_max_len": 12.0, "edge_max_error": 1.3, "verts_per_poly": 6.0,
                 "detail_sample_dist": 6.0, "detail_sample_max_error": 1.0, "filter_low_hanging_obstacles": True,
                 "filter_ledge_spans": True, "filter_walkable_low_height_spans": True,
                 "include_static_objects": False}

    def set_defaults(self) -> None:
        for name, default in self._all_defaults().items():
            setattr(self, name, default)


class SimulatorConfiguration(_Fields):
    _defaults = {"scene_id": "", "scene_dataset_config_file": "default", "default_agent_id": 0,
                 "default_camera_uuid": "rgba_camera", "gpu_device_id": 0, "random_seed": 0,
                 "allow_sliding": True, "create_renderer": True, "frustum_culling": True, "enable_physics": False,
                 "enable_hbao": False, "physics_config_file": "data/default.physics_config.json",
                 "load_semantic_mesh": True, "force_separate_semantic_scene_graph": False,
                 "requires_textures": True, "leave_context_with_background_renderer": False,
                 "enable_gfx_replay_save": False, "navmesh_settings": None, "scene_light_setup": "",
                 "override_scene_light_defaults": False, "pbr_image_based_lighting": False,
                 "use_semantic_textures": True}


class Configuration(_Fields):
    """The simulator's whole configuration: ``sim_cfg`` and one ``AgentConfiguration`` per agent."""

    _defaults = {"sim_cfg": SimulatorConfiguration, "agents": list, "metadata_mediator": None,
                 "enable_batch_renderer": False}

    def __init__(self, sim_cfg: SimulatorConfiguration | None = None, agents: list | None = None, *args,
                 **kwargs) -> None:
        super().__init__(sim_cfg if sim_cfg is not None else SimulatorConfiguration(),
                         agents if agents is not None else [AgentConfiguration()], *args, **kwargs)
