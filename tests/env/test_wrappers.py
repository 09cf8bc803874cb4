"""The RL-library wrappers: uint8 depth for SB3's image path, habitat-lab's reward, numpy info for TorchRL."""

import gymnasium as gym
import numpy as np
import pytest

import navbench  # noqa: F401
from navbench.env.config import EnvConfig
from navbench.env.wrappers import DepthUint8, HabitatReward, NumpyInfo, numpy_info


@pytest.fixture
def env():
    env = gym.make("navbench/PointNav-v0", config=EnvConfig(rgb=False, width=32, height=32))  # bundled val
    yield env
    env.close()


def test_depth_uint8_is_the_normalised_depth_times_255(env):
    wrapped = DepthUint8(env)
    space = wrapped.observation_space["depth"]
    assert space.dtype == np.uint8 and space.shape == (32, 32, 1) and space.high.max() == 255
    obs, _ = wrapped.reset(seed=0)
    assert obs["depth"].dtype == np.uint8 and obs["depth"] in space and obs["depth"].max() > 0
    again, _ = env.reset(seed=0)  # the same episode, unwrapped
    assert np.abs(obs["depth"].astype(np.float32) / 255 - again["depth"]).max() <= 0.5 / 255 + 1e-6
    assert {k: v.dtype for k, v in obs.items() if k != "depth"} == {k: v.dtype for k, v in again.items()
                                                                    if k != "depth"}


def test_depth_uint8_refuses_raw_metres():
    env = gym.make("navbench/PointNav-v0", config=EnvConfig(rgb=False, normalize_depth=False, width=32, height=32))
    with pytest.raises(ValueError, match="normalize_depth=True"):
        DepthUint8(env)


def test_sb3_takes_uint8_depth_as_an_image(env):
    pytest.importorskip("stable_baselines3")
    from stable_baselines3.common.preprocessing import is_image_space
    assert is_image_space(DepthUint8(env).observation_space["depth"])
    assert not is_image_space(env.observation_space["depth"])


def test_habitat_reward_is_progress_plus_slack_plus_success(env):
    wrapped = HabitatReward(env, success_reward=2.5, slack_reward=-0.01)
    _, info = wrapped.reset(seed=0)
    d0 = info["distance_to_goal"]
    _, reward, _, _, info = wrapped.step(1)
    assert reward == pytest.approx(d0 - info["distance_to_goal"] - 0.01)
    _, reward, terminated, _, info = wrapped.step(0)  # STOP away from the goal: no bonus
    assert terminated and not info["success"] and reward == pytest.approx(-0.01)


def test_numpy_info_has_numpy_scalars_and_no_strings(env):
    _, info = NumpyInfo(env).reset(seed=0)
    assert "episode_id" not in info and "scene_id" not in info and info
    assert all(isinstance(v, (np.generic, np.ndarray)) for v in info.values())
    assert numpy_info({"a": True, "b": 3, "c": 0.5, "s": "x"}) == {"a": np.bool_(True), "b": 3, "c": 0.5}


def test_torchrl_default_info_reader_reads_numpy_info(env):
    pytest.importorskip("torchrl")
    from torchrl.envs import GymWrapper
    from torchrl.envs.libs.gym import default_info_dict_reader
    keys = ["success", "spl", "distance_to_goal"]
    with pytest.raises(AttributeError):  # plain Python numbers: the reader needs .dtype
        GymWrapper(env).set_info_dict_reader(default_info_dict_reader(keys)).rollout(2)
    td = GymWrapper(NumpyInfo(env)).set_info_dict_reader(default_info_dict_reader(keys)).rollout(2)
    assert td["next", "distance_to_goal"].shape[0] == td.batch_size[0] and td["next", "distance_to_goal"].min() > 0
