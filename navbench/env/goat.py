"""``navbench/GOAT-v0``: GOAT-Bench's lifelong navigation, a sequence of subtasks in one episode.

Run it on a GOAT-Bench split (goat-bench's files, unchanged)::

    import gymnasium as gym, navbench
    env = gym.make("navbench/GOAT-v0", dataset="data/goat_bench/hm3d/v1/val_seen/val_seen.json.gz",
                   scene_dir="data/scene_datasets", config=navbench.EnvConfig.load("goat-bench"))
    obs, info = env.reset(seed=0)
    obs["current_subtask"], obs["subtask_category"]   # e.g. [0], "chair"
    obs, _, terminated, truncated, info = env.step(6)  # SUBTASK_STOP: the next subtask starts here

## Action space
``Discrete(7)``: STOP, MOVE_FORWARD, TURN_LEFT, TURN_RIGHT, LOOK_UP, LOOK_DOWN, SUBTASK_STOP (goat-bench
``goat_bench/task/actions.py``: ``subtask_stop`` is 6). SUBTASK_STOP does not move the agent.

## Observations (``Dict``)
The sensors of :class:`navbench.env.base.NavEnv` (``rgb``, ``depth``, ``gps`` and ``compass`` from the
episode's start) and the raw goal of the active subtask: ``current_subtask`` ([0], [1] or [2] for an
object, description or image subtask, [3] past the last one, as goat-bench's ``GoatCurrentSubtaskSensor``),
``subtask_category``, ``subtask_description`` ("" unless a description subtask) and ``subtask_image``
(rendered once per image subtask at its file's camera pose, zeros otherwise).

## Episode end and measures
SUBTASK_STOP closes the active subtask (success: geodesic distance to its goals' view points < 0.25 m)
and starts the next; closing the last one terminates the episode, as STOP does at once (the subtasks not
closed score 0); ``max_steps`` (5000) truncates it. ``info`` carries goat-bench's measures
(:func:`navbench.metrics.goat_metrics`) and, for the columns every task reports, ``success`` =
``partial_success``, ``spl`` = ``composite_spl``, ``soft_spl`` = ``composite_softspl``;
``geodesic_distance`` is the first subtask's start distance, ``distance_to_goal`` the active one's.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from navbench.env.base import NavEnv
from navbench.env.config import EnvConfig
from navbench.episodes.goat import SUBTASK_STOP, GoatEpisode, GoatProgress
from navbench.episodes.instance_imagenav import ImageGoal
from navbench.episodes.types import Episode, EpisodeDataset, EpisodeError
from navbench.render.goal_images import GoalImageCache


class GoatEnv(NavEnv):
    task = "goat"

    def __init__(self, dataset: str | Path | EpisodeDataset | None = None, scene_dir: str | Path | None = None,
                 config: EnvConfig | None = None, render_mode: str | None = None, task: str | None = None):
        self.goat_progress: GoatProgress | None = None
        self._pending: int | None = None  # the action NavEnv.step is taking, recorded when it reports
        self._field_subtask = -1  # the subtask the distance field measures to (-1: every subtask's goals)
        super().__init__(dataset, scene_dir, config, render_mode, task)
        if len(self.actions) <= SUBTASK_STOP or self.actions[SUBTASK_STOP] != "SUBTASK_STOP":
            raise ValueError(f"the GOAT env needs SUBTASK_STOP as action {SUBTASK_STOP}: leave EnvConfig.actions "
                             f"unset (the task's), got {', '.join(self.actions)}")
        self._images = GoalImageCache(self.config.gl_platform)

    # ------------------------------------------------------------------ goals
    def _goal_points(self, episode: Episode) -> np.ndarray:
        """Every subtask's view points: the storeys an episode runs on are chosen from all of its goals."""
        if not isinstance(episode, GoatEpisode):
            raise EpisodeError(f"episode {episode.episode_id}: not a GOAT-Bench episode")
        return np.concatenate([episode.subtask_goal_positions(k) for k in range(episode.num_goals)], axis=0)

    def _use_subtask(self, k: int) -> None:
        """Measure distance to the goals of subtask ``k`` from now on."""
        assert isinstance(self.episode, GoatEpisode) and self._motion is not None
        self._goals = self.episode.subtask_goal_positions(k)
        self._field = self._motion.distance_field(self._goals)
        self._field_subtask = k

    def _start_field(self) -> Any:
        """Subtask 0's field: all subtasks' view points choose the storeys the episode runs on, but distance is
        only ever measured to the active subtask's (a field to all of them would go unused)."""
        self._use_subtask(0)
        return self._field

    def goal_image(self, camera: ImageGoal) -> np.ndarray:
        """The active image subtask's goal image, rendered once per subtask; a copy, as per-episode goal
        observations are (what a caller is given is its own: writing into it changes no later step)."""
        assert self.episode is not None and self.asset is not None and self.goat_progress is not None
        key = (self.episode.scene_id, self.episode.episode_id, self.goat_progress.active)
        return self._images.get(key, self.asset, camera).copy()

    # ------------------------------------------------------------------ gym API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        self.goat_progress = None
        self._field_subtask = -1
        super().reset(seed=seed, options=options)
        assert isinstance(self.episode, GoatEpisode)
        self._use_subtask(0)
        self._d0 = float(self._field.distance(self._position))
        self.goat_progress = GoatProgress(self.episode, self.config.max_steps, self.success_distance)
        self.goat_progress.reset(self._position, self._d0)
        return self._observe(), self._info()

    def step(self, action):
        if self._done:
            raise RuntimeError("episode is over: call reset() before step()")
        progress = self.goat_progress
        assert progress is not None  # set by reset()
        if isinstance(action, (int, np.integer)) and int(action) == SUBTASK_STOP:
            self._num_steps += 1
            progress.step(SUBTASK_STOP, self._position, self._distance_to)  # the next subtask's distance
            terminated = progress.over and not progress.num_steps >= self.config.max_steps
            truncated = progress.over and not terminated
            self._done = progress.over
            return self._observe(), 0.0, terminated, truncated, self._info()
        self._pending = int(action)
        try:
            return super().step(action)
        finally:
            self._pending = None

    # ------------------------------------------------------------------ snapshots
    def snapshot(self) -> dict[str, Any]:
        """NavEnv's snapshot and where the GOAT episode stands (its states, active subtask, STOP)."""
        snap = super().snapshot()
        p = self.goat_progress
        assert p is not None  # set by reset()
        snap["goat"] = {"states": [[a, list(pos), d] for a, pos, d in p.states], "active": p.active,
                        "stop_called": p.stop_called}
        return snap

    def restore(self, snap: dict[str, Any]) -> dict[str, np.ndarray]:
        super().restore(snap)
        p, g = self.goat_progress, snap.get("goat")
        assert p is not None  # set by the reset restore makes
        if g is not None:
            p.load(g["states"], g["active"], g["stop_called"])
            if p.active < p.episode.num_goals:
                self._use_subtask(p.active)
        return self._observe()

    def _distance_to(self, k: int) -> float:
        """The distance from the agent to subtask ``k``'s goals (measured to them from now on)."""
        if k != self._field_subtask:
            self._use_subtask(k)
        return float(self._field.distance(self._position))

    def _info(self) -> dict[str, Any]:
        progress = self.goat_progress
        if progress is not None and self._pending is not None:  # NavEnv.step moved the agent: record the step
            progress.step(self._pending, self._position, self._distance_to)
            self._pending = None
        info = super()._info()
        if progress is None:
            return info
        m = progress.metrics()
        info.update({k: v for k, v in m.items() if k not in ("stop_called", "distance_to_goal")})
        info.update(success=m["partial_success"], spl=m["composite_spl"], soft_spl=m["composite_softspl"],
                    geodesic_distance=progress.states[0][2], current_subtask=progress.current_subtask)
        if math.isnan(info["distance_to_goal"]):
            info["distance_to_goal"] = progress.distance
        return info
