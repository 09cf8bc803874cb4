"""ImageNav (habitat-lab ImageGoalSensor): PointNav-v1 episodes unchanged, the goal image rendered once per
episode at goals[0] with the episode's RGB sensor, its yaw drawn from a stable hash of the episode id."""

import dataclasses
import gzip
import json
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest

import navbench
from navbench.cli import main
from navbench.env.config import EnvConfig
from navbench.env.make import task_env
from navbench.episodes.generate import write_imagenav_split
from navbench.episodes.types import EpisodeError
from navbench.paths import SCENES_DIR, split_file
from navbench.tasks import get_task
from navbench.tasks.imagenav import goal_rotation, goal_yaw


def test_imagenav_is_registered_with_habitats_settings():
    t = get_task("imagenav")
    assert (t.gym_id, t.success_distance, t.max_steps, t.distance_to, t.episode_format) == \
        ("navbench/ImageNav-v0", 0.2, 1000, "POINT", "PointNav-v1")
    env = gym.make("navbench/ImageNav-v0")  # the bundled val split
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs) and obs["imagegoal"].shape == (224, 224, 3)
    assert obs["imagegoal"].dtype == np.uint8 and "pointgoal_with_gps_compass" not in obs
    assert env.unwrapped.config.max_steps == 1000 and env.unwrapped.success_distance == 0.2
    assert env.action_space.n == 4
    env.close()


def test_gymnasiums_env_checker_passes(pointnav_file):
    from gymnasium.utils.env_checker import check_env
    env = gym.make("navbench/ImageNav-v0", dataset=pointnav_file, render_mode="rgb_array")
    check_env(env.unwrapped, skip_render_check=False)
    env.close()


def test_the_goal_image_is_the_rgb_sensor_at_the_goal_facing_the_episodes_yaw(pointnav_file):
    env = task_env("imagenav", pointnav_file, config=EnvConfig(depth=False))
    for i in range(3):
        obs, _ = env.reset(seed=0, options={"episode": i})
        ep = env.episode
        env.set_agent_state(ep.goals[0].position, goal_rotation(ep.episode_id))
        assert np.array_equal(env.get_observations_at()["rgb"], obs["imagegoal"])
        assert abs(env.agent_yaw - np.arctan2(np.sin(goal_yaw(ep.episode_id)), np.cos(goal_yaw(ep.episode_id)))) < 1e-9
        assert not np.array_equal(obs["rgb"], obs["imagegoal"])  # the start's view is not the goal's
    env.close()


def test_the_goal_image_is_rendered_once_per_episode(pointnav_file):
    env = task_env("imagenav", pointnav_file, config=EnvConfig(rgb=False, depth=False))
    calls = []
    sensor = env.goal_sensors[0]
    env.goal_sensors = (dataclasses.replace(sensor, observe=lambda ctx: calls.append(1) or sensor.observe(ctx)),)
    obs, _ = env.reset(seed=0, options={"episode": 0})
    first = obs["imagegoal"].copy()
    assert first.any()
    obs["imagegoal"][:] = 0  # the caller's copy: the env's stays
    for a in (1, 2, 1, 3, 1):
        obs, *_ = env.step(a)
        assert np.array_equal(obs["imagegoal"], first)
    assert len(calls) == 1
    env.reset(seed=0, options={"episode": 1})
    assert len(calls) == 2
    env.close()


def test_the_goal_yaw_is_the_same_in_every_process_where_habitats_is_not():
    code = "import sys; from navbench.tasks.imagenav import goal_yaw; print(goal_yaw('17'), hash('17'))"
    out = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                          env={"PYTHONHASHSEED": seed, "PYTHONPATH": ":".join(sys.path)}).stdout.split()
           for seed in ("1", "2")]
    assert out[0][0] == out[1][0] == repr(goal_yaw("17"))
    assert out[0][1] != out[1][1]  # Python's salted hash, which Habitat seeds the yaw with
    assert 0 <= goal_yaw("17") < 2 * np.pi and goal_yaw("17") != goal_yaw("18")


def test_the_named_benchmark_configuration(pointnav_file):
    c = EnvConfig.load("habitat-imagenav")
    assert (c.width, c.height, c.hfov_deg, c.agent_height, c.agent_radius, c.turn_angle_deg, c.max_steps,
            c.gps_compass, c.allow_sliding, c.success_distance) == (256, 256, 90.0, 1.25, 0.1, 10.0, 1000,
                                                                    False, True, 0.2)
    env = task_env("imagenav", pointnav_file, config=dataclasses.replace(c, depth=False))
    obs, _ = env.reset(seed=0, options={"episode": 0})
    assert set(obs) == {"rgb", "imagegoal"} and obs["imagegoal"].shape == (256, 256, 3)
    env.close()


