"""ImageNav: reach the place a goal image was taken (habitat-lab ``habitat/config/habitat/task/imagenav.yaml``,
``habitat/tasks/nav/nav.py`` ``ImageGoalSensor``; benchmarks ``habitat/config/benchmark/nav/imagenav/
imagenav_{gibson,mp3d}.yaml``).

Episodes are Habitat's PointNav-v1 files, unchanged (``habitat/config/habitat/dataset/imagenav/gibson.yaml``:
``type: PointNav-v1``). The ``imagegoal`` observation is the episode's RGB sensor (its size, hfov, height and
mounting) rendered with the agent standing at ``goals[0].position``, turned by a yaw drawn from the episode id,
rendered once when the episode starts and the same at every step. Success: STOP within 0.2 m (geodesic) of the
goal point; 1000 steps.

Habitat draws the yaw as ``RandomState(abs(hash(episode_id)) % 2**32).uniform(0, 2 pi)``, and Python salts
``hash`` of a string per process, so its goal images change from run to run. navbench seeds the same draw with a
stable hash of the id (:func:`goal_yaw`), so a goal image is the same in every process and every run.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
from gymnasium import spaces

from navbench.episodes.types import Episode, EpisodeDataset, EpisodeError
from navbench.tasks.base import SPL_RULE, GoalContext, GoalSensor, Task, default_reader


def goal_seed(episode_id: str) -> int:
    """The seed of an episode's goal yaw: the first 4 bytes (little-endian) of sha256 of its id, where Habitat
    takes ``abs(hash(episode_id)) % 2**32``.

    >>> goal_seed("0")
    1726737503
    """
    return int.from_bytes(hashlib.sha256(str(episode_id).encode()).digest()[:4], "little")


def goal_yaw(episode_id: str) -> float:
    """The yaw (radians, in [0, 2 pi)) the goal image is taken with, drawn as Habitat draws it."""
    return float(np.random.RandomState(goal_seed(episode_id)).uniform(0, 2 * np.pi))


def goal_rotation(episode_id: str) -> list[float]:
    """The goal camera's rotation [x, y, z, w] as Habitat writes it: ``[0, sin(a/2), 0, cos(a/2)]``."""
    a = goal_yaw(episode_id)
    return [0.0, math.sin(a / 2), 0.0, math.cos(a / 2)]


def _imagegoal_space(dataset: EpisodeDataset, config) -> spaces.Box:
    # the RGB sensor's observation space (ImageGoalSensor._get_observation_space)
    return spaces.Box(0, 255, (config.height, config.width, 3), np.uint8)


def imagegoal(ctx: GoalContext) -> np.ndarray:
    """The RGB image at ``goals[0].position`` facing :func:`goal_yaw` of the episode id."""
    assert ctx.episode is not None  # the env's episode, set by reset()
    return ctx.render_rgb(np.asarray(ctx.episode.goals[0].position, np.float64), goal_rotation(ctx.episode.episode_id))


def read_episodes(path: str | Path, select: Callable[..., list[Episode]] | None = None) -> EpisodeDataset:
    """Habitat's PointNav-v1 file (:func:`navbench.tasks.base.default_reader`); an episode with an object category
    instead of a goal point is one line naming the file, the episode and the field."""
    dataset = default_reader(path, select)
    for ep in dataset.episodes:
        if ep.object_category is not None:
            raise EpisodeError(f"{path}: episode {ep.episode_id}: object_category {ep.object_category!r}: ImageNav "
                               f"reads PointNav-v1 episodes (its goal image is taken at goals[0].position)")
    return dataset


TASK = Task(
    name="imagenav",
    gym_id="navbench/ImageNav-v0",
    title="reach the place a goal image (imagegoal, taken at goals[0]) shows",
    reference="habitat-lab habitat/config/habitat/task/imagenav.yaml, habitat/tasks/nav/nav.py ImageGoalSensor",
    goal_sensors=(GoalSensor("imagegoal", _imagegoal_space, imagegoal, per_episode=True),),
    episode_format="PointNav-v1",
    read_episodes=read_episodes,
    measures=("distance_to_goal", "success", "spl", "soft_spl"),
    distance_to="POINT",
    success_distance=0.2,
    max_steps=1000,
    splits=("val",),
    default_split="val",
    default_agent="memory",
    display_name="ImageNav",
    rules="The agent is given an image taken by its own camera standing at the goal position, turned by a yaw "
          "drawn from the episode id. An episode succeeds when the agent calls STOP within {sd} m geodesic distance "
          "of that position, and ends after at most {max_steps} actions; " + SPL_RULE,
    goal_images="the episode's RGB sensor at goals[0].position, yaw drawn from sha256(episode_id) (goal_yaw)",
)
