"""navbench's agent protocol: ``reset(episode)`` once per episode, then ``act(observations)`` -> action id
per step. Agents written for Habitat's ``habitat.Agent`` (``reset()`` without the episode, ``act`` returning
an id, an action name or ``{"action": ...}``) run unchanged through :mod:`navbench.agents.habitat_compat`.

An agent may also expose ``sensors`` (which rendered observations it needs, so the evaluator can skip
rendering the rest; default RGB and depth) and ``episode_log()`` (decisions to record in
``episodes.jsonl``). Both are optional, for single and batched agents alike, so neither is a member of
the protocols below.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Sequence
from typing import Any, Protocol, cast, runtime_checkable

import numpy as np

from navbench.env.sensors import AGENT_POSE, world_pose
from navbench.episodes.types import Episode
from navbench.scene.pose import yaw_from_quat


@runtime_checkable
class Agent(Protocol):
    """One episode at a time: ``reset(episode)``, then ``act(observations)`` returns an action
    (:class:`navbench.env.config.Action`, or its int). Optional: ``sensors``, a subset of ("rgb",
    "depth", "semantic"), and ``episode_log()``."""

    def reset(self, episode: Episode) -> None: ...

    def act(self, observations: dict[str, np.ndarray]) -> int: ...


@runtime_checkable
class BatchAgent(Protocol):
    """An agent that acts for ``num_envs`` episodes at once (one forward pass of its network for all):
    ``reset_env(i, episode)`` starts an episode in slot ``i``; ``act_batch`` takes one observation
    dict per slot (None for a slot without an episode) and returns per slot an action, or the
    exception that ends that slot's episode as failed. ``num_envs`` is optional (default 1), as are
    ``sensors`` and ``slot(i)``, the object whose ``episode_log()`` and ``decision()`` describe slot
    ``i``'s episode."""

    def reset_env(self, i: int, episode: Episode) -> None: ...

    def act_batch(self, observations: list[dict[str, np.ndarray] | None]) -> Sequence[int | BaseException]: ...


def is_batch_agent(agent: Any) -> bool:
    """Whether ``agent`` steps episodes in batches (has ``reset_env`` and ``act_batch``); what it declares
    beyond those (``num_envs``, ``sensors``) does not matter.

    >>> class Batched:
    ...     def reset_env(self, i, episode): pass
    ...     def act_batch(self, observations): return [1 for _ in observations]
    >>> is_batch_agent(Batched()), isinstance(Batched(), BatchAgent)
    (True, True)
    """
    return callable(getattr(agent, "reset_env", None)) and callable(getattr(agent, "act_batch", None))


def episode_seed(seed: int, episode: Episode) -> list[int]:
    """A generator seed for one episode's draws: from the run's seed and the episode, not from the worker,
    slot or order the episode runs in, so a run's records do not depend on how it is split up."""
    return [seed, zlib.crc32(f"{episode.scene_id}:{episode.episode_id}".encode())]


def slot_agent(agent: BatchAgent, i: int) -> Any:
    """What describes slot ``i``'s episode of a batched agent (its ``slot(i)``), or None."""
    slot = getattr(agent, "slot", None)
    return slot(i) if callable(slot) else None


def episode_log(agent: Agent) -> dict[str, Any]:
    log = getattr(agent, "episode_log", None)
    return cast("dict[str, Any]", log()) if callable(log) else {}


class PoseTracker:
    """World pose from the episode's start pose plus GPS+compass, the way Habitat agents know it; for a
    privileged agent (one that lists ``agent_pose`` in its ``sensors``), plus the simulator's pose in the same
    start frame (:meth:`navbench.env.base.NavEnv.give_agent_pose`), under any configuration."""

    def reset(self, episode: Episode) -> None:
        self.start_position = np.asarray(episode.start_position, np.float64)
        self.start_yaw = yaw_from_quat(np.asarray(episode.start_rotation, np.float64))

    def __call__(self, observations: dict[str, np.ndarray]) -> tuple[np.ndarray, float]:
        pose = observations.get(AGENT_POSE)
        if pose is not None:
            return world_pose(pose[:2], pose[2:], self.start_position, self.start_yaw)
        return world_pose(observations["gps"], observations["compass"], self.start_position, self.start_yaw)


def xz_dist(a: np.ndarray, b: np.ndarray) -> float:
    """Distance in the floor plane (navigation thresholds are all measured in xz)."""
    return math.hypot(float(a[0] - b[0]), float(a[2] - b[2]))


def xz_dists(points: np.ndarray, p: np.ndarray) -> np.ndarray:
    return np.hypot(points[:, 0] - p[0], points[:, 2] - p[2])


def log_value(v: Any) -> Any:
    """A decision-log value as compact JSON: floats and arrays rounded to millimetres."""
    if isinstance(v, (float, np.floating)):
        return round(float(v), 3)
    if isinstance(v, np.ndarray):
        return [round(float(x), 3) for x in v.ravel()]
    return v


def fov_leave_distance(point: np.ndarray, camera_height: float, tan_half_vfov: float) -> float:
    """xz distance below which ``point`` is above or below the camera's vertical field of view."""
    return abs(float(point[1]) - camera_height) / tan_half_vfov


def nearest_to_height(points: np.ndarray, height: float) -> np.ndarray:
    """The point of a target's cloud whose height is closest to ``height`` (the camera's): the part of
    the target the camera keeps in view longest as it closes in."""
    return points[int(np.argmin(np.abs(points[:, 1] - height)))]


def fov_stop_radius(target: np.ndarray, stop_radius: float, margin: float, camera_height: float,
                    tan_half_vfov: float) -> float:
    """STOP radius (xz) for a target whose point nearest the camera's height is ``target``:
    ``stop_radius``, grown for a target so far above or below the camera that it leaves the vertical
    field of view closer than that (a rug, a picture high on a wall) to the distance where it leaves
    the view plus ``margin``. Within a plain 0.9 m radius such a target could never pass a visibility
    test; the episodes' view points (cells that see the object) lie outside it too. Taking the
    target's point nearest the camera height, not the goal point (the nearest in xz, which may be a
    picture's top edge or a fridge's top), keeps the radius as small as the target allows."""
    return max(stop_radius, fov_leave_distance(target, camera_height, tan_half_vfov) + margin)
