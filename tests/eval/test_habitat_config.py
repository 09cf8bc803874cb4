"""`navbench run --habitat-config FILE`: a resolved habitat-lab configuration, read as it is."""

import json
import math

import pytest
import yaml

from navbench.cli import main
from navbench.eval.habitat_config import HabitatConfigError, read_habitat_config
from navbench.paths import SCENES_DIR, split_file

VAL_UNSEEN = split_file("objectnav", "val_unseen")


def objectnav_config(**changes):
    """A resolved ObjectNav configuration as habitat-baselines writes one (habitat-lab 0.3's keys), with the
    values of the HM3D ObjectNav challenge but for those ``changes`` sets (dotted keys)."""
    sensor = {"type": "HabitatSimRGBSensor", "width": 320, "height": 240, "hfov": 79, "position": [0.0, 0.88, 0.0],
              "orientation": [0.0, 0.0, 0.0], "sensor_subtype": "PINHOLE", "noise_model": "None",
              "noise_model_kwargs": {}}
    doc = {
        "habitat": {
            "seed": 100, "env_task": "GymHabitatEnv",
            "environment": {"max_episode_steps": 400, "max_episode_seconds": 10000000},
            "simulator": {
                "type": "Sim-v0", "forward_step_size": 0.25, "turn_angle": 30, "tilt_angle": 30,
                "action_space_config": "v1", "action_space_config_arguments": {},
                "habitat_sim_v0": {"gpu_device_id": 0, "allow_sliding": False, "frustum_culling": True},
                "agents": {"main_agent": {
                    "height": 0.88, "radius": 0.18, "max_climb": 0.2, "max_slope": 45.0,
                    "sim_sensors": {
                        "rgb_sensor": dict(sensor),
                        "depth_sensor": {**sensor, "type": "HabitatSimDepthSensor", "min_depth": 0.5,
                                         "max_depth": 5.0, "normalize_depth": True}}}},
                "agents_order": ["main_agent"]},
            "task": {
                "type": "ObjectNav-v1", "reward_measure": "distance_to_goal_reward", "success_measure": "spl",
                "success_reward": 2.5, "slack_reward": -0.001, "end_on_success": True,
                "lab_sensors": {"objectgoal_sensor": {"type": "ObjectGoalSensor"}, "compass_sensor": {
                    "type": "CompassSensor"}, "gps_sensor": {"type": "GPSSensor", "dimensionality": 2}},
                "measurements": {"distance_to_goal": {"type": "DistanceToGoal", "distance_to": "VIEW_POINTS"},
                                 "success": {"type": "Success", "success_distance": 0.3}, "spl": {"type": "SPL"}},
                "goal_sensor_uuid": "objectgoal",
                "actions": {"stop": {"type": "StopAction"}, "move_forward": {"type": "MoveForwardAction"},
                            "turn_left": {"type": "TurnLeftAction"}, "turn_right": {"type": "TurnRightAction"}}},
            "dataset": {"type": "ObjectNav-v1", "split": "val_unseen", "scenes_dir": str(SCENES_DIR),
                        "data_path": str(VAL_UNSEEN.parent.parent / "{split}" / "{split}.json.gz")},
        },
        "habitat_baselines": {"trainer_name": "ppo", "num_environments": 4, "rl": {"ppo": {"lr": 2.5e-4}}},
    }
    for key, value in changes.items():
        node, *path, last = key.split(".")
        cur = doc[node]
        for p in path:
            cur = cur[p]
        if value is None:
            cur.pop(last)
        else:
            cur[last] = value
    return doc


