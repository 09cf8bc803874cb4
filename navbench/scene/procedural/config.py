"""The procedural houses' parameters: :class:`HouseConfig` and the 5 cm floor-plan grid."""

from __future__ import annotations

from dataclasses import dataclass

PLAN_UNIT = 0.05  # metres per floor-plan grid unit


class HouseConfigError(ValueError):
    """A :class:`HouseConfig` value is out of range; the message names it."""


@dataclass(frozen=True)
class HouseConfig:
    min_rooms: int = 3
    max_rooms: int = 8
    max_extent: float = 20.0  # the house fits in max_extent x max_extent metres
    room_area: tuple[float, float] = (12.0, 22.0)  # m^2 of footprint per room, sampled per house
    min_room_size: float = 2.4  # smallest room side (wall centre to wall centre)
    hallway_prob: float = 0.5  # chance of a corridor layout when there are >= 5 rooms
    wall_thickness: float = 0.1
    wall_height: float = 2.6
    door_height: float = 2.1
    door_width: tuple[float, float] = (0.9, 1.2)
    extra_door_prob: float = 0.25
    door_clearance: float = 0.7  # free corridor depth in front of each doorway, both sides
    objects_per_room: tuple[int, int] = (3, 8)
    object_margin: float = 0.05  # minimum horizontal gap between object AABBs
    agent_radius: float = 0.18
    agent_height: float = 0.88
    grid: float = 0.05  # free-space raster cell used for the connectivity check
    furnish: bool = True

    def __post_init__(self) -> None:
        if not 1 <= self.min_rooms <= self.max_rooms:
            raise HouseConfigError(
                f"room count range ({self.min_rooms}, {self.max_rooms}) must satisfy 1 <= min <= max")
        if self.min_room_size < 2.0 or self.max_extent < self.min_room_size:
            raise HouseConfigError(
                f"min_room_size {self.min_room_size} must be >= 2.0 and <= max_extent {self.max_extent}")
        if not 0.0 < self.room_area[0] <= self.room_area[1]:
            raise HouseConfigError(f"room_area {self.room_area} must be an increasing positive range")
        if not 2 * self.agent_radius < self.door_width[0] <= self.door_width[1]:
            raise HouseConfigError(f"door_width {self.door_width} must be increasing and wider than the agent")
        if not self.door_height < self.wall_height:
            raise HouseConfigError(f"door_height {self.door_height} must be below wall_height {self.wall_height}")
        if not 0 <= self.objects_per_room[0] <= self.objects_per_room[1]:
            raise HouseConfigError(f"objects_per_room {self.objects_per_room} must be an increasing range >= 0")
