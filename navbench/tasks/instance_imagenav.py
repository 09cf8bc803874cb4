"""InstanceImageNav: find the one object instance a goal image shows (habitat-lab
``habitat/config/habitat/task/instance_imagenav.yaml``, ``habitat/tasks/nav/instance_image_nav_task.py``;
HM3D v1, v2 and the 2023 challenge's v3 files, read by :mod:`navbench.episodes.instance_imagenav`)."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from navbench.episodes.types import Episode, EpisodeDataset, EpisodeError
from navbench.tasks.base import IMAGE_GOAL_RULE, NAV_ACTIONS, SPL_RULE, GoalContext, GoalSensor, Task

# habitat-lab config/habitat/task/instance_imagenav.yaml (success.success_distance) and the benchmark yamls
# (environment.max_episode_steps); the reader and measures (navbench.episodes.instance_imagenav) state the same.
SUCCESS_DISTANCE = 0.1
MAX_EPISODE_STEPS = 1000


def read_episodes(path, select=None) -> EpisodeDataset:
    """:func:`navbench.episodes.instance_imagenav.load_instance_imagenav` (imported when a file is read)."""
    from navbench.episodes.instance_imagenav import load_instance_imagenav
    return load_instance_imagenav(path, select)


def _episode(ctx: GoalContext) -> Episode:
    from navbench.episodes.instance_imagenav import InstanceImageEpisode

    ep = ctx.episode
    if not isinstance(ep, InstanceImageEpisode):
        raise EpisodeError(f"episode {getattr(ep, 'episode_id', '?')}: not an InstanceImageNav episode "
                           f"(read its file with the instance_imagenav task)")
    return ep


def _image_space(dataset: EpisodeDataset, config) -> spaces.Box:
    # habitat-lab's InstanceImageGoalSensor: the size of the first goal's first image (L133-139)
    first = next((g.image_goals[0] for e in dataset.episodes for g in e.goals[:1] if getattr(g, "image_goals", None)),
                 None)
    h, w = (first.height, first.width) if first is not None else (512, 512)
    return spaces.Box(0, 255, (h, w, 3), np.uint8)


def instance_imagegoal(ctx: GoalContext) -> np.ndarray:
    """The goal image: a pinhole camera at ``image_goals[goal_image_id]``'s world pose, hfov and size."""
    from navbench.render.goal_images import render_image_goal

    return render_image_goal(ctx.asset, _episode(ctx).image_goal, ctx.config.gl_platform)  # type: ignore[attr-defined]


def instance_imagegoal_hfov(ctx: GoalContext) -> np.ndarray:
    return np.array([_episode(ctx).image_goal.hfov_deg], np.float32)  # type: ignore[attr-defined]


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
    read_episodes=read_episodes,
    actions=(*NAV_ACTIONS, "LOOK_UP", "LOOK_DOWN"),  # instance_imagenav.yaml's actions
    distance_to="VIEW_POINTS",
    success_distance=SUCCESS_DISTANCE,
    max_steps=MAX_EPISODE_STEPS,
    splits=("val",),
    default_split="val",
    default_agent="memory",
    display_name="InstanceImageNav",
    rules="The agent is given an image of one object instance, taken by a camera of the episode's own pose and "
          "field of view, and that field of view. An episode succeeds when the agent calls STOP within {sd} m "
          "geodesic distance of the nearest of the pictured instance's view points (the positions it is seen "
          "from), not of other instances of its category, and ends after at most {max_steps} actions; " + SPL_RULE,
    group_by="object_category",
    env_class="navbench.env.base:NavEnv",
    goal_images=IMAGE_GOAL_RULE,
)
