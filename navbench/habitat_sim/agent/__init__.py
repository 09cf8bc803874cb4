"""``habitat_sim.agent``: the agent, its state and its controls."""

from navbench.habitat_sim.agent.agent import (
    ActionSpec,
    ActuationSpec,
    Agent,
    AgentConfiguration,
    AgentState,
    SixDOFPose,
)
from navbench.habitat_sim.agent.controls import ObjectControls

__all__ = ["ActionSpec", "ActuationSpec", "Agent", "AgentConfiguration", "AgentState", "ObjectControls", "SixDOFPose"]
