"""Gymnasium wrappers for training with RL libraries (Stable-Baselines3, TorchRL, CleanRL-style loops).

    import gymnasium as gym, navbench
    from navbench.env.wrappers import DepthUint8, HabitatReward, NumpyInfo
    env = NumpyInfo(HabitatReward(DepthUint8(gym.make("navbench/PointNav-v0"))))

- :class:`DepthUint8`: depth as a uint8 image (0-255), the only kind of image SB3's ``MultiInputPolicy``
  and ``CnnPolicy`` send through a CNN (float depth is flattened into a dense network, and SB3's
  ``check_env`` warns that it "is an image" of the wrong dtype).
- :class:`HabitatReward`: habitat-lab's PointNav reward (the env's own reward is always 0).
- :class:`NumpyInfo`: ``info`` numbers as numpy scalars, which TorchRL's ``default_info_dict_reader``
  needs (it reads ``val.dtype``); strings (``episode_id``, ``scene_id``) are left out.

The env itself is unchanged by these: evaluation (``navbench run``) never uses them.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces


class DepthUint8(gym.ObservationWrapper):
    """``depth`` as ``Box(0, 255, (H, W, 1), uint8)``: the normalised depth times 255, rounded. Needs the
    env's default ``normalize_depth=True`` (depth in [0, 1]); a library that divides images by 255 gets
    the normalised depth back, to 1/255 (2 cm over the 0.5-5 m range)."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        space = env.observation_space
        if not isinstance(space, spaces.Dict) or "depth" not in space.spaces:
            raise ValueError("DepthUint8: the env renders no depth (EnvConfig(depth=True))")
        depth = space.spaces["depth"]
        if not isinstance(depth, spaces.Box) or not (np.all(depth.low == 0) and np.all(depth.high == 1)):
            raise ValueError("DepthUint8: depth is not normalised to [0, 1] (EnvConfig(normalize_depth=True))")
        self.observation_space = spaces.Dict({**space.spaces, "depth": spaces.Box(0, 255, depth.shape, np.uint8)})

    def observation(self, observation: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        d = np.clip(observation["depth"], 0.0, 1.0)
        return {**observation, "depth": np.rint(d * 255.0).astype(np.uint8)}


class HabitatReward(gym.Wrapper):
    """habitat-lab's PointNav reward: the decrease of the geodesic distance to the goal, plus
    ``slack_reward`` every step, plus ``success_reward`` on a successful STOP (habitat-lab's defaults
    2.5 and -0.01, as navbench's own PPO trainer)."""

    def __init__(self, env: gym.Env, success_reward: float = 2.5, slack_reward: float = -0.01):
        super().__init__(env)
        self.success_reward, self.slack_reward = float(success_reward), float(slack_reward)
        self._distance = 0.0

    def reset(self, **kwargs: Any):
        obs, info = self.env.reset(**kwargs)
        self._distance = float(info["distance_to_goal"])
        return obs, info

    def step(self, action: Any):
        obs, _, terminated, truncated, info = self.env.step(action)
        d = float(info["distance_to_goal"])
        reward = self._distance - d + self.slack_reward + (self.success_reward if info["success"] else 0.0)
        self._distance = d
        return obs, reward, terminated, truncated, info


def numpy_info(info: dict[str, Any]) -> dict[str, Any]:
    """``info`` with bools, ints and floats as numpy scalars and strings left out."""
    out: dict[str, Any] = {}
    for k, v in info.items():
        if isinstance(v, (bool, np.bool_)):
            out[k] = np.bool_(v)
        elif isinstance(v, (int, np.integer)):
            out[k] = np.int64(v)
        elif isinstance(v, (float, np.floating)):
            out[k] = np.float32(v)
        elif isinstance(v, np.ndarray):
            out[k] = v
    return out


class NumpyInfo(gym.Wrapper):
    """``info`` as :func:`numpy_info` makes it, for TorchRL's ``default_info_dict_reader``."""

    def reset(self, **kwargs: Any):
        obs, info = self.env.reset(**kwargs)
        return obs, numpy_info(info)

    def step(self, action: Any):
        obs, reward, terminated, truncated, info = self.env.step(action)
        return obs, reward, terminated, truncated, numpy_info(info)
