"""Goal images rendered from a dataset's camera poses: InstanceImageNav's ``instance_imagegoal`` and
GOAT-Bench's image subtasks, which use the same procedure.

habitat-lab ``habitat/tasks/nav/instance_image_nav_task.py`` (``InstanceImageGoalSensor``, L141-187)
adds a temporary pinhole COLOR sensor of ``resolution = image_dimensions`` ([H, W]) and ``hfov`` and
sets its pose to the file's world ``position`` and ``rotation`` (``infer_sensor_states=False``: the
agent's body, height and camera play no part, so pitch and roll are the file's), draws it and keeps
RGB. The image is made once per episode and returned unchanged at every step (:class:`GoalImageCache`).

A goal is any object with ``position`` (3), ``rotation`` [x, y, z, w], ``hfov_deg``, ``height`` and
``width`` (:class:`navbench.episodes.instance_imagenav.ImageGoal`).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from navbench.render.camera import CameraConfig
from navbench.scene.asset import SceneAsset


class CameraGoal(Protocol):
    @property
    def position(self) -> tuple[float, float, float]: ...
    @property
    def rotation(self) -> tuple[float, float, float, float]: ...
    @property
    def hfov_deg(self) -> float: ...
    @property
    def height(self) -> int: ...
    @property
    def width(self) -> int: ...


def image_goal_camera(goal: CameraGoal) -> CameraConfig:
    """The pinhole camera of a goal image: its width, height and horizontal field of view."""
    return CameraConfig(width=goal.width, height=goal.height, hfov_deg=goal.hfov_deg)


def render_image_goal(asset: SceneAsset, goal: CameraGoal, platform: str = "auto") -> np.ndarray:
    """The (H, W, 3) uint8 RGB image a camera at the goal's full world pose sees in ``asset``."""
    return _render(asset, goal, platform, ids=False)[0]


def render_image_goal_ids(asset: SceneAsset, goal: CameraGoal, platform: str = "auto") -> tuple[np.ndarray, np.ndarray]:
    """The goal image and its (H, W) int32 instance ids (-1: no object), from one frame: what oracle perception
    reads of a goal image, as it reads the keyframes' id images."""
    rgb, ids = _render(asset, goal, platform, ids=True)
    assert ids is not None
    return rgb, ids


def _render(asset: SceneAsset, goal: CameraGoal, platform: str, ids: bool) -> tuple[np.ndarray, np.ndarray | None]:
    from navbench.render.renderer import Renderer  # binds the GL platform: only when an image is drawn

    # one frame: building a scan's occlusion sets costs more than they save (a 200k-triangle scan on 2 shared
    # cores: 0.7 s a goal image with them, 0.35 s without; the images are equal)
    with Renderer(asset, image_goal_camera(goal), platform=platform, occlusion_culling=False) as renderer:
        out = renderer.render(np.asarray(goal.position), np.asarray(goal.rotation), rgb=True, depth=False, ids=ids)
    assert out.rgb is not None  # rendered when asked for
    return np.ascontiguousarray(out.rgb[:, :, :3], dtype=np.uint8), out.ids


class GoalImageCache:
    """A goal's image, rendered the first time it is asked for and kept until another is asked for (as
    habitat-lab keys its cache by ``"{scene_id} {episode_id}"``; GOAT asks per subtask)."""

    def __init__(self, platform: str = "auto") -> None:
        self.platform = platform
        self._key: object = None
        self._image: np.ndarray | None = None
        self.renders = 0

    def get(self, key: object, asset: SceneAsset, goal: CameraGoal) -> np.ndarray:
        if self._image is None or key != self._key:
            self._image = render_image_goal(asset, goal, self.platform)
            self._key = key
            self.renders += 1
        return self._image
