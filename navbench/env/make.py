"""The env of a registered task, by name: the class its definition names (``Task.env_class``).

    env = task_env("objectnav", "episodes/objectnav/val_seen/val_seen.json.gz")
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

from navbench.env.base import NavEnv
from navbench.env.config import EnvConfig
from navbench.episodes.types import EpisodeDataset
from navbench.tasks import get_task


def env_class(task: str) -> type[NavEnv]:
    """The env class of ``task`` (ValueError naming the known tasks for an unknown one)."""
    module, _, name = get_task(task).env_class.partition(":")
    return getattr(importlib.import_module(module), name)


def task_env(task: str, dataset: str | Path | EpisodeDataset | None = None, scene_dir: str | Path | None = None,
             config: EnvConfig | None = None, render_mode: str | None = None, **kwargs: Any) -> NavEnv:
    """A new env of ``task`` over ``dataset`` (default: the task's default bundled split)."""
    return env_class(task)(dataset, scene_dir=scene_dir, config=config, render_mode=render_mode, task=task, **kwargs)
