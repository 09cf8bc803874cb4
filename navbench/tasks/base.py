"""What a navigation task is: one :class:`Task` definition that the envs, the runner, the API and the CLI read.

A task states its episode reader, its goal observations (:class:`GoalSensor`: Habitat's uuid, the
Gymnasium space, how the value is computed), its default action list, its measures, its success
distance, its step limit, its bundled splits and default split, its default agent and its Gymnasium id.
Nothing outside ``navbench/tasks/`` names a particular task.

A goal sensor computes its observation from a :class:`GoalContext`: the env as a goal sensor sees it (the
episode, the agent's pose, the start pose, and a camera to render with), so a task module needs no env.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from navbench.episodes.types import Episode, EpisodeDataset, EpisodeError

# Habitat's action names, by Habitat's ids (habitat-lab habitat/sims/habitat_simulator/actions.py,
# HabitatSimActions: stop 0, move_forward 1, turn_left 2, turn_right 3, look_up 4, look_down 5).
NAV_ACTIONS = ("STOP", "MOVE_FORWARD", "TURN_LEFT", "TURN_RIGHT")
MEASURES = ("distance_to_goal", "success", "spl", "soft_spl")
# The sentence on SPL every Habitat task's rules end with (habitat-lab habitat/tasks/nav/nav.py SPL).
SPL_RULE = "SPL weighs success by the shortest path's length over the longer of it and the length walked."
# A table's columns: (header, measure, scale): SR and SPL in percent, distances in metres.
COLUMNS = (("SR", "success", 100), ("SPL", "spl", 100), ("SoftSPL", "soft_spl", 100), ("DTG", "distance_to_goal", 1))


class GoalContext(Protocol):
    """The env as a goal sensor reads it (``navbench.env.base.NavEnv`` provides all of it)."""

    episode: Episode | None
    dataset: EpisodeDataset
    config: Any  # navbench.env.config.EnvConfig
    asset: Any  # the episode's scene (navbench.scene.types.SceneAsset), for goal images at a file's camera pose

    @property
    def agent_position(self) -> np.ndarray: ...

    @property
    def agent_yaw(self) -> float: ...

    @property
    def start_position(self) -> np.ndarray: ...

    @property
    def start_yaw(self) -> float: ...

    def render_rgb(self, position: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        """The episode's RGB sensor (its size, hfov, height above the agent and mounting pitch) for an
        agent standing at ``position`` (on the floor) with ``rotation`` [x, y, z, w] (a yaw); no noise."""
        ...


@dataclass(frozen=True)
class GoalSensor:
    """One goal observation.

    Attributes:
        uuid: the observation's key, Habitat's sensor uuid (``objectgoal``, ``imagegoal``...).
        space: ``space(dataset, config)``: its Gymnasium space for this dataset and EnvConfig.
        observe: ``observe(context)``: its value now (see :class:`GoalContext`).
        per_episode: computed once when the episode starts and returned unchanged at every step (Habitat
            caches goal images per episode); else computed at every step.
        enabled: ``enabled(config)``: whether the env gives it under this EnvConfig (default: always).
    """
    uuid: str
    space: Callable[[EpisodeDataset, Any], Any]
    observe: Callable[[GoalContext], np.ndarray]
    per_episode: bool = False
    enabled: Callable[[Any], bool] = field(default=lambda config: True)


def default_reader(path: str | Path, select: Callable[..., list[Episode]] | None = None) -> EpisodeDataset:
    """Habitat's PointNav-v1 / ObjectNav-v1 JSON (:func:`navbench.episodes.io.load_dataset`)."""
    from navbench.episodes.io import load_dataset
    return load_dataset(path, select)


def default_episode_files(path: str | Path, gt: str | Path | None = None) -> list[Path]:
    """The files a split is read from: the file, then each ``content/*.json(.gz)`` beside it (habitat-lab's
    per-scene layout: :func:`navbench.episodes.instance_imagenav.split_files`)."""
    from navbench.episodes.instance_imagenav import split_files
    return split_files(Path(path))


