"""``navbench/VLNCE-v0``: follow a natural-language instruction (R2R-CE, RxR-CE) and stop within 3.0 m of its goal.

Run it::

    import gymnasium as gym, navbench
    env = gym.make("navbench/VLNCE-v0", dataset="R2R_VLNCE_v1-3_preprocessed/val_seen/val_seen.json.gz",
                   scene_dir="data/scene_datasets")           # task="rxr_ce" for RxR-CE files
    obs, info = env.reset(seed=0)
    obs["instruction"]["text"]
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces

from navbench.env.base import NavEnv
from navbench.env.config import EnvConfig
from navbench.episodes.types import Episode, EpisodeDataset
from navbench.metrics import VLNCE_METRIC_KEYS, vlnce_episode_metrics, vlnce_step_length
from navbench.scene.pose import quat_from_yaw


def habitat_heading(rotation: Any) -> float:
    """The heading VLN-CE's inference writes (``vlnce_baselines/common/environments.py: VLNCEInferenceEnv.get_info``):
    ``h = quaternion_rotate_vector(rotation.inverse(), [0, 0, -1])``, ``cartesian_to_polar(-h[2], h[0])[1]``
    (habitat-lab v0.1.7 ``habitat/tasks/utils.py``, ``habitat/utils/geometry_utils.py``); ``rotation`` [x, y, z, w]."""
    x, y, z, w = (float(v) for v in rotation)
    # the inverse of a unit quaternion is its conjugate; v' = q v q* for q = (w, -x, -y, -z)
    qv = np.array([-x, -y, -z])
    v = np.array([0.0, 0.0, -1.0])
    t = 2.0 * np.cross(qv, v)
    h = v + w * t + np.cross(qv, t)
    return float(math.atan2(h[0], -h[2]))


class VLNCEEnv(NavEnv):
    """Vision-and-language navigation in continuous environments, Habitat's conventions (y up, the agent faces
    -z, quaternions [x, y, z, w]), on any registered VLN-CE task (``task="r2r_ce"`` or ``"rxr_ce"``).

    ## Action space
    The task's configuration's (``configs/env/r2r-ce.toml``: STOP, MOVE_FORWARD 0.25 m, TURN_LEFT and TURN_RIGHT
    15 deg, sliding along walls; ``rxr-ce.toml``: 30 deg turns, LOOK_UP / LOOK_DOWN 30 deg, no sliding).

    ## Observation space (``Dict``)
    ``rgb``, ``depth`` as the configuration sets them, and ``instruction``: ``text``, ``tokens`` (as in the
    file), ``trajectory_id``, for RxR ``language`` and, where they exist, ``features`` (see
    :mod:`navbench.tasks.vlnce`), the features also as ``rxr_instruction`` (VLN-CE's ``RxRInstructionSensor``
    uuid). No GPS, compass or goal point.

    ## Episode end
    Terminated when STOP is called; truncated after 500 actions.

    ## Info
    VLN-CE's measures under its names, as :func:`navbench.metrics.vlnce_episode_metrics` computes them:
    ``distance_to_goal``, ``success``, ``oracle_success``, ``spl``, ``path_length`` (3-D Euclidean),
    ``steps_taken`` after every step; ``ndtw``, ``sdtw`` and ``ndtw_exact`` when the episode ends (NaN before,
    and without a gt file), with ``vlnce_path`` (the positions, headings and stop flags the leaderboard
    formats take). An episode without goals (a test split) is measured against nothing: its measures are NaN.
    Also ``num_steps``, ``collisions``, ``stop_called``, ``geodesic_distance`` (d0), ``episode_id``, ``scene_id``.

    ## Version history
    - v0: initial release.
    """

    task = "r2r_ce"

    def __init__(self, dataset: str | Path | EpisodeDataset | None = None, scene_dir: str | Path | None = None,
                 config: EnvConfig | None = None, render_mode: str | None = None, task: str | None = None):
        super().__init__(dataset, scene_dir, config, render_mode, task)
        self._track: dict[str, list] = {"positions": [], "headings": [], "distances": []}
        self._d_at: np.ndarray | None = None
        self._d_last = math.nan
        self._tl = 0.0
        self._oracle = False

    def _observation_spaces(self) -> dict:
        obs = super()._observation_spaces()
        ins = obs.get("instruction")
        # RxR with text features: also under VLN-CE's sensor uuid
        if isinstance(ins, spaces.Dict) and "features" in ins.spaces:
            obs["rxr_instruction"] = ins.spaces["features"]
        return obs

    def _goal_observation(self) -> dict:
        out = super()._goal_observation()
        if isinstance(out.get("instruction"), dict) and "features" in out["instruction"]:
            out["rxr_instruction"] = out["instruction"]["features"]  # RxRInstructionSensor's uuid
        return out

    def _goal_points(self, episode: Episode) -> np.ndarray:
        if episode.goals:
            return super()._goal_points(episode)
        # nothing to measure against: the start stands in, so the env runs; _info reports NaN
        return np.asarray(episode.start_position, np.float64).reshape(1, 3)

    @property
    def scored(self) -> bool:
        """Whether the episode has a goal (a test split's episodes have none and are not scored)."""
        return self.episode is not None and bool(self.episode.goals)

    def _distance(self, p32: np.ndarray) -> float:
        """d_t as habitat-lab v0.1.7's DistanceToGoal keeps it: recomputed only when the float32 position moved
        beyond ``np.allclose(previous, p, atol=1e-4)`` (:func:`navbench.metrics.habitat_distances`,
        incrementally); the geodesic is taken from the env's own position (rounded to float32, a position on
        a cell's edge could read as the cell beside it)."""
        if self._d_at is None or not np.allclose(self._d_at, p32, atol=1e-4):
            self._d_last = float(self._field.distance(self._position)) if self.scored else math.nan
            self._d_at = p32
        return self._d_last

    def _record_pose(self) -> None:
        t = self._track
        if self._num_steps == 0:  # reset: start the episode's track
            t["positions"], t["headings"], t["distances"] = [], [], []
            self._d_at, self._tl, self._oracle = None, 0.0, False
        elif len(t["positions"]) > self._num_steps:  # already recorded for this step
            return
        p32 = np.asarray(self._position, np.float32)
        if t["positions"]:
            self._tl += vlnce_step_length(t["positions"][-1], p32)
        d = self._distance(p32)
        self._oracle = self._oracle or d < self.success_distance
        t["positions"].append(p32)
        t["headings"].append(habitat_heading(quat_from_yaw(self._yaw)))
        t["distances"].append(d)

    def _info(self) -> dict[str, Any]:
        info = super()._info()
        self._record_pose()
        t = self._track
        nan = math.nan
        if self._done:
            gt = getattr(self.dataset, "gt_locations", None)
            assert self.episode is not None
            locs = gt.get(self.episode.episode_id) if gt is not None else None
            m = vlnce_episode_metrics(t["positions"], t["distances"], self._stop_called, locs, self.success_distance)
            stops = [False] * (len(t["positions"]) - 1) + [bool(self._stop_called)]
            info["vlnce_path"] = {"positions": [p.tolist() for p in t["positions"]], "headings": list(t["headings"]),
                                  "stop": stops}
            iid = self.episode.extra["instruction"].get("instruction_id")
            if iid is not None:  # RxR: what its leaderboard file is keyed by
                info["vlnce_path"]["instruction_id"] = int(iid)
        else:
            d = t["distances"][-1]
            m = {"distance_to_goal": d, "success": 0.0, "oracle_success": float(self._oracle), "spl": 0.0,
                 "path_length": self._tl, "steps_taken": float(self._num_steps), "ndtw": nan, "sdtw": nan,
                 "ndtw_exact": nan}
        if not self.scored:
            m = {k: nan if k != "steps_taken" and k != "path_length" else v for k, v in m.items()}
            info["geodesic_distance"] = info["soft_spl"] = nan
        info.update({k: m[k] for k in VLNCE_METRIC_KEYS})
        return info
