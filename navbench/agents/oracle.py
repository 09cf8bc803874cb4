"""``oracle``: follows the geodesic shortest path to the nearest goal and stops inside the success
distance, like Habitat's ShortestPathFollower (on a GOAT-Bench episode, to each subtask's goals in turn,
closing each with SUBTASK_STOP). Its SR/SPL are the ceiling a benchmark split allows;
if they are low, the geodesics, view points or motion model are wrong. Both oracles are privileged: they read the
simulator's pose (``agent_pose``, :meth:`navbench.env.base.NavEnv.give_agent_pose`) as habitat-lab's
ShortestPathFollower reads ``sim.get_agent_state()``, so they run under configurations without GPS+compass too.

``optimistic``: the same follower planning on the map its own depth frames have shown it (unseen
cells count as free; :mod:`navbench.scene.optimistic`), on the start's storey or, for a goal on another
storey the env joins to it, on every storey over the stairs and ramps between them. It knows where the
goal is and what it has seen, which is what a PointNav policy can know, so its SR/SPL are the ceiling
for a learner that imitates well: the distance between the two oracles is what knowing the map is worth.

    navbench run --task pointnav --split val --agent optimistic
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from navbench.agents.base import PoseTracker
from navbench.env.base import resolve_scene_path
from navbench.env.config import EnvConfig
from navbench.env.sensors import AGENT_POSE
from navbench.episodes.goat import SUBTASK_STOP, GoatEpisode
from navbench.episodes.types import Episode
from navbench.scene.asset import load_scene
from navbench.scene.cache import layers_for, load_scene_and_navgrid
from navbench.scene.follower import GreedyFollower
from navbench.scene.layers import LayeredNav, LayerView
from navbench.scene.optimistic import LayeredOptimisticFollower, OptimisticFollower
from navbench.scene.pose import quat_from_yaw


class OracleAgent:
    sensors: tuple[str, ...] = (AGENT_POSE,)  # privileged: the simulator's pose, no rendered observation

    def __init__(self, scene_dir: str | Path, success_distance: float, env_config: EnvConfig = EnvConfig()):
        self.scene_dir = Path(scene_dir)
        self.success_distance = success_distance
        self.env_config = env_config
        self.nav_config = env_config.nav_grid_config()
        self._pose = PoseTracker()
        self._grids: dict[tuple[Path, float], object] = {}
        self._layered: tuple[Path, LayeredNav] | None = None
        self._view: LayerView | None = None

    def _navgrid(self, episode: Episode):
        path = resolve_scene_path(episode.scene_id, self.scene_dir)
        key = (path, round(float(episode.start_position[1]), 2))
        if key not in self._grids:  # keep one scene; on a multi-storey scan, the grid of the start's storey
            self._grids = {key: load_scene_and_navgrid(path, self.nav_config,
                                                       floor_hint=float(episode.start_position[1]))[1]}
        return self._grids[key]

    def _motion(self, episode: Episode):
        """The start storey's grid, or, when a goal is on another storey, the scene's joined surfaces (as the
        env moves such an episode on them)."""
        grid = self._navgrid(episode)
        self._view = None
        goals = np.concatenate(_goal_sets(episode), axis=0)
        off = ~grid.on_storey(goals)
        if not off.any():
            return grid
        path = resolve_scene_path(episode.scene_id, self.scene_dir)
        if self._layered is None or self._layered[0] != path:
            self._layered = (path, layers_for(load_scene(path), self.nav_config))
        if not self._layered[1].reaches_any(episode.start_position, goals[off]):
            return grid
        self._view = LayerView(self._layered[1], episode.start_position)
        return self._view

    def reset(self, episode: Episode) -> None:
        self._pose.reset(episode)
        # one goal set per subtask: GOAT-Bench's subtasks in turn, each closed with SUBTASK_STOP (6)
        self._goal_sets = _goal_sets(episode)
        self._subtask_stop = isinstance(episode, GoatEpisode)
        self._k = 0
        self._motion_now = self._motion(episode)
        self._follow(0)

    def _follow(self, k: int) -> None:
        self._follower = GreedyFollower(self._motion_now, self._goal_sets[k], self.success_distance,
                                        forward_step=self.env_config.forward_step,
                                        turn_angle_deg=self.env_config.turn_angle_deg)

    def act(self, observations: dict[str, np.ndarray]) -> int:
        position, yaw = self._pose(observations)
        if self._view is not None:
            self._view.track(position)
        action = int(self._follower.next_action(position, quat_from_yaw(yaw)))
        if action == 0 and self._subtask_stop:
            self._k += 1
            if self._k < len(self._goal_sets):
                self._follow(self._k)
            return SUBTASK_STOP
        return action


def _goal_sets(episode: Episode) -> list[np.ndarray]:
    """The goal points of each of the episode's subtasks: one set, or a GOAT-Bench episode's, in order."""
    if isinstance(episode, GoatEpisode):
        return [episode.subtask_goal_positions(k) for k in range(episode.num_goals)]
    return [episode.goal_positions()]


class OptimisticOracleAgent(OracleAgent):
    sensors: tuple[str, ...] = ("depth", AGENT_POSE)  # what it has seen is the map it plans on

    def reset(self, episode: Episode) -> None:
        self._pose.reset(episode)
        c = self.env_config
        motion = self._motion(episode)  # the start storey's grid, or the joined storeys for a goal upstairs
        follower = LayeredOptimisticFollower if isinstance(motion, LayerView) else OptimisticFollower
        self._follower = follower(motion, episode.goal_positions(), self.success_distance,  # type: ignore[arg-type]
                                  c.hfov_deg, c.min_depth, c.max_depth, forward_step=c.forward_step,
                                  turn_angle_deg=c.turn_angle_deg)

    def act(self, observations: dict[str, np.ndarray]) -> int:
        position, yaw = self._pose(observations)
        if self._view is not None:
            self._view.track(position)
        self._follower.observe(observations["depth"], position, yaw)
        return int(self._follower.next_action(position, quat_from_yaw(yaw)))
