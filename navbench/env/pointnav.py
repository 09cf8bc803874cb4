"""``navbench/PointNav-v0``: drive to a goal given as a polar offset from the agent.

Run it::

    import gymnasium as gym, navbench
    env = gym.make("navbench/PointNav-v0")            # bundled PointNav val split
    obs, info = env.reset(seed=0)
    obs, reward, terminated, truncated, info = env.step(1)   # MOVE_FORWARD
"""

from __future__ import annotations

from pathlib import Path

from navbench.env.base import NavEnv
from navbench.env.config import EnvConfig
from navbench.episodes.types import EpisodeDataset


class PointNavEnv(NavEnv):
    """Point-goal navigation with Habitat's conventions (y up, the agent faces -z, quaternions [x,y,z,w]).

    ## Action space
    ``Discrete(4)``: 0 STOP (ends the episode), 1 MOVE_FORWARD (``forward_step`` = 0.25 m; motion is
    checked against the navigability grid: without sliding the agent stops where the segment leaves
    the navigable area and a collision is counted), 2 TURN_LEFT and 3 TURN_RIGHT (``turn_angle_deg`` = 30,
    left = counter-clockwise seen from above). An ``EnvConfig`` may list Habitat's six actions
    (``actions``): 4 LOOK_UP and 5 LOOK_DOWN then tilt the camera by ``tilt_angle_deg`` about its x axis,
    without limit, as habitat-lab does; the images are rendered at that pitch and nothing moves.

    ## Observation space (``Dict``)
    - ``rgb``: ``Box(0, 255, (H, W, 3), uint8)`` pinhole camera, HFOV 79 deg, 0.88 m above the floor.
    - ``depth``: ``Box(0, 1, (H, W, 1), float32)`` linear depth clipped to [0.5, 5.0] m and normalised
      (raw metres with ``normalize_depth=False``).
    - ``semantic`` (only with ``EnvConfig(semantic=True)``): instance ids, -1 for structure.
    - ``gps``: ``(2,) float32`` position relative to the start, in the start frame: [forward, right].
    - ``compass``: ``(1,) float32`` heading relative to the start, radians, counter-clockwise positive.
    - ``pointgoal_with_gps_compass``: ``(2,) float32`` [rho, theta] of the goal in the agent frame,
      theta counter-clockwise positive (Habitat's polar convention).
    - With ``EnvConfig(gps_compass=False)`` (Habitat's PointNav challenges): no ``gps``/``compass``, and
      ``pointgoal`` instead: [rho, theta] of the goal from the episode's start pose, the same every step.
    - Realistic conditions (``EnvConfig`` actuation, depth and RGB noise, camera pitch): docs/realistic.md.

    ## Rewards
    Always 0: navbench is an evaluation harness; training code shapes its own reward from ``info``.

    ## Episode end
    Terminated when STOP is called; truncated after ``max_steps`` (500) actions. Success = STOP with
    the geodesic distance to the goal < ``success_distance`` (0.2 m by default).

    ## Info
    ``distance_to_goal`` (geodesic, m), ``success``, ``spl``, ``soft_spl``, ``num_steps``, ``collisions``,
    ``path_length``, ``stop_called``, ``geodesic_distance`` (d0), ``episode_id``, ``scene_id``.

    ## Arguments
    - ``dataset``: a Habitat PointNav-v1 ``.json(.gz)`` path or an :class:`EpisodeDataset`
      (default: the bundled ``val`` split).
    - ``scene_dir``: where episode ``scene_id`` paths are resolved (default: the bundled ``envs/``).
    - ``config``: :class:`navbench.env.config.EnvConfig` (sensors, agent, limits).
    - ``render_mode``: ``None`` or ``"rgb_array"``.

    ``reset(seed=s)`` draws an episode with the env's seeded generator; ``reset(options={"episode": e})``
    runs a given episode (an ``Episode``, an episode id, or an index).

    The goal sensors, success distance, step limit and default split are the ``pointnav`` task's
    (:mod:`navbench.tasks.pointnav`).

    ## Version history
    - v0: initial release.
    """

    task = "pointnav"

    def __init__(self, dataset: str | Path | EpisodeDataset | None = None, scene_dir: str | Path | None = None,
                 config: EnvConfig | None = None, render_mode: str | None = None, task: str | None = None):
        super().__init__(dataset, scene_dir, config, render_mode, task)

    @property
    def goal_sensor(self) -> str:
        """``pointgoal_with_gps_compass`` (the goal from where the agent is), or without GPS+compass
        Habitat's static ``pointgoal`` (the goal from the start pose, the same every step)."""
        return self.task_def.goal_sensor_uuid(self.config)
