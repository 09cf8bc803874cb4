"""Named configurations of the image- and GOAT-Bench tasks, field for field from their upstream yamls."""

from navbench.env.config import EnvConfig, env_config_names
from navbench.episodes.goat import MAX_EPISODE_STEPS, SUCCESS_DISTANCE


def test_goat_bench_configuration():
    assert "goat-bench" in env_config_names()
    c = EnvConfig.load("goat-bench")
    assert (c.agent_height, c.agent_radius, c.max_climb) == (1.41, 0.17, 0.1)
    assert (c.width, c.height, c.hfov_deg, c.turn_angle_deg, c.allow_sliding) == (360, 640, 42.0, 30.0, False)
    assert c.tilt_angle_deg == 30.0 and c.actions is None  # the goat task's seven actions
    assert (c.max_steps, c.success_distance) == (MAX_EPISODE_STEPS, SUCCESS_DISTANCE) == (5000, 0.25)


def test_imagenav_2023_challenge_configuration():
    c = EnvConfig.load("habitat-challenge-imagenav-2023")
    assert (c.agent_height, c.agent_radius, c.max_climb, c.allow_sliding) == (1.41, 0.17, 0.1, False)
    assert (c.width, c.height, c.hfov_deg, c.min_depth, c.max_depth) == (480, 640, 42.0, 0.5, 5.0)
    assert (c.max_steps, c.success_distance, c.turn_angle_deg, c.tilt_angle_deg) == (1000, 0.1, 30.0, 30.0)
    assert c.actions == ("STOP", "MOVE_FORWARD", "TURN_LEFT", "TURN_RIGHT", "LOOK_UP", "LOOK_DOWN")
