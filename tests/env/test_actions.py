"""Habitat's ObjectNav action space (STOP, MOVE_FORWARD, TURN_LEFT, TURN_RIGHT, LOOK_UP, LOOK_DOWN) under the
``habitat-objectnav-hm3d`` configuration: the camera tilts, the renderer renders at that pitch, and agents
written for Habitat that look down and up run unchanged."""

import dataclasses
import json

import gymnasium as gym
import numpy as np
import pytest

import navbench
from navbench.env.config import EnvConfig
from navbench.eval.provenance import config_protocol
from navbench.eval.rundir import RunError

LOOK_UP, LOOK_DOWN = 4, 5


def _hm3d(**kw) -> EnvConfig:
    # the configuration at a smaller image, so the test renders quickly (the pitch is what is checked)
    return dataclasses.replace(EnvConfig.load("habitat-objectnav-hm3d"), width=96, height=72, **kw)


def test_the_named_configuration_is_habitats_objectnav_hm3d():
    c = EnvConfig.load("habitat-objectnav-hm3d")
    assert c.actions == ("STOP", "MOVE_FORWARD", "TURN_LEFT", "TURN_RIGHT", "LOOK_UP", "LOOK_DOWN")
    assert (c.tilt_angle_deg, c.turn_angle_deg, c.forward_step, c.max_steps, c.success_distance) == \
        (30.0, 30.0, 0.25, 500, 0.1)
    assert (c.width, c.height, c.hfov_deg, c.min_depth, c.max_depth, c.agent_height, c.agent_radius) == \
        (640, 480, 79.0, 0.5, 5.0, 0.88, 0.18)
    assert EnvConfig().actions is None  # navbench's own splits keep the task's four actions


def test_look_down_changes_the_depth_image_and_look_up_restores_it(objectnav_file):
    env = gym.make("navbench/ObjectNav-v0", dataset=objectnav_file, config=_hm3d(rgb=False))
    assert env.action_space.n == 6
    level, _ = env.reset(seed=0, options={"episode": 0})
    down, *_ = env.step(LOOK_DOWN)
    assert env.unwrapped.camera_tilt_deg == -30.0
    # looking 30 deg down at a floor 0.88 m below: the lower rows see the floor nearer than they did level
    assert not np.array_equal(down["depth"], level["depth"])
    rows = level["depth"].shape[0]
    assert down["depth"][rows // 2:].mean() < level["depth"][rows // 2:].mean()
    up, *_ = env.step(LOOK_UP)
    assert env.unwrapped.camera_tilt_deg == 0.0 and np.array_equal(up["depth"], level["depth"])
    up2, *_ = env.step(LOOK_UP)
    assert env.unwrapped.camera_tilt_deg == 30.0 and not np.array_equal(up2["depth"], level["depth"])
    pos = env.unwrapped.agent_position
    _, _, terminated, _, info = env.step(LOOK_DOWN)  # looking moves nothing and costs a step
    assert np.array_equal(env.unwrapped.agent_position, pos) and info["num_steps"] == 4 and not terminated
    env.close()


def test_four_action_envs_refuse_a_look(objectnav_file):
    env = gym.make("navbench/ObjectNav-v0", dataset=objectnav_file, config=EnvConfig(rgb=False, depth=False))
    env.reset(seed=0)
    assert env.action_space.n == 4
    with pytest.raises(ValueError, match=r"0\.\.3 \(STOP, MOVE_FORWARD, TURN_LEFT, TURN_RIGHT\)"):
        env.step(LOOK_DOWN)
    env.close()


def test_bad_action_lists_are_one_line_naming_the_file(tmp_path):
    bad = tmp_path / "bad.toml"
    for text, needle in (('actions = ["STOP", "FLY"]\n', "unknown FLY"),
                         ('actions = ["STOP", "MOVE_FORWARD", "TURN_RIGHT", "TURN_LEFT"]\n', "id order"),
                         ('actions = "STOP"\n', "list of action names")):
        bad.write_text(text)
        with pytest.raises(ValueError, match=needle) as exc:
            EnvConfig.load(bad)
        assert str(exc.value).startswith(str(bad)) and "\n" not in str(exc.value)


class LooksDownThenUp:
    """Written for habitat.Agent: reset() without the episode, act answers with Habitat's action names."""
    script = ("look_down", "look_down", {"action": "look_up"}, "look_up", "stop")
    sensors = ("depth",)

    def reset(self):
        self.i = 0

    def act(self, observations):
        assert observations["depth"].ndim == 3 and "objectgoal" in observations
        a = self.script[min(self.i, len(self.script) - 1)]
        self.i += 1
        return a


def test_a_habitat_agent_that_looks_down_then_up_runs_unchanged(objectnav_file, tmp_path):
    summary = navbench.evaluate(LooksDownThenUp, task="objectnav", episodes=objectnav_file, limit=2,
                                env_config="habitat-objectnav-hm3d", out=tmp_path / "run")
    assert summary["num_failed"] == 0 and summary["num_episodes"] == 2
    records = [json.loads(line) for line in (tmp_path / "run" / "episodes.jsonl").read_text().splitlines()]
    assert all(r["trace"]["actions"] == "55440" and r["num_steps"] == 5 for r in records)
    cfg = json.loads((tmp_path / "run" / "config.json").read_text())
    assert cfg["env"]["actions"][4:] == ["LOOK_UP", "LOOK_DOWN"] and cfg["env_config_name"] == "habitat-objectnav-hm3d"
    from navbench.eval.config import RunConfig
    proto = config_protocol(RunConfig(**{k: v for k, v in cfg.items() if k in RunConfig.__dataclass_fields__}))
    assert proto["actions"][4:] == ["LOOK_UP", "LOOK_DOWN"] and proto["tilt_angle_deg"] == 30.0
    # resumable: the recorded configuration reads back as the same one
    navbench.evaluate(LooksDownThenUp, task="objectnav", episodes=objectnav_file, limit=2,
                      env_config="habitat-objectnav-hm3d", out=tmp_path / "run", resume=True)
    # under navbench's four actions the same agent's LOOK_DOWN (5) is an invalid action
    with pytest.raises(RunError, match=r"invalid action 5 \(expected 0-3\)"):
        navbench.evaluate(LooksDownThenUp, task="objectnav", episodes=objectnav_file, limit=1, fail_fast=True,
                          out=tmp_path / "four")
