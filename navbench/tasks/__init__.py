"""The navigation tasks navbench runs: :data:`TASKS`, one :class:`~navbench.tasks.base.Task` each.

    >>> sorted(TASKS)
    ['goat', 'imagenav', 'instance_imagenav', 'objectnav', 'pointnav', 'r2r_ce', 'rxr_ce']
    >>> get_task("pointnav").gym_id
    'navbench/PointNav-v0'

Adding a task: write ``navbench/tasks/NAME.py`` defining ``TASK = Task(...)`` (its goal sensors, reader,
measures, limits and defaults), add the module to :data:`TASKS` below, and bundle its splits under
``episodes/NAME/``. The envs, the worker, the runner, the API, the CLI and the agents' seam read the
definition; none of them names a task.
"""

from __future__ import annotations

from navbench.tasks import goat, imagenav, instance_imagenav, objectnav, pointnav, vlnce
from navbench.tasks.base import GoalContext, GoalSensor, Task

__all__ = ["TASKS", "GoalContext", "GoalSensor", "Task", "get_task", "task_names"]

TASKS: dict[str, Task] = {t.name: t for t in (pointnav.TASK, objectnav.TASK, imagenav.TASK, instance_imagenav.TASK,
                                              goat.TASK, vlnce.R2R_TASK, vlnce.RXR_TASK)}


def task_names() -> tuple[str, ...]:
    """``--task``'s choices, in registry order."""
    return tuple(TASKS)


def get_task(name: str) -> Task:
    """The task named ``name``; a one-line ValueError naming the known tasks otherwise."""
    try:
        return TASKS[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown task {name!r}: choose from {', '.join(TASKS)}") from None
