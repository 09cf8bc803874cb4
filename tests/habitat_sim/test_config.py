"""habitat-sim's configuration objects: exact fields (habitat-lab's overwrite_config probes them with hasattr)."""

import pytest

from navbench.habitat_sim import config as c
from navbench.habitat_sim.nav import nav_grid_config


def test_fields_are_habitat_sims_and_no_others():
    sim = c.SimulatorConfiguration()
    for name in ("gpu_device_id", "allow_sliding", "frustum_culling", "enable_physics", "enable_hbao",
                 "physics_config_file", "leave_context_with_background_renderer", "enable_gfx_replay_save",
                 "scene_id", "scene_dataset_config_file", "navmesh_settings", "create_renderer",
                 "load_semantic_mesh", "requires_textures", "random_seed", "default_agent_id"):
        assert hasattr(sim, name), name
    spec = c.CameraSensorSpec()
    for name in ("uuid", "sensor_type", "sensor_subtype", "position", "orientation", "hfov", "resolution", "near",
                 "far", "channels", "noise_model", "noise_model_kwargs", "gpu2gpu_transfer", "ortho_scale"):
        assert hasattr(spec, name), name
    assert spec.sensor_subtype == c.SensorSubType.PINHOLE
    agent = c.AgentConfiguration()
    assert (agent.height, agent.radius, agent.body_type) == (1.5, 0.1, "cylinder")
    assert sorted(agent.action_space) == ["move_forward", "turn_left", "turn_right"]
    # a yaml key habitat-sim does not have must not pass habitat-lab's hasattr check, nor be settable
    for obj in (sim, spec, agent, c.NavMeshSettings()):
        assert not hasattr(obj, "max_depth")
        with pytest.raises(AttributeError):
            obj.max_depth = 10.0


def test_configuration_equality_decides_reload():
    a = c.Configuration(c.SimulatorConfiguration(), [c.AgentConfiguration()])
    b = c.Configuration()
    assert a == b
    b.sim_cfg.scene_id = "other.glb"
    assert a != b


def test_enums_are_looked_up_by_name():
    names = ("ORTHOGRAPHIC", "DOUBLE_SPHERE")  # habitat-lab: getattr(habitat_sim.SensorSubType, yaml_value)
    assert getattr(c.SensorSubType, names[0]) is c.SensorSubType.ORTHOGRAPHIC
    assert getattr(c.FisheyeSensorModelType, names[1]) is c.FisheyeSensorModelType.DOUBLE_SPHERE
    assert c.ActionSpec("move_forward", c.ActuationSpec(amount=0.25)).actuation.amount == 0.25


def test_navmesh_settings_map_to_the_grid_and_refuse_another_slope():
    s = c.NavMeshSettings()
    s.agent_radius, s.agent_height, s.agent_max_climb = 0.2, 1.2, 0.1
    g = nav_grid_config(s)
    assert (g.agent_radius, g.agent_height, g.max_climb, g.cell_size) == (0.2, 1.2, 0.1, 0.05)
    s.agent_max_slope = 30.0
    with pytest.raises(ValueError, match="agent_max_slope=30.0"):
        nav_grid_config(s)
    s.set_defaults()
    assert s.agent_max_slope == 45.0 and s.agent_radius == 0.1
