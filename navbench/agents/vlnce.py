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
  the simulator's pose (``agent_pose``), so it runs under ``r2r-ce`` / ``rxr-ce`` as under their GPS+compass
  variants.

- ``vln_memory``: memory over maps for instructions (:class:`InstructionMemoryAgent`): the instruction's final
  landmark, in the room the route enters, localised in the pre-scan memory and driven to with the PointNav
  policy; without GPS+compass (VLN-CE's own configurations) it knows its pose from its actions and depth.

The first three do not read the instruction: they are the floor (random, forward) and the ceiling (oracle).
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path
from typing import Any

import numpy as np

from navbench.agents.base import PoseTracker, episode_seed, xz_dist
from navbench.agents.odometry import DepthOdometry
from navbench.env.base import resolve_scene_path
from navbench.env.config import MOVE_FORWARD, STOP, TURN_LEFT, TURN_RIGHT, EnvConfig
from navbench.env.sensors import AGENT_POSE
from navbench.episodes.types import Episode
from navbench.localize.describe import phrase
from navbench.scene.cache import load_scene_and_navgrid
from navbench.scene.follower import WaypointFollower
from navbench.scene.pose import quat_from_yaw
from navbench.scene.procedural.furniture import ROOM_TYPES

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

    sensors: tuple[str, ...] = (AGENT_POSE,)  # privileged: the simulator's pose, no rendered observation

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


# ------------------------------------------------------------------------------ memory over maps, for instructions
INSTRUCTION_SCOPES = ("full", "last")  # what of the instruction vln_memory reads (its ``instruction`` option)
_ROOMS = sorted((phrase(r) for r in ROOM_TYPES), key=len, reverse=True)
_LEFT = re.compile(r"\b(leave|exit|out of)$")  # a room named after these is the one the route leaves


def _words(text: str) -> str:
    return " ".join(re.sub(r"[^a-z ]", " ", str(text).lower()).split())


def _last_landmark(sentence: str) -> str:
    """A sentence's last "the ..." phrase, with its "in the <room>" when it has one: "stop next to the pink plant
    in the kitchen" -> "the pink plant in the kitchen"; "" when there is none."""
    t = " " + _words(sentence)
    head, sep, room = t.rpartition(" in the ")
    if sep and room and " the " in head:
        return f"the {head.rsplit(' the ', 1)[1]} in the {room}"
    return "the " + t.rsplit(" the ", 1)[1] if " the " in t else ""


def _entered_room(text: str) -> str | None:
    """The last room the text names that the route does not leave ("Leave the bedroom. Enter the kitchen." ->
    "kitchen"), in the room words of ``navbench localize``'s descriptions; None when it names none."""
    t = " " + _words(text) + " "
    best: tuple[int, str] | None = None
    for room in _ROOMS:
        for m in re.finditer(f" the {room} ", t):
            if not _LEFT.search(t[:m.start()].rstrip()) and (best is None or m.start() > best[0]):
                best = (m.start(), room)
    return None if best is None else best[1]


def instruction_goal(text: str, scope: str = "full") -> str:
    """The final landmark of an instruction as a description ``navbench localize``'s language queries take: the
    last sentence's last "the ..." phrase; with ``scope`` "full", placed in the last room the instruction enters
    when the phrase names none ("... Enter the kitchen. Stop next to the plant." -> "the plant in the kitchen");
    with "last", the last sentence alone ("the plant"). "" when there is no landmark."""
    if scope not in INSTRUCTION_SCOPES:
        raise ValueError(f"unknown instruction scope {scope!r}: choose from {', '.join(INSTRUCTION_SCOPES)}")
    sentences = [x for x in re.split(r"[.!?;]", str(text)) if x.strip()]
    landmark = _last_landmark(sentences[-1]) if sentences else ""
    if scope == "last" or not landmark or " in the " in landmark:
        return landmark
    room = _entered_room(text)
    return f"{landmark} in the {room}" if room else landmark


class InstructionMemoryAgent:
    """Memory over maps for instructions: the instruction's final landmark (:func:`instruction_goal`; ``scope``
    "last" reads the last sentence only, the ablation) localised in the scene's pre-scan keyframe memory, as
    ``navbench localize`` localises a language query, then driven to with the PointNav policy by the ObjectNav
    memory agent (:mod:`navbench.agents.memory_agent`), which stops by it. An honest, simple baseline: of the
    route it reads only the room the route enters, which tells the final landmark from others of its kind; its
    nDTW reflects how far the shortest way there happens to follow the instruction's.

    Its pose starts at the episode's start pose (the frame the pre-scan memory is in; the project's agents take
    it from the episode, see :class:`~navbench.agents.base.PoseTracker`). Under a configuration with GPS+compass
    it reads them; without (``r2r-ce``, ``rxr-ce``, as VLN-CE defines the task) it knows its pose from its own
    actions and depth alone: :class:`~navbench.agents.odometry.DepthOdometry` takes each turn as exact and measures
    each forward step (which may stop at a wall or slide along it) from depth."""

    def __init__(self, inner: Any, env_config: EnvConfig | None = None, scope: str = "full"):
        if scope not in INSTRUCTION_SCOPES:
            raise ValueError(f"unknown instruction scope {scope!r}: choose from {', '.join(INSTRUCTION_SCOPES)}")
        self.inner, self.scope = inner, scope
        self.sensors = tuple(getattr(inner, "sensors", ()))
        self.goal_text = ""
        self.odometry: DepthOdometry | None = None
        if env_config is not None and not env_config.gps_compass:
            self.odometry = DepthOdometry(env_config)
            inner._pose = self.odometry  # the memory agent reads its pose here each step

    def reset(self, episode: Episode) -> None:
        ins = episode.extra.get("instruction") or {}
        self.goal_text = instruction_goal(ins.get("instruction_text", ""), self.scope)
        self.inner.reset(dataclasses.replace(episode, object_category=self.goal_text or "object", goals=[]))

    def act(self, observations) -> int:
        action = int(self.inner.act(observations))
        if self.odometry is not None:
            self.odometry.note(action)
        return action

    def __getattr__(self, name: str) -> Any:  # the inner agent's log and decision, for the run's records
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)
