"""``habitat_sim._ext.habitat_sim_bindings``: the names habitat-lab imports from habitat-sim's bindings."""

from navbench.habitat_sim.config import Configuration, SimulatorConfiguration
from navbench.habitat_sim.physics import RigidState

__all__ = ["Configuration", "RigidState", "SimulatorConfiguration"]
