"""``habitat_sim.sim``: the simulator and its configuration."""

from navbench.habitat_sim._out_of_scope import placeholder
from navbench.habitat_sim.config import Configuration, SimulatorConfiguration
from navbench.habitat_sim.simulator import Simulator

SimulatorBackend = placeholder("habitat_sim.sim.SimulatorBackend", "the C++ backend is navbench's Python")
ReplayRendererConfiguration = placeholder("habitat_sim.sim.ReplayRendererConfiguration", "no batch renderer")
ReplayRenderer = placeholder("habitat_sim.sim.ReplayRenderer", "no batch renderer")

__all__ = ["Configuration", "ReplayRenderer", "ReplayRendererConfiguration", "Simulator", "SimulatorBackend",
           "SimulatorConfiguration"]
