"""``navbench/ObjectNav-v0``: find any instance of a named object category.

Run it::

    import gymnasium as gym, navbench
    env = gym.make("navbench/ObjectNav-v0")           # bundled ObjectNav val_seen split
    obs, info = env.reset(seed=0)
    env.unwrapped.episode.object_category             # e.g. "chair"
"""

from __future__ import annotations

from pathlib import Path

from navbench.env.base import NavEnv
from navbench.env.config import EnvConfig
from navbench.episodes.types import EpisodeDataset


class ObjectNavEnv(NavEnv):
    """Object-goal navigation (Habitat ObjectNav-v1 semantics).

    ## Action space
    As :class:`navbench.env.pointnav.PointNavEnv`: ``Discrete(4)`` STOP, MOVE_FORWARD, TURN_LEFT, TURN_RIGHT;
    under a configuration with Habitat's HM3D ObjectNav actions (``EnvConfig.load("habitat-objectnav-hm3d")``)
    ``Discrete(6)``, adding 4 LOOK_UP and 5 LOOK_DOWN (the camera tilts by ``tilt_angle_deg`` = 30).

    ## Observation space (``Dict``)
    ``rgb``, ``depth``, optional ``semantic``, ``gps``, ``compass`` as in PointNav, plus
    ``objectgoal``: ``Box(0, C-1, (1,), int64)`` the goal category's id in the dataset's
    ``category_to_task_category_id``. There is no point-goal sensor: the goal must be found.

    ## Episode end and success
    Terminated by STOP, truncated after ``max_steps`` (500). Success = STOP with the geodesic distance
    to the nearest view point of any goal instance < ``success_distance`` (0.1 m, Habitat's HM3D
    ObjectNav value; navbench's OVON-style splits are evaluated at 0.25 m by ``navbench run``).
    Distance-to-goal and SPL are measured to view points, as Habitat does.

    ## Arguments
    ``dataset`` (ObjectNav-v1 file or :class:`EpisodeDataset`; default: bundled ``val_seen``),
    ``scene_dir``, ``config``, ``render_mode`` as for PointNav.

    The goal sensor, success distance, step limit and default split are the ``objectnav`` task's
    (:mod:`navbench.tasks.objectnav`).

    ## Version history
    - v0: initial release.
    """

    task = "objectnav"

    def __init__(self, dataset: str | Path | EpisodeDataset | None = None, scene_dir: str | Path | None = None,
                 config: EnvConfig | None = None, render_mode: str | None = None, task: str | None = None):
        super().__init__(dataset, scene_dir, config, render_mode, task)
