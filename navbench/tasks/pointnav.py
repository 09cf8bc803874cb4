"""PointNav: drive to a goal given as a polar offset (habitat-lab ``habitat/config/habitat/task/pointnav.yaml``,
``tasks/nav/nav.py`` ``PointGoalSensor`` / ``IntegratedPointGoalGPSAndCompassSensor``)."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from navbench.scene.pose import pointgoal_polar
from navbench.tasks.base import SPL_RULE, GoalContext, GoalSensor, Task


def _polar_space(dataset, config) -> spaces.Box:
    big = np.finfo(np.float32).max
    return spaces.Box(-big, big, (2,), np.float32)


def _goal(ctx: GoalContext) -> np.ndarray:
    assert ctx.episode is not None  # the env's episode, set by reset()
    return np.asarray(ctx.episode.goals[0].position, np.float64)


def pointgoal_with_gps_compass(ctx: GoalContext) -> np.ndarray:
    """[rho, theta] of the goal from where the agent is now."""
    return pointgoal_polar(_goal(ctx), ctx.agent_position, ctx.agent_yaw)


def pointgoal(ctx: GoalContext) -> np.ndarray:
    """[rho, theta] of the goal from the episode's start pose (Habitat's PointNav challenges, no GPS+compass)."""
    return pointgoal_polar(_goal(ctx), ctx.start_position, ctx.start_yaw)


TASK = Task(
    name="pointnav",
    gym_id="navbench/PointNav-v0",
    title="drive to a goal point given as [rho, theta] from the agent (or from the start, without GPS+compass)",
    reference="habitat-lab habitat/config/habitat/task/pointnav.yaml, habitat/tasks/nav/nav.py",
    goal_sensors=(
        GoalSensor("pointgoal_with_gps_compass", _polar_space, pointgoal_with_gps_compass,
                   enabled=lambda config: config.gps_compass),
        GoalSensor("pointgoal", _polar_space, pointgoal, enabled=lambda config: not config.gps_compass),
    ),
    episode_format="PointNav-v1",
    distance_to="POINT",
    success_distance=0.2,
    max_steps=500,
    # `select`: houses of their own for choosing among trained policies, so `val` is looked at once, to report
    splits=("train", "val", "select"),
    default_split="val",
    default_agent="pointnav",
    display_name="PointNav",
    rules="The agent is given the goal position as a distance and direction: from where it stands at every step "
          "with GPS+compass, or once, from the start pose, without them. An episode succeeds when the agent calls "
          "STOP within {sd} m geodesic distance of the goal position, and ends after at most {max_steps} actions; "
          + SPL_RULE,
    env_class="navbench.env.pointnav:PointNavEnv",
)
