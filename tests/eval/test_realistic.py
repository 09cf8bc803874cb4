"""Runs under realistic conditions: the same seed gives the same records with 1 or 2 workers, config.json and
the protocol record the conditions, a noisy run is never compared with a noiseless one unasked, and an agent
that cannot run under a configuration says so in one line."""

import json

import pytest

from navbench.api import evaluate
from navbench.cli import main
from navbench.eval.provenance import ProtocolError, check_same_protocol
from navbench.eval.runner import comparable, read_records


def _challenge_like(tmp_path):
    """The 2021 PointNav challenge's noise at a small image, so the test stays fast."""
    path = tmp_path / "noisy.toml"
    path.write_text('actuation_noise = "LoCoBot-Proportional"\nactuation_noise_multiplier = 0.5\n'
                    'depth_noise = "redwood"\nrgb_noise = "gaussian"\nrgb_noise_intensity = 0.1\n'
                    'width = 64\nheight = 48\n')
    return path


def test_same_seed_same_noisy_records_with_one_or_two_workers(pointnav_file, tmp_path):
    cfg = _challenge_like(tmp_path)
    one = evaluate("oracle", episodes=pointnav_file, env_config=cfg, seed=2, workers=1, out=tmp_path / "one")
    two = evaluate("oracle", episodes=pointnav_file, env_config=cfg, seed=2, workers=2, out=tmp_path / "two")
    a, b = (comparable(read_records(tmp_path / d / "episodes.jsonl")) for d in ("one", "two"))
    assert a == b and one["spl"] == two["spl"]
    quiet = evaluate("oracle", episodes=pointnav_file, seed=2, workers=1, out=tmp_path / "quiet")
    # the noise moved the agent: paths differ from the noiseless run's
    assert [r["path_length"] for r in a] != [r["path_length"] for r in comparable(
        read_records(tmp_path / "quiet" / "episodes.jsonl"))]
    assert quiet["num_episodes"] == one["num_episodes"]
    cj = json.loads((tmp_path / "one" / "config.json").read_text())
    assert cj["env_config_name"] == "noisy" and cj["env"]["actuation_noise"] == "LoCoBot-Proportional"
    assert "env_config_name" not in json.loads((tmp_path / "quiet" / "config.json").read_text())
    proto = json.loads((tmp_path / "one" / "provenance.json").read_text())["protocol"]
    assert proto["depth_noise"] == "redwood" and proto["actuation_noise_multiplier"] == 0.5
    assert "depth_noise" not in json.loads((tmp_path / "quiet" / "provenance.json").read_text())["protocol"]
    with pytest.raises(ProtocolError, match="actuation_noise"):
        check_same_protocol([tmp_path / "quiet", tmp_path / "one"])
    assert main(["compare", str(tmp_path / "quiet"), str(tmp_path / "one")]) == 2
    assert main(["compare", "--mix-protocols", str(tmp_path / "quiet"), str(tmp_path / "one")]) == 0


@pytest.mark.parametrize("agent,needle", [("memory", "GPS+compass"), ("frontier", "GPS+compass")])
def test_an_agent_that_needs_gps_exits_2_in_one_line_without_it(agent, needle, capsys, tmp_path):
    argv = ["run", "--task", "objectnav", "--agent", agent, "--env-config", "navbench-dead-reckoning", "--limit", "1",
            "--out", str(tmp_path / "o")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and needle in err[0] and agent in err[0]


def test_an_agent_that_maps_with_a_level_camera_exits_2_under_a_pitched_one(capsys, tmp_path):
    pitched = tmp_path / "pitched.toml"
    pitched.write_text("camera_pitch_deg = -20.0\n")
    assert main(["run", "--agent", "frontier", "--env-config", str(pitched), "--limit", "1",
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "level camera" in err[0] and not (tmp_path / "o").exists()


def test_an_unknown_env_config_exits_2_naming_the_choices(capsys, tmp_path):
    assert main(["run", "--task", "pointnav", "--env-config", "habitat-2099", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "habitat-challenge-pointnav-2021" in err[0]


@pytest.mark.slow
def test_pointnav_dead_reckons_under_the_challenge_configuration(pointnav_file, tmp_path):
    """No GPS+compass, pitched camera, 640x360, all noise: the policy runs on its own estimate of the goal."""
    s = evaluate("pointnav", episodes=pointnav_file, env_config="habitat-challenge-pointnav-2021", limit=1,
                 workers=1, out=tmp_path / "c", options={"decoding": "argmax"})
    assert s["num_episodes"] == 1 and s["num_failed"] == 0
    cj = json.loads((tmp_path / "c" / "config.json").read_text())
    assert cj["env_config_name"] == "habitat-challenge-pointnav-2021" and cj["success_distance"] == 0.36
    assert cj["env"]["gps_compass"] is False and cj["env"]["camera_pitch_deg"] == -20.0


def test_a_habitat_agent_is_told_the_static_goal_sensor_without_gps_compass():
    from navbench.agents.habitat_compat import run_arguments
    from navbench.eval.config import RunConfig

    class HabitatLike:
        def __init__(self, success_distance, goal_sensor_uuid):
            pass

    cfg = RunConfig(task="pointnav", split="val", agent="x", episodes="e", scene_dir="s", success_distance=0.36,
                    env={"gps_compass": False})
    assert run_arguments(HabitatLike, cfg, {})["goal_sensor_uuid"] == "pointgoal"
    cfg.env = {}
    assert run_arguments(HabitatLike, cfg, {})["goal_sensor_uuid"] == "pointgoal_with_gps_compass"