def write(tmp_path, doc, name="config.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc, sort_keys=False))  # in order, as OmegaConf writes it
    return path


def test_a_resolved_objectnav_config_runs_and_config_json_shows_each_value_it_set(tmp_path, capsys):
    cfg = write(tmp_path, objectnav_config())
    out = tmp_path / "run"
    assert main(["run", "--habitat-config", str(cfg), "--agent", "oracle", "--limit", "2", "--out", str(out),
                 "-q"]) == 0
    err = capsys.readouterr().err
    assert f"{cfg}: ignored " in err and "habitat_baselines" in err and len(err.strip().splitlines()) == 1
    rec = json.loads((out / "config.json").read_text())
    assert rec["task"] == "objectnav" and rec["success_distance"] == 0.3
    assert rec["episodes"] == str(VAL_UNSEEN) and rec["scene_dir"] == str(SCENES_DIR)
    assert rec["env"] == {"width": 320, "height": 240, "max_steps": 400}  # what differs from navbench's defaults
    used = rec["habitat_config"]["used"]
    assert used["habitat.environment.max_episode_steps"] == 400
    assert used["habitat.task.measurements.success.success_distance"] == 0.3
    assert used["habitat.simulator.agents.main_agent.sim_sensors.rgb_sensor.width"] == 320
    assert used["habitat.task.actions"] == ["stop", "move_forward", "turn_left", "turn_right"]
    assert used["habitat.dataset.data_path"].endswith("{split}.json.gz")
    assert "habitat_baselines.rl.ppo.lr" in rec["habitat_config"]["ignored"]
    assert "habitat.task.success_reward" in rec["habitat_config"]["ignored"]
    assert json.loads((out / "provenance.json").read_text())["protocol"]["max_steps"] == 400
    # the flags override it: another split, and the dataset's keys are then not used
    s = read_habitat_config(cfg)
    from navbench.eval.habitat_config import run_arguments
    assert run_arguments(s, None, "val_seen", None, None, 0.1)[1:] == (None, SCENES_DIR, 0.1)
    assert "habitat.dataset.data_path" in s.ignored and "habitat.dataset.data_path" not in s.used


def test_habitat_objectnav_six_actions_set_the_action_list_and_the_tilt(tmp_path):
    six = {"stop": {"type": "StopAction"}, "move_forward": {"type": "MoveForwardAction"},
           "turn_left": {"type": "TurnLeftAction"}, "turn_right": {"type": "TurnRightAction"},
           "look_up": {"type": "LookUpAction"}, "look_down": {"type": "LookDownAction"}}
    s = read_habitat_config(write(tmp_path, objectnav_config(**{"habitat.task.actions": six})))
    assert s.env.actions == ("STOP", "MOVE_FORWARD", "TURN_LEFT", "TURN_RIGHT", "LOOK_UP", "LOOK_DOWN")
    assert s.env.tilt_angle_deg == 30


@pytest.mark.parametrize("changes, key", [
    ({"habitat.simulator.agents.main_agent.sim_sensors.rgb_sensor.position": [0.0, 1.25, 0.0]},
     "habitat.simulator.agents.main_agent.sim_sensors.rgb_sensor.position"),
    ({"habitat.simulator.agents.main_agent.sim_sensors.depth_sensor.hfov": 90},
     "habitat.simulator.agents.main_agent.sim_sensors.depth_sensor.hfov"),
    ({"habitat.task.measurements.distance_to_goal.distance_to": "POINT"},
     "habitat.task.measurements.distance_to_goal.distance_to"),
    ({"habitat.simulator.agents.main_agent.sim_sensors.rgb_sensor.noise_model": "MyNoise"},
     "habitat.simulator.agents.main_agent.sim_sensors.rgb_sensor.noise_model"),
    ({"habitat.task.type": "VLN-v0"}, "habitat.task.type"),
])
def test_a_key_navbench_cannot_honour_exits_2_naming_it(tmp_path, capsys, changes, key):
    cfg = write(tmp_path, objectnav_config(**changes))
    assert main(["run", "--habitat-config", str(cfg), "--agent", "oracle", "--limit", "1",
                 "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{cfg}: {key}: " in err[0] and "cannot honour" in err[0]
    assert not (tmp_path / "run").exists()


def test_noise_pitch_and_sliding_map_onto_navbench_and_bad_files_are_one_line(tmp_path):
    sensors = "habitat.simulator.agents.main_agent.sim_sensors"
    doc = objectnav_config(**{
        f"{sensors}.rgb_sensor.noise_model": "GaussianNoiseModel",
        f"{sensors}.rgb_sensor.noise_model_kwargs": {"intensity_constant": 0.1},
        f"{sensors}.depth_sensor.noise_model": "RedwoodDepthNoiseModel",
        f"{sensors}.rgb_sensor.orientation": [-0.3490659, 0.0, 0.0],
        f"{sensors}.depth_sensor.orientation": [-0.3490659, 0.0, 0.0],
        "habitat.simulator.action_space_config": "pyrobotnoisy",
        "habitat.simulator.action_space_config_arguments": {"robot": "LoCoBot", "controller": "Proportional",
                                                            "noise_multiplier": 0.5},
        "habitat.simulator.habitat_sim_v0.allow_sliding": True})
    env = read_habitat_config(write(tmp_path, doc)).env
    assert (env.rgb_noise, env.rgb_noise_intensity, env.depth_noise) == ("gaussian", 0.1, "redwood")
    assert (env.actuation_noise, env.actuation_noise_multiplier) == ("LoCoBot-Proportional", 0.5)
    assert math.isclose(env.camera_pitch_deg, -20.0) and env.allow_sliding
    bad = tmp_path / "bad.yaml"
    bad.write_text("habitat: [unclosed")
    with pytest.raises(HabitatConfigError, match="bad.yaml: not a readable yaml"):
        read_habitat_config(bad)
    with pytest.raises(HabitatConfigError, match="max_episode_steps: expected int"):
        read_habitat_config(write(tmp_path, objectnav_config(**{"habitat.environment.max_episode_steps": "500"})))


def test_the_config_inside_a_habitat_baselines_checkpoint(tmp_path):
    """A checkpoint's config read back with weights_only: a plain dict as it is, and OmegaConf's nodes (here
    stand-ins pickled under OmegaConf's module and class names, with its state layout) through their state."""
    import sys
    import types

    import torch

    plain = tmp_path / "plain.pth"
    torch.save({"state_dict": {"w": torch.zeros(1)}, "config": objectnav_config()}, plain)
    assert read_habitat_config(plain).env.max_steps == 400

    mods = {name: types.ModuleType(name) for name in ("omegaconf", "omegaconf.dictconfig", "omegaconf.nodes")}

    class DictConfig:
        def __init__(self, content):
            self.__dict__.update(_metadata=None, _parent=None, _content=content)

    class AnyNode:
        def __init__(self, val):
            self.__dict__.update(_metadata=None, _parent=None, _val=val)

    DictConfig.__module__, AnyNode.__module__ = "omegaconf.dictconfig", "omegaconf.nodes"
    DictConfig.__qualname__ = DictConfig.__name__ = "DictConfig"
    AnyNode.__qualname__ = AnyNode.__name__ = "AnyNode"
    mods["omegaconf.dictconfig"].DictConfig, mods["omegaconf.nodes"].AnyNode = DictConfig, AnyNode

    def wrap(node):
        if isinstance(node, dict):
            return DictConfig({k: wrap(v) for k, v in node.items()})
        return AnyNode(node)

    path = tmp_path / "ckpt.pth"
    with pytest.MonkeyPatch.context() as mp:  # restores a real omegaconf where one is imported (habitat-lab's)
        for name, mod in mods.items():
            mp.setitem(sys.modules, name, mod)
        torch.save({"state_dict": {"w": torch.zeros(1)}, "config": wrap(objectnav_config())}, path)
    s = read_habitat_config(path)
    assert s.task == "objectnav" and s.env.max_steps == 400 and s.success_distance == 0.3
    assert s.used["habitat.simulator.agents.main_agent.sim_sensors.depth_sensor.max_depth"] == 5.0
