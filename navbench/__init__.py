"""navbench: a CPU-friendly, Habitat-style benchmark harness for embodied navigation.

``import navbench`` registers a Gymnasium id for each task of :data:`navbench.tasks.TASKS`
(``navbench/PointNav-v0``, ``navbench/ObjectNav-v0``...; entry points are strings, so nothing heavy is
imported until an env is made). What users import is
listed in ``__all__`` and loaded on first use:

    >>> import navbench
    >>> navbench.Action.STOP == 0
    True
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import gymnasium as _gym

from navbench._version import __version__
from navbench.tasks import TASKS as _TASKS

if TYPE_CHECKING:
    from navbench.agents.base import Agent, BatchAgent
    from navbench.api import evaluate
    from navbench.env.config import Action, EnvConfig
    from navbench.episodes.types import Episode
    from navbench.eval.config import RunConfig
    from navbench.eval.records import EpisodeRecord, RunSummary

for _task in _TASKS.values():
    if _task.gym_id not in _gym.registry:
        # The env truncates at the task's step limit itself, as Habitat does; no TimeLimit wrapper on top.
        _gym.register(id=_task.gym_id, entry_point=_task.env_class, kwargs={"task": _task.name},
                      disable_env_checker=True)

# name -> the module that defines it; imported on first access, so `import navbench` stays light
_EXPORTS = {
    "evaluate": "navbench.api", "Agent": "navbench.agents.base", "BatchAgent": "navbench.agents.base",
    "Action": "navbench.env.config", "EnvConfig": "navbench.env.config", "Episode": "navbench.episodes.types",
    "RunConfig": "navbench.eval.config", "EpisodeRecord": "navbench.eval.records",
    "RunSummary": "navbench.eval.records",
}
__all__ = ["Action", "Agent", "BatchAgent", "EnvConfig", "Episode", "EpisodeRecord", "RunConfig", "RunSummary",
           "__version__", "evaluate"]


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module 'navbench' has no attribute {name!r}")
    import importlib
    value = getattr(importlib.import_module(_EXPORTS[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
