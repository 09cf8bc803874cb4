import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import navbench  # noqa: F401  (registers the ids)
from navbench.env.config import MOVE_FORWARD, STOP, TURN_LEFT, TURN_RIGHT, EnvConfig
from navbench.env.objectnav import ObjectNavEnv
from navbench.env.pointnav import PointNavEnv
from navbench.env.sensors import pointgoal_polar, to_agent_frame, world_pose
from navbench.episodes.io import load_dataset
from navbench.episodes.types import EpisodeError


@pytest.mark.parametrize("env_id,fixture", [("navbench/PointNav-v0", "pointnav_file"),
                                            ("navbench/ObjectNav-v0", "objectnav_file")])
def test_env_checker(env_id, fixture, request):
    env = gym.make(env_id, dataset=request.getfixturevalue(fixture), render_mode="rgb_array")
    check_env(env.unwrapped, skip_render_check=False)
    env.close()


def test_gym_make_with_bundled_data():
    for env_id in ("navbench/PointNav-v0", "navbench/ObjectNav-v0"):
        env = gym.make(env_id)
        obs, info = env.reset(seed=0)
        assert env.observation_space.contains(obs)
        assert math.isfinite(info["distance_to_goal"])
        env.close()


def test_reset_seed_is_deterministic(pointnav_file):
    env = PointNavEnv(pointnav_file)
    rng = np.random.default_rng(3)
    actions = rng.integers(1, 4, size=25)
    runs = []
    for _ in range(2):
        obs, _ = env.reset(seed=11)
        traj = [env.agent_position.copy()]
        for a in actions:
            obs, *_ = env.step(int(a))
            traj.append(env.agent_position.copy())
        runs.append((env.episode.episode_id, np.array(traj), obs["depth"].copy()))
    assert runs[0][0] == runs[1][0]
    np.testing.assert_array_equal(runs[0][1], runs[1][1])
    np.testing.assert_array_equal(runs[0][2], runs[1][2])


def test_sensors_follow_habitat_conventions(pointnav_file):
    env = PointNavEnv(pointnav_file, config=EnvConfig(rgb=False))
    obs, _ = env.reset(options={"episode": 0})
    assert np.allclose(obs["gps"], 0) and np.allclose(obs["compass"], 0)
    goal = np.asarray(env.episode.goals[0].position)
    rho, theta = obs["pointgoal_with_gps_compass"]
    assert rho == pytest.approx(np.linalg.norm((goal - env.agent_position)[[0, 2]]), abs=1e-4)
    # turning left by 30 deg: compass +30 deg, and the goal's bearing decreases by 30 deg
    obs2, *_ = env.step(TURN_LEFT)
    assert obs2["compass"][0] == pytest.approx(math.radians(30), abs=1e-5)
    d = (obs2["pointgoal_with_gps_compass"][1] - theta + math.pi) % (2 * math.pi) - math.pi
    assert d == pytest.approx(-math.radians(30), abs=1e-4)
    # walk, then GPS + compass + the episode's start pose recover the true world pose
    for a in (MOVE_FORWARD, MOVE_FORWARD, TURN_RIGHT, MOVE_FORWARD):
        obs2, *_ = env.step(a)
    pos, yaw = world_pose(obs2["gps"], obs2["compass"], env.episode.start_position,
                          navbench.scene.pose.yaw_from_quat(env.episode.start_rotation))
    assert np.allclose(pos[[0, 2]], env.agent_position[[0, 2]], atol=1e-4)
    assert yaw == pytest.approx(env.agent_yaw, abs=1e-5)


def test_sensor_math_left_is_positive():
    # agent at the origin facing -z; a goal 1 m to its left (-x) is at theta = +90 deg
    rho, theta = pointgoal_polar(np.array([-1.0, 0, 0]), np.zeros(3), 0.0)
    assert rho == pytest.approx(1.0) and theta == pytest.approx(math.pi / 2)
    assert to_agent_frame(np.array([0, 0, -2.0]), 0.0) == pytest.approx((2.0, 0.0))


def test_forward_moves_quarter_metre_and_walls_collide(pointnav_file):
    env = PointNavEnv(pointnav_file, config=EnvConfig(rgb=False, depth=False))
    env.reset(options={"episode": 0})
    # face each direction in turn and walk until blocked; a blocked step is a collision and shorter
    for _ in range(4):
        start = env.agent_position
        _, _, _, _, info = env.step(MOVE_FORWARD)
        moved = np.linalg.norm((env.agent_position - start)[[0, 2]])
        assert moved <= 0.25 + 1e-6
        if info["collisions"] == 0:
            assert moved == pytest.approx(0.25, abs=1e-6)
        env.step(TURN_LEFT)
    collisions = 0
    for _ in range(120):  # straight into a wall eventually
        before = env.agent_position
        _, _, term, trunc, info = env.step(MOVE_FORWARD)
        assert env.navgrid.is_navigable(env.agent_position)
        if info["collisions"] > collisions:
            collisions = info["collisions"]
            assert np.linalg.norm((env.agent_position - before)[[0, 2]]) < 0.25
            break
    assert collisions > 0


def test_stop_terminates_and_max_steps_truncates(pointnav_file):
    env = PointNavEnv(pointnav_file, config=EnvConfig(rgb=False, depth=False, max_steps=5))
    env.reset(options={"episode": 1})
    for _ in range(4):
        _, _, term, trunc, _ = env.step(TURN_LEFT)
        assert not term and not trunc
    _, _, term, trunc, info = env.step(TURN_LEFT)
    assert trunc and not term and info["num_steps"] == 5
    with pytest.raises(RuntimeError, match="reset"):
        env.step(TURN_LEFT)
    env.reset(options={"episode": 1})
    _, _, term, trunc, info = env.step(STOP)
    assert term and info["stop_called"] and info["success"] == 0.0  # stopped far from the goal


@pytest.mark.parametrize("action", [4, -1, 1.5, "forward", None])
def test_out_of_range_action(pointnav_file, action):
    env = PointNavEnv(pointnav_file, config=EnvConfig(rgb=False, depth=False))
    env.reset(options={"episode": 0})
    with pytest.raises(ValueError, match="action must be"):
        env.step(action)


def test_bad_start_pose(pointnav_file):
    ds = load_dataset(pointnav_file)
    env = PointNavEnv(ds, config=EnvConfig(rgb=False, depth=False))
    ep = ds.episodes[0]
    ep_nan = type(ep)(**{**ep.__dict__, "episode_id": "nan", "start_position": [float("nan"), 0.0, 0.0]})
    with pytest.raises(EpisodeError, match="episode nan: non-finite start pose"):
        env.reset(options={"episode": ep_nan})
    ep_off = type(ep)(**{**ep.__dict__, "episode_id": "off", "start_position": [500.0, 0.0, 500.0]})
    with pytest.raises(EpisodeError, match="episode off .* is not navigable"):
        env.reset(options={"episode": ep_off})


def test_objectnav_goal_sensor_and_success_at_view_point(objectnav_file):
    env = ObjectNavEnv(objectnav_file, config=EnvConfig(rgb=False, depth=False, success_distance=0.1))
    obs, info = env.reset(options={"episode": 0})
    cats = env.dataset.category_to_task_category_id
    assert obs["objectgoal"][0] == cats[env.episode.object_category]
    # distance-to-goal is measured to the nearest view point of any goal instance
    vps = env.episode.goal_positions()
    assert info["distance_to_goal"] >= np.min(np.linalg.norm((vps - env.agent_position)[:, [0, 2]], axis=1)) - 1e-6