def test_objectnav_episodes_are_refused_in_one_line_naming_file_and_field(objectnav_file, capsys):
    with pytest.raises(EpisodeError, match="object_category") as exc:
        get_task("imagenav").read_episodes(objectnav_file)
    assert str(exc.value).startswith(str(objectnav_file)) and "\n" not in str(exc.value)
    assert main(["run", "--task", "imagenav", "--episodes", str(objectnav_file), "--agent", "oracle"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(objectnav_file) in err[0] and "use --task objectnav" in err[0]


def test_an_episode_without_a_goal_exits_2_naming_file_and_field(tmp_path, pointnav_file, capsys):
    data = json.loads(gzip.decompress(pointnav_file.read_bytes()))
    data["episodes"][1]["goals"] = []
    bad = tmp_path / "nogoal.json.gz"
    bad.write_bytes(gzip.compress(json.dumps(data).encode()))
    assert main(["run", "--task", "imagenav", "--episodes", str(bad), "--agent", "oracle",
                 "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0] and "no goals" in err[0]


def test_the_bundled_split_regenerates_byte_for_byte(tmp_path):
    write_imagenav_split(tmp_path, SCENES_DIR, seed=0, log=lambda *a: None)
    assert (tmp_path / "imagenav" / "val" / "val.json.gz").read_bytes() == split_file("imagenav", "val").read_bytes()


def test_the_oracle_reaches_every_goal_of_the_bundled_split(tmp_path):
    summary = navbench.evaluate("oracle", task="imagenav", per_scene=10, out=tmp_path / "run")
    assert summary["num_episodes"] == 40 and summary["success"] == 1.0 and summary["num_failed"] == 0
    cfg = json.loads((tmp_path / "run" / "config.json").read_text())
    assert (cfg["task"], cfg["split"], cfg["success_distance"], cfg["env"]) == ("imagenav", "val", 0.2,
                                                                              {"max_steps": 1000})


@pytest.mark.slow
def test_the_oracle_reaches_every_goal_of_the_whole_bundled_split(tmp_path):
    summary = navbench.evaluate("oracle", task="imagenav", out=tmp_path / "run")
    assert summary["num_episodes"] == 400 and summary["success"] == 1.0


def test_a_habitat_pointnav_v1_file_with_content_runs_unchanged(tmp_path, pointnav_file):
    """A PointNav-v1 split as habitat-lab's datasets/pointnav/pointnav_dataset.py reads it (an empty top-level
    file, the episodes in content/{scene}.json.gz; written here from the schema, not by navbench): the oracle
    reaches every goal with d0 within 3% of the file's geodesic distance."""
    src = json.loads(gzip.decompress(pointnav_file.read_bytes()))["episodes"]
    episodes = [{"episode_id": str(e["episode_id"]), "scene_id": e["scene_id"],
                 "start_position": e["start_position"], "start_rotation": e["start_rotation"],
                 "info": {"geodesic_distance": e["info"]["geodesic_distance"]},
                 "goals": [{"position": e["goals"][0]["position"], "radius": None}],
                 "shortest_paths": None, "start_room": None} for e in src]
    split = tmp_path / "val"
    (split / "content").mkdir(parents=True)
    (split / "val.json.gz").write_bytes(gzip.compress(json.dumps({"episodes": []}).encode()))
    scene = episodes[0]["scene_id"].rsplit("/", 1)[-1].split(".")[0]
    (split / "content" / f"{scene}.json.gz").write_bytes(gzip.compress(json.dumps({"episodes": episodes}).encode()))
    summary = navbench.evaluate("oracle", task="imagenav", episodes=split / "val.json.gz", out=tmp_path / "run")
    assert summary["num_episodes"] == len(episodes) and summary["success"] == 1.0
    records = [json.loads(line) for line in (tmp_path / "run" / "episodes.jsonl").read_text().splitlines()]
    file_d0 = {e["episode_id"]: e["info"]["geodesic_distance"] for e in episodes}
    assert all(abs(r["geodesic_distance"] - file_d0[r["episode_id"]]) <= 0.03 * file_d0[r["episode_id"]]
               for r in records)
