"""Environment configuration: the agent, its sensors and the episode limits (HM3D ObjectNav defaults)."""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from navbench.scene.navigability import NavGridConfig

# Habitat's action ids.
STOP, MOVE_FORWARD, TURN_LEFT, TURN_RIGHT = 0, 1, 2, 3
ACTION_NAMES = ("STOP", "MOVE_FORWARD", "TURN_LEFT", "TURN_RIGHT")


class Action(IntEnum):
    """The actions of both tasks, as an agent's ``act`` may return them (a plain int works too).

    >>> Action.MOVE_FORWARD == 1, Action(3).name
    (True, 'TURN_RIGHT')
    """
    STOP = STOP
    MOVE_FORWARD = MOVE_FORWARD
    TURN_LEFT = TURN_LEFT
    TURN_RIGHT = TURN_RIGHT


# Success distances by task as Habitat's configs set them; HM3D-OVON uses 0.25 m (naokiyokoyama/ovon
# config/experiments/*.yaml, habitat.task.measurements.success.success_distance).
SUCCESS_DISTANCE = {"pointnav": 0.2, "objectnav": 0.1, "ovon": 0.25}


@dataclass(frozen=True)
class EnvConfig:
    # sensors
    width: int = 224
    height: int = 224
    hfov_deg: float = 79.0
    min_depth: float = 0.5
    max_depth: float = 5.0
    normalize_depth: bool = True
    rgb: bool = True
    depth: bool = True
    semantic: bool = False  # per-pixel instance ids (Habitat's "semantic" sensor), -1 for structure
    # agent
    agent_height: float = 0.88  # camera height above the floor, and the clearance the agent needs
    agent_radius: float = 0.18
    max_climb: float = 0.2
    forward_step: float = 0.25
    turn_angle_deg: float = 30.0
    allow_sliding: bool = False  # HM3D ObjectNav: no sliding along walls
    # episode
    max_steps: int = 500
    success_distance: float | None = None  # None: the task's default (SUCCESS_DISTANCE)
    # An episode start up to this far from the navigable grid is snapped onto it: real datasets were made
    # on habitat-sim's navmesh, whose boundary differs from our grid by a cell or two.
    start_snap_tolerance: float = 0.25
    # infrastructure
    cell_size: float = 0.05
    # "auto": EGL when a GPU is present, else OSMesa (navbench.render.gl_platform); or "osmesa", "egl"
    gl_platform: str = "auto"

    def nav_grid_config(self) -> NavGridConfig:
        """The navigability grid this body moves on: its height, radius and climb, at ``cell_size``."""
        # imported here: this module is read by the CLI at start-up, the grid's module pulls trimesh and cv2
        from navbench.scene.navigability import NavGridConfig
        return NavGridConfig(agent_height=self.agent_height, agent_radius=self.agent_radius,
                             max_climb=self.max_climb, cell_size=self.cell_size)