# How InstanceImageNav's and GOAT-Bench's image goals are rendered (navbench.render.goal_images), as a protocol
# states it (Task.goal_images).
IMAGE_GOAL_RULE = "a pinhole camera at the file's image goal pose (pitch and roll too), its hfov and size; no noise"


@dataclass(frozen=True)
class Task:
    """One navigation task, as every part of navbench reads it.

    Attributes:
        name: ``--task`` and the run directory's first level (``pointnav``, ``objectnav``...).
        gym_id: the Gymnasium id (``navbench/PointNav-v0``).
        title: one line for ``navbench tasks``.
        reference: the upstream file(s) defining the task, as ``navbench tasks`` and docs/tasks.md cite them.
        goal_sensors: the goal observations, in the order they are added to the observation dict.
        episode_format: the Habitat dataset type its files are in (``PointNav-v1``, ``ObjectNav-v1``).
        read_episodes: ``read_episodes(path, select)`` -> EpisodeDataset; ``select`` as
            :func:`navbench.episodes.io.load_dataset` takes it. Bad input: EpisodeError naming file and field.
        actions: the action names, by id, when the EnvConfig does not give its own ``actions``.
        measures: what each record and the summary report (the env's ``info`` keys): Habitat's four
            (:data:`MEASURES`) and any of the task's own, which ``extra_info`` computes; a record holds each
            from the episode's last ``info`` (0 for a failed episode) and the summary their means.
        extra_info: optional ``extra_info(context, info)`` -> the task's own ``info`` entries, computed after
            each reset and step from the env (:class:`GoalContext`) and its standard ``info``.
        record_fields: ``info`` entries a record also holds but the summary does not average (per-subtask
            lists, such as GOAT-Bench's ``subtask_success``); absent from a failed episode's record.
        distance_to: ``"POINT"`` (goal positions) or ``"VIEW_POINTS"`` (the goals' view points, falling
            back on an object's centre when it has none), Habitat's DistanceToGoal ``distance_to``.
        success_distance: Habitat's ``success.success_distance`` for the task.
        success_rule: optional ``rule(split, dataset)`` -> a success distance other than ``success_distance``
            for a bundled split (``dataset`` None) or a user's file (its first episode), or None to keep it.
        success_rule_text: what ``success_rule`` does, in a few words (``navbench tasks`` prints it).
        max_steps: Habitat's ``environment.max_episode_steps`` for the task's benchmark.
        splits: the bundled splits (``episodes/NAME/SPLIT/SPLIT.json.gz``).
        default_split: what a run reads without ``--split`` or ``--episodes``.
        default_agent: what ``navbench run`` runs without ``--agent``: the strongest baseline that reads only
            the configuration's sensors (never a privileged agent, such as the oracle).
        group_by: the episode field tables break results down by (``object_category``), or None.
        env_class: the env's ``module:Class`` (the Gymnasium entry point); it takes ``task=NAME``.
        columns: ``navbench table``'s columns for the task's runs: (header, measure, scale).
        env_config: the named configuration (``configs/env/NAME.toml``) the task runs under when a run or an
            env is given none; None: navbench's EnvConfig with ``max_steps``.
        goal_images: how the task's goal images are rendered, in a line (camera, pose, size), or "" for a task
            without them: it changes what an agent is shown, so the protocol carries it.
        episode_files: ``episode_files(path, gt)`` -> every file a run of ``path`` reads its episodes (and their
            references) from, the file first; provenance hashes them all. ``gt``: a VLN-CE run's ``--gt``.
        headline: the measures ``navbench compare`` reports without ``--metric``; empty: those of ``columns``.
        display_name: the task's name in prose (``R2R-CE``), as a methods paragraph and errors write it.
        rules: the task's rules in words for a methods paragraph (``navbench protocol``): what the agent is given,
            when an episode succeeds and ends, what each measure means; ``{sd}`` (the success distance, m) and
            ``{max_steps}`` are filled in from the run's protocol.
    """
    name: str
    gym_id: str
    title: str
    reference: str
    goal_sensors: tuple[GoalSensor, ...]
    episode_format: str = "PointNav-v1"
    read_episodes: Callable[..., EpisodeDataset] = default_reader
    actions: tuple[str, ...] = NAV_ACTIONS
    measures: tuple[str, ...] = MEASURES
    extra_info: Callable[[GoalContext, dict[str, Any]], dict[str, Any]] | None = None
    record_fields: tuple[str, ...] = ()
    distance_to: str = "POINT"
    success_distance: float = 0.2
    success_rule: Callable[[str | None, EpisodeDataset | None], float | None] | None = None
    success_rule_text: str = ""
    max_steps: int = 500
    splits: tuple[str, ...] = ()
    default_split: str = ""  # "" for a task that bundles no split
    default_agent: str = "random"
    group_by: str | None = None
    env_class: str = "navbench.env.base:NavEnv"
    columns: tuple[tuple[str, str, float], ...] = COLUMNS
    env_config: str | None = None
    goal_images: str = ""
    episode_files: Callable[..., list[Path]] = default_episode_files
    headline: tuple[str, ...] = ()
    display_name: str = ""
    rules: str = ""

    def __post_init__(self) -> None:
        if self.distance_to not in ("POINT", "VIEW_POINTS"):
            raise ValueError(f"task {self.name}: distance_to must be POINT or VIEW_POINTS, got {self.distance_to!r}")
        if self.splits and self.default_split not in self.splits:
            raise ValueError(f"task {self.name}: default split {self.default_split!r} is not one of its splits")
        if not self.splits and self.default_split:
            raise ValueError(f"task {self.name}: default split {self.default_split!r}, but it bundles no split")
        if not self.display_name:
            object.__setattr__(self, "display_name", self.name)

    def success_distance_for(self, split: str | None = None, dataset: EpisodeDataset | None = None) -> float:
        """The success distance a run of this task scores at, for a bundled ``split`` or a user's
        ``dataset`` (see ``success_rule``)."""
        if self.success_rule is not None:
            sd = self.success_rule(split, dataset)
            if sd is not None:
                return sd
        return self.success_distance

    @property
    def headline_measures(self) -> tuple[str, ...]:
        """What ``navbench compare`` reports by default: ``headline``, else the measures of ``columns``."""
        return self.headline or tuple(dict.fromkeys(m for _, m, _ in self.columns))

    @property
    def extra_measures(self) -> tuple[str, ...]:
        """The task's measures beyond Habitat's four (:data:`MEASURES`)."""
        return tuple(m for m in self.measures if m not in MEASURES)

    def goal_points(self, episode: Episode) -> np.ndarray:
        """The points distance-to-goal is measured to (``distance_to``); EpisodeError without goals."""
        if self.distance_to == "VIEW_POINTS":
            return episode.goal_positions()
        if not episode.goals:
            raise EpisodeError(f"episode {episode.episode_id}: has no goals")
        return np.array([g.position for g in episode.goals], np.float64).reshape(-1, 3)

    @property
    def summary_keys(self) -> tuple[str, ...]:
        """What a run's summary averages (with intervals): navbench's SR / SPL / SoftSPL / DTG where the task
        measures them, in that order, then the task's other measures."""
        from navbench.metrics import METRIC_KEYS
        return (*(k for k in METRIC_KEYS if k in self.measures), *self.extra_measures)

    def sensors(self, config: Any) -> tuple[GoalSensor, ...]:
        """The goal sensors this EnvConfig enables."""
        return tuple(s for s in self.goal_sensors if s.enabled(config))

    def goal_sensor_uuid(self, config: Any = None) -> str:
        """habitat-baselines' ``goal_sensor_uuid``: the first goal sensor the config enables."""
        sensors = self.sensors(config) if config is not None else self.goal_sensors
        return sensors[0].uuid if sensors else ""

    def env_actions(self, config: Any = None) -> tuple[str, ...]:
        """The action list of an env under ``config``: its ``actions`` when it sets them, else the task's."""
        actions = getattr(config, "actions", None)
        return tuple(actions) if actions else self.actions

    def split_file(self, split: str) -> Path:
        from navbench.paths import split_file
        return split_file(self.name, split)

