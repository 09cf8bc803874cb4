"""Habitat's episodic pose sensors and their inverse, as plain functions of (position, yaw).

Yaw is the rotation about +y; at yaw 0 the agent faces -z, and positive yaw turns it left
(counter-clockwise seen from above).
"""

from __future__ import annotations

import math

import numpy as np

# to_agent_frame and pointgoal_polar live with the other pose geometry (task goal sensors read them there)
from navbench.scene.pose import pointgoal_polar, to_agent_frame, wrap_angle  # noqa: F401

# The privileged pose observation (NavEnv.give_agent_pose): a privileged agent lists it in its ``sensors``.
AGENT_POSE = "agent_pose"


def from_agent_frame(forward: float, right: float, yaw: float) -> np.ndarray:
    """Inverse of :func:`to_agent_frame`: (forward, right) -> world xz offset as a 3-vector (y = 0)."""
    c, s = math.cos(yaw), math.sin(yaw)
    x, z = right, -forward
    return np.array([c * x + s * z, 0.0, -s * x + c * z])


def gps(position: np.ndarray, start_position: np.ndarray, start_yaw: float) -> np.ndarray:
    """Habitat's 2-D EpisodicGPSSensor: [forward, right] of the agent in the start frame."""
    return np.array(to_agent_frame(np.asarray(position) - np.asarray(start_position), start_yaw), np.float32)


def compass(yaw: float, start_yaw: float) -> np.ndarray:
    return np.array([wrap_angle(yaw - start_yaw)], np.float32)


def world_pose(gps_obs: np.ndarray, compass_obs: np.ndarray, start_position: np.ndarray,
               start_yaw: float) -> tuple[np.ndarray, float]:
    """World (position, yaw) from GPS+compass and the episode's start pose, as Habitat agents recover it.
    The returned position is on the start's floor level (y of the start)."""
    offset = from_agent_frame(float(gps_obs[0]), float(gps_obs[1]), start_yaw)
    return np.asarray(start_position, np.float64) + offset, wrap_angle(start_yaw + float(compass_obs[0]))


def normalize_depth(depth_m: np.ndarray, min_depth: float, max_depth: float, normalized: bool) -> np.ndarray:
    """Rendered linear depth in metres (H, W) -> the depth sensor's (H, W, 1) float32 observation.

    Habitat's DepthSensor: clip to [min, max] (so "nothing hit" = 0 becomes min), then optionally
    normalise to [0, 1]."""
    d = np.clip(depth_m, min_depth, max_depth)
    if normalized:
        d = (d - min_depth) / (max_depth - min_depth)
    return d.astype(np.float32)[..., None]


def depth_metres(depth_obs: np.ndarray, min_depth: float, max_depth: float, normalized: bool) -> np.ndarray:
    """The depth sensor's (H, W, 1) observation back in metres (H, W), float64. Pixels the sensor
    clipped to the minimum (nothing measured, or nearer than ``min_depth``) come back as ``min_depth``."""
    d = depth_obs[..., 0].astype(np.float64)
    return d * (max_depth - min_depth) + min_depth if normalized else d
