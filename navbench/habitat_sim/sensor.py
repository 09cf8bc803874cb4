"""``habitat_sim.sensor``: sensor specs and the sensors on an agent's node.

A :class:`Sensor` is a scene node under its agent's body, placed by its spec (``position`` relative to the body,
``orientation`` Euler radians applied about x, then y, then z in the body frame, as habitat-sim's
``Sensor::setTransformationFromSpec``); the simulator renders it at the node's absolute pose with navbench's
renderer at the spec's own resolution, near and far. A PINHOLE camera sees ``hfov`` across; an ORTHOGRAPHIC one
looks along parallel rays over ``1 / ortho_scale`` metres across and ``H / W / ortho_scale`` down (habitat-sim's
``projectionMatrixInternal``, ``src/esp/sensor/CameraSensor.cpp``). Observations are habitat-sim's: COLOR
``uint8 (H, W, 4)`` RGBA, DEPTH ``float32 (H, W)`` z-depth in metres with 0 where nothing was hit (for both
projections; habitat-sim itself unprojects an orthographic depth buffer with the perspective formula of
``src/esp/gfx_batch/DepthUnprojection.cpp``, so its orthographic DEPTH is not in metres), SEMANTIC
``uint32 (H, W)``, the instance ids ``semantic_scene`` lists, 0 for structure and background.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from navbench.habitat_sim import magnum as mn
from navbench.habitat_sim.config import (
    AudioSensorSpec,
    CameraSensorSpec,
    EquirectangularSensorSpec,
    FisheyeSensorDoubleSphereSpec,
    FisheyeSensorModelType,
    FisheyeSensorSpec,
    SensorSpec,
    SensorSubType,
    SensorType,
    VisualSensorSpec,
)
from navbench.habitat_sim.scene import SceneNode, SceneNodeType

__all__ = ["AudioSensorSpec", "CameraSensor", "CameraSensorSpec", "EquirectangularSensorSpec",
           "FisheyeSensorDoubleSphereSpec", "FisheyeSensorModelType", "FisheyeSensorSpec", "Sensor", "SensorSpec",
           "SensorSubType", "SensorType", "VisualSensorSpec", "apply_noise", "check_spec"]

COVERAGE = "navbench's habitat_sim covers navigation"

# habitat-sim's sensor noise models (src_python/habitat_sim/sensors/noise_models) -> the sensor types they apply
# to, and their keyword arguments; navbench.env.noise implements them
NOISE_MODELS: dict[str, tuple[SensorType, ...]] = {
    "None": (), "": (), "RedwoodDepthNoiseModel": (SensorType.DEPTH,), "GaussianNoiseModel": (SensorType.COLOR,),
    "SpeckleNoiseModel": (SensorType.COLOR,), "PoissonNoiseModel": (SensorType.COLOR,),
    "SaltAndPepperNoiseModel": (SensorType.COLOR,)}
NOISE_KWARGS: dict[str, set[str]] = {
    "None": set(), "": set(), "RedwoodDepthNoiseModel": {"noise_multiplier"},
    "GaussianNoiseModel": {"intensity_constant", "mean", "sigma"},
    "SpeckleNoiseModel": {"intensity_constant", "mean", "sigma"},
    "PoissonNoiseModel": set(), "SaltAndPepperNoiseModel": {"amount", "s_vs_p"}}


def apply_noise(spec: SensorSpec, obs: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``obs`` with the spec's noise model applied, drawn from ``rng``. A COLOR observation is noised whole, alpha
    included, as habitat-sim 0.3.3's ``Sensor.get_observation`` hands its RGBA buffer to the noise model
    (``src_python/habitat_sim/simulator.py``): salt and pepper then reaches the blue channel and never alpha."""
    from navbench.env import noise

    model, kw = str(spec.noise_model), dict(spec.noise_model_kwargs or {})
    if model in ("None", ""):
        return obs
    if model == "RedwoodDepthNoiseModel":
        return noise.redwood_depth(obs, float(kw.get("noise_multiplier", 1.0)), rng)
    if model == "GaussianNoiseModel":
        return noise.gaussian_rgb(obs, float(kw.get("intensity_constant", 0.2)), rng)
    if model == "SpeckleNoiseModel":
        return noise.speckle_rgb(obs, float(kw.get("intensity_constant", 0.2)), rng)
    if model == "PoissonNoiseModel":
        return noise.poisson_rgb(obs, rng)
    return noise.salt_and_pepper_rgb(obs, rng, float(kw.get("amount", 0.05)), float(kw.get("s_vs_p", 0.5)))


