"""InstanceImageNav: find the one object instance a goal image shows (habitat-lab
``habitat/config/habitat/task/instance_imagenav.yaml``, ``habitat/tasks/nav/instance_image_nav_task.py``;
HM3D v1, v2 and the 2023 challenge's v3 files, read by :mod:`navbench.episodes.instance_imagenav`)."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from navbench.episodes.instance_imagenav import (
    MAX_EPISODE_STEPS,
    SUCCESS_DISTANCE,
    InstanceImageEpisode,
    load_instance_imagenav,
)
from navbench.episodes.types import EpisodeDataset, EpisodeError
from navbench.tasks.base import NAV_ACTIONS, GoalContext, GoalSensor, Task


def _episode(ctx: GoalContext) -> InstanceImageEpisode:
    ep = ctx.episode
    if not isinstance(ep, InstanceImageEpisode):
        raise EpisodeError(f"episode {getattr(ep, 'episode_id', '?')}: not an InstanceImageNav episode "
                           f"(read its file with the instance_imagenav task)")
    return ep


def _image_space(dataset: EpisodeDataset, config) -> spaces.Box:
    # habitat-lab's InstanceImageGoalSensor: the size of the first goal's first image (L133-139)
    ep = next((e for e in dataset.episodes if isinstance(e, InstanceImageEpisode)), None)
    h, w = (ep.goals[0].image_goals[0].height, ep.goals[0].image_goals[0].width) if ep else (512, 512)
    return spaces.Box(0, 255, (h, w, 3), np.uint8)


def instance_imagegoal(ctx: GoalContext) -> np.ndarray:
    """The goal image: a pinhole camera at ``image_goals[goal_image_id]``'s world pose, hfov and size."""
    from navbench.render.goal_images import render_image_goal

    return render_image_goal(ctx.asset, _episode(ctx).image_goal, ctx.config.gl_platform)


def instance_imagegoal_hfov(ctx: GoalContext) -> np.ndarray:
    return np.array([_episode(ctx).image_goal.hfov_deg], np.float32)


TASK = Task(
    name="instance_imagenav",
    gym_id="navbench/InstanceImageNav-v0",
    title="find the object instance a goal image shows (the image from the file's camera pose, hfov and size)",
    reference="habitat-lab habitat/config/habitat/task/instance_imagenav.yaml, "
              "habitat/tasks/nav/instance_image_nav_task.py, habitat/datasets/image_nav/instance_image_nav_dataset.py",
    goal_sensors=(
        GoalSensor("instance_imagegoal", _image_space, instance_imagegoal, per_episode=True),
        GoalSensor("instance_imagegoal_hfov", lambda dataset, config: spaces.Box(0.0, 360.0, (1,), np.float32),
                   instance_imagegoal_hfov, per_episode=True),
    ),
    episode_format="InstanceImageNav-v1",
    read_episodes=load_instance_imagenav,
    actions=(*NAV_ACTIONS, "LOOK_UP", "LOOK_DOWN"),  # instance_imagenav.yaml's actions
    distance_to="VIEW_POINTS",
    success_distance=SUCCESS_DISTANCE,
    max_steps=MAX_EPISODE_STEPS,
    default_split="val",
    default_agent="oracle",
    group_by="object_category",
    env_class="navbench.env.base:NavEnv",
)
