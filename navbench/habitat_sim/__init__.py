"""habitat-sim's Python API for navigation, over navbench's scenes, navigability and renderer.

habitat-lab and habitat-baselines run on this package through the ``navbench-habitat-sim`` distribution
(``compat/habitat-sim``), whose top-level ``habitat_sim``, ``magnum`` and ``corrade`` modules are this package,
:mod:`navbench.habitat_sim.magnum` and an empty ``corrade``. See docs/habitat_lab.md for what runs and what is
refused. Module names mirror habitat-sim's (``agent``, ``nav``, ``sensor``, ``simulator``, ``utils.common``, ...).
"""

from navbench._version import __version__ as _navbench_version
from navbench.habitat_sim import (
    _ext,
    agent,
    errors,
    geo,
    gfx,
    logging,
    magnum,
    metadata,
    nav,
    physics,
    scene,
    sensor,
    sim,
    simulator,
    utils,
)
from navbench.habitat_sim.agent import (
    ActionSpec,
    ActuationSpec,
    Agent,
    AgentConfiguration,
    AgentState,
    SixDOFPose,
)
from navbench.habitat_sim.config import (
    AudioSensorSpec,
    CameraSensorSpec,
    Configuration,
    EquirectangularSensorSpec,
    FisheyeSensorDoubleSphereSpec,
    FisheyeSensorModelType,
    FisheyeSensorSpec,
    NavMeshSettings,
    SensorSpec,
    SensorSubType,
    SensorType,
    SimulatorConfiguration,
    VisualSensorSpec,
)
from navbench.habitat_sim.nav import (
    GreedyFollowerCodes,
    GreedyGeodesicFollower,
    MultiGoalShortestPath,
    PathFinder,
    ShortestPath,
)
from navbench.habitat_sim.physics import RigidState
from navbench.habitat_sim.sensor import CameraSensor
from navbench.habitat_sim.sim import ReplayRenderer, ReplayRendererConfiguration
from navbench.habitat_sim.simulator import Simulator
from navbench.habitat_sim.utils import common as _common  # noqa: F401  (habitat_sim.utils.common)

# habitat-sim's version this API follows, and which navbench answers it
__version__ = f"0.3.3+navbench.{_navbench_version}"
__navbench__ = _navbench_version
# no CUDA: habitat-lab's gpu2gpu paths are skipped
cuda_enabled = False
built_with_bullet = False

# the submodules habitat-sim has, as the top-level habitat_sim distribution registers them
SUBMODULES = ("_ext", "_ext.habitat_sim_bindings", "agent", "agent.agent", "agent.controls", "errors", "geo", "gfx",
              "logging", "metadata", "nav", "physics", "scene", "sensor", "sim", "simulator", "utils",
              "utils.common")

__all__ = [
    "ActionSpec", "ActuationSpec", "Agent", "AgentConfiguration", "AgentState", "AudioSensorSpec", "CameraSensor",
    "CameraSensorSpec", "Configuration", "EquirectangularSensorSpec", "FisheyeSensorDoubleSphereSpec",
    "FisheyeSensorModelType", "FisheyeSensorSpec", "GreedyFollowerCodes", "GreedyGeodesicFollower",
    "MultiGoalShortestPath", "NavMeshSettings", "PathFinder", "ReplayRenderer", "ReplayRendererConfiguration",
    "RigidState", "SensorSpec", "SensorSubType", "SensorType", "ShortestPath", "Simulator", "SimulatorConfiguration",
    "SixDOFPose", "VisualSensorSpec", "_ext", "agent", "cuda_enabled", "errors", "geo", "gfx", "logging", "magnum",
    "metadata", "nav", "physics", "scene", "sensor", "sim", "simulator", "utils",
]