def check_spec(spec: SensorSpec) -> None:
    """Refuse, in one line naming the sensor, what this simulator does not render."""
    name = f"sensor {spec.uuid!r}"
    if isinstance(spec, (EquirectangularSensorSpec, FisheyeSensorSpec)) or spec.sensor_subtype in (
            SensorSubType.FISHEYE, SensorSubType.EQUIRECTANGULAR):
        raise NotImplementedError(f"{name}: {spec.sensor_subtype.name} sensors are not supported ({COVERAGE} with "
                                  "pinhole and orthographic cameras)")
    if not isinstance(spec, CameraSensorSpec):
        raise NotImplementedError(f"{name}: {type(spec).__name__} is not supported ({COVERAGE} with pinhole and "
                                  "orthographic cameras)")
    if spec.sensor_subtype not in (SensorSubType.PINHOLE, SensorSubType.ORTHOGRAPHIC):
        raise NotImplementedError(f"{name}: sensor_subtype {spec.sensor_subtype.name} is not supported (PINHOLE and "
                                  "ORTHOGRAPHIC are)")
    if spec.sensor_subtype == SensorSubType.ORTHOGRAPHIC and not float(spec.ortho_scale) > 0.0:
        raise ValueError(f"{name}: ortho_scale must be greater than 0, got {spec.ortho_scale}")
    if spec.sensor_type not in (SensorType.COLOR, SensorType.DEPTH, SensorType.SEMANTIC):
        raise NotImplementedError(f"{name}: sensor_type {spec.sensor_type.name} is not supported (COLOR, DEPTH "
                                  "and SEMANTIC are)")
    model = str(spec.noise_model)
    if model not in NOISE_MODELS:
        raise NotImplementedError(f"{name}: noise_model {model!r} is not supported (known: {sorted(NOISE_MODELS)})")
    kinds = NOISE_MODELS[model]
    if kinds and spec.sensor_type not in kinds:
        raise ValueError(f"{name}: noise_model {model!r} applies to {' and '.join(k.name for k in kinds)} sensors")
    kwargs = dict(spec.noise_model_kwargs or {})
    unknown = set(kwargs) - NOISE_KWARGS[model]
    if unknown:
        raise ValueError(f"{name}: noise_model {model!r} takes {sorted(NOISE_KWARGS[model])}, got {sorted(unknown)}")
    if model in ("GaussianNoiseModel", "SpeckleNoiseModel") and (
            float(kwargs.get("mean", 0.0)), float(kwargs.get("sigma", 1.0))) != (0, 1):
        raise NotImplementedError(f"{name}: {model} with mean or sigma other than 0 and 1 is not supported")
    h, w = (int(v) for v in np.asarray(spec.resolution).reshape(2))
    if h <= 0 or w <= 0:
        raise ValueError(f"{name}: resolution must be positive [H, W], got {[h, w]}")


class Sensor:
    """A sensor on an agent: ``uuid``, ``node`` (its scene node), :meth:`specification`, and
    :meth:`draw_observation` / :meth:`get_observation`."""

    def __init__(self, spec: CameraSensorSpec, parent: SceneNode, sim: Any) -> None:
        # sim: the Simulator that renders this sensor (navbench.habitat_sim.simulator imports this module)
        check_spec(spec)
        self._spec = spec
        self._node = SceneNode(parent)
        self._node.type = SceneNodeType.SENSOR
        self._sim = sim
        self._obs: np.ndarray | None = None
        self.set_transformation_from_spec()

    @property
    def uuid(self) -> str:
        return self._spec.uuid

    @property
    def node(self) -> SceneNode:
        return self._node

    @property
    def object(self) -> SceneNode:
        return self._node

    def specification(self) -> CameraSensorSpec:
        return self._spec

    @property
    def spec(self) -> CameraSensorSpec:
        return self._spec

    @property
    def hfov(self) -> mn.Deg:
        return mn.Deg(float(self._spec.hfov))

    @property
    def resolution(self) -> np.ndarray:
        return np.asarray(self._spec.resolution, dtype=np.int32).reshape(2)

    def set_transformation_from_spec(self) -> None:
        node = self._node
        node.reset_transformation()
        node.translate(mn.Vector3(np.asarray(self._spec.position, dtype=np.float32)))
        o = np.asarray(self._spec.orientation, dtype=np.float64).reshape(3)
        node.rotate_x(mn.Rad(o[0]))
        node.rotate_y(mn.Rad(o[1]))
        node.rotate_z(mn.Rad(o[2]))

    def world_pose(self) -> tuple[np.ndarray, np.ndarray]:
        """(position, rotation ``[x, y, z, w]``) of the sensor in the world."""
        q = self._node.absolute_rotation().normalized()
        return (np.asarray(self._node.absolute_translation, np.float64),
                np.array([*np.asarray(q.vector, np.float64), q.scalar]))

    def draw_observation(self) -> None:
        self._obs = self._sim._nb_render([self])[self.uuid]

    def get_observation(self) -> np.ndarray:
        if self._obs is None:
            self.draw_observation()
        assert self._obs is not None
        return self._obs


CameraSensor = Sensor
