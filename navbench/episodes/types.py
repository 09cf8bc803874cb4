"""Episodes as plain dataclasses, field-for-field with Habitat's PointNav-v1 / ObjectNav-v1 JSON.

Unknown JSON keys are kept in ``extra`` so a real dataset (HM3D, MP3D, OVON) survives a
read/write round-trip unchanged apart from float rounding.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


class EpisodeError(ValueError):
    """A dataset file or an episode in it is unusable; the message names the file and episode id."""


Vec3 = list[float]
Quat = list[float]  # [x, y, z, w]


@dataclass
class AgentState:
    position: Vec3
    rotation: Quat


@dataclass
class ViewPoint:
    agent_state: AgentState
    iou: float = 0.0


@dataclass
class NavigationGoal:
    """PointNav goal: a position with an optional radius (None = the task's success distance)."""

    position: Vec3
    radius: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass
class ObjectGoal:
    """ObjectNav goal: one object instance and the navigable view points from which it is seen."""

    position: Vec3
    object_id: int
    object_category: str
    radius: float | None = None
    object_name: str = ""
    room_id: str | None = None
    room_name: str | None = None
    view_points: list[ViewPoint] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)

    def view_point_positions(self) -> np.ndarray:
        return np.array([vp.agent_state.position for vp in self.view_points], np.float64).reshape(-1, 3)


@dataclass
class Episode:
    """One navigation episode. ``object_category`` is set for ObjectNav episodes, None for PointNav."""

    episode_id: str
    scene_id: str
    start_position: Vec3
    start_rotation: Quat
    goals: list[NavigationGoal | ObjectGoal] = field(default_factory=list)
    info: dict[str, Any] = field(default_factory=dict)
    object_category: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def task(self) -> str:
        return "objectnav" if self.object_category is not None else "pointnav"

    def goal_positions(self) -> np.ndarray:
        """The points distance-to-goal is measured to: view points for ObjectNav (object centres when a
        goal has none, as Habitat falls back), goal positions for PointNav."""
        pts = []
        for g in self.goals:
            if isinstance(g, ObjectGoal) and g.view_points:
                pts.append(g.view_point_positions())
            else:
                pts.append(np.asarray(g.position, np.float64).reshape(1, 3))
        if not pts:
            raise EpisodeError(f"episode {self.episode_id}: has no goals")
        return np.concatenate(pts, axis=0)


@dataclass
class EpisodeDataset:
    """A Habitat-format dataset: episodes plus, for ObjectNav, the shared goals table."""

    episodes: list[Episode] = field(default_factory=list)
    goals_by_category: dict[str, list[ObjectGoal]] = field(default_factory=dict)
    category_to_task_category_id: dict[str, int] = field(default_factory=dict)
    category_to_scene_annotation_category_id: dict[str, int] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def task(self) -> str:
        if self.goals_by_category or any(e.object_category is not None for e in self.episodes):
            return "objectnav"
        return "pointnav"

    @property
    def scene_ids(self) -> list[str]:
        return sorted({e.scene_id for e in self.episodes})
