"""Baselines for VLN-CE (R2R-CE, RxR-CE).

- ``vln_random``: VLN-CE's ``RandomAgent`` (jacobkrantz/VLN-CE ``vlnce_baselines/nonlearning_agents.py``): each
  action drawn from the oracle action distribution of the R2R training set, STOP 0.02, MOVE_FORWARD 0.68,
  TURN_LEFT 0.15, TURN_RIGHT 0.15. Draws are seeded by the run's seed and the episode.
- ``vln_forward``: VLN-CE's ``HandcraftedAgent``, the forward-only baseline: a random number of right turns in
  [0, 24] (a random heading at R2R-CE's 15 degrees; the reference draws from ``360 / 15`` whatever the turn
  angle, and so does this), then 37 forward steps (9.25 m, the training set's mean oracle path), then STOP.
- ``vln_oracle``: follows the episode's ``reference_path`` (the viewpoints the instruction describes) waypoint
  by waypoint with navbench's geodesic follower, then stops within ``stop_radius`` of the last one; its nDTW
  is what following the described path, not only reaching its end, scores. Privileged: it reads the scene and
  its pose from GPS+compass (run it under ``navbench-r2r-ce`` / ``navbench-rxr-ce``).

None of them reads the instruction: they are the floor (random, forward) and the ceiling (oracle) of a split.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from navbench.agents.base import PoseTracker, episode_seed, xz_dist
from navbench.env.base import resolve_scene_path
from navbench.env.config import MOVE_FORWARD, STOP, TURN_LEFT, TURN_RIGHT, EnvConfig
from navbench.episodes.types import Episode
from navbench.scene.cache import load_scene_and_navgrid
from navbench.scene.follower import WaypointFollower
from navbench.scene.pose import quat_from_yaw

RANDOM_ACTIONS = (STOP, MOVE_FORWARD, TURN_LEFT, TURN_RIGHT)
RANDOM_PROBS = (0.02, 0.68, 0.15, 0.15)  # RandomAgent.probs
FORWARD_STEPS = 37  # HandcraftedAgent: "9.27m avg oracle path length in Train", 9.25 m / 0.25 m


class VLNRandomAgent:
    """VLN-CE's RandomAgent (module docstring)."""

    sensors: tuple[str, ...] = ()

    def __init__(self, seed: int = 0):
        self.seed = seed

    def reset(self, episode: Episode) -> None:
        self._rng = np.random.default_rng(episode_seed(self.seed, episode))

    def act(self, observations) -> int:
        return int(self._rng.choice(RANDOM_ACTIONS, p=RANDOM_PROBS))


class VLNForwardAgent:
    """VLN-CE's HandcraftedAgent (module docstring)."""

    sensors: tuple[str, ...] = ()

    def __init__(self, seed: int = 0):
        self.seed = seed

    def reset(self, episode: Episode) -> None:
        rng = np.random.default_rng(episode_seed(self.seed, episode))
        self.turns = int(rng.integers(0, int(360 / 15) + 1))  # np.random.randint(0, 360 / 15 + 1)
        self.forward_steps = FORWARD_STEPS

    def act(self, observations) -> int:
        if self.turns > 0:
            self.turns -= 1
            return TURN_RIGHT
        if self.forward_steps > 0:
            self.forward_steps -= 1
            return MOVE_FORWARD
        return STOP


class ReferencePathOracle:
    """Follows ``reference_path`` waypoint by waypoint (module docstring) with
    :class:`navbench.scene.follower.WaypointFollower`, stopping within ``stop_radius`` of its end."""

    sensors: tuple[str, ...] = ()  # privileged: needs no rendered observation

    def __init__(self, scene_dir: str | Path, env_config: EnvConfig = EnvConfig(), waypoint_radius: float = 0.5,
                 stop_radius: float = 0.5):
        self.scene_dir = Path(scene_dir)
        self.env_config = env_config
        self.nav_config = env_config.nav_grid_config()
        self.waypoint_radius, self.stop_radius = waypoint_radius, stop_radius
        self._pose = PoseTracker()
        self._grid_key: tuple | None = None
        self._grid = None

    def _navgrid(self, episode: Episode):
        path = resolve_scene_path(episode.scene_id, self.scene_dir)
        key = (path, round(float(episode.start_position[1]), 2))
        if key != self._grid_key:
            self._grid = load_scene_and_navgrid(path, self.nav_config, floor_hint=float(episode.start_position[1]))[1]
            self._grid_key = key
        return self._grid

    def reset(self, episode: Episode) -> None:
        self._pose.reset(episode)
        ref = episode.extra.get("reference_path") or []
        points = [np.asarray(p, np.float64) for p in ref[1:]]  # the first is the start
        if episode.goals:
            goal = np.asarray(episode.goals[0].position, np.float64)
            if not points or xz_dist(points[-1], goal) > 1e-6:
                points.append(goal)
        c = self.env_config
        self._follower = WaypointFollower(self._navgrid(episode), points, forward_step=c.forward_step,
                                          turn_angle_deg=c.turn_angle_deg, sliding=c.allow_sliding,
                                          waypoint_radius=self.waypoint_radius, stop_radius=self.stop_radius)

    def act(self, observations) -> int:
        position, yaw = self._pose(observations)
        return self._follower.next_action(position, quat_from_yaw(yaw))
