"""InstanceImageNav and GOAT-Bench through their Gymnasium ids, on files written from the published schemas
(benchmarks/habitat_formats.py, not navbench's writer), driven by the geodesic follower."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import navbench  # noqa: F401  (registers the ids)
from navbench.env.config import EnvConfig
from navbench.scene.follower import GreedyFollower

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    spec = importlib.util.spec_from_file_location("habitat_formats", ROOT / "benchmarks" / "habitat_formats.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.write_all(tmp_path_factory.mktemp("formats"))


def follow(env, success_distance, stop_action=0, limit=200):
    """Drive to the nearest current goal point and issue ``stop_action`` inside ``success_distance``."""
    u = env.unwrapped
    f = GreedyFollower(u._motion, u.goal_points, success_distance, u.config.forward_step, u.config.turn_angle_deg)
    for _ in range(limit):
        a = int(f.next_action(u.agent_position, u.agent_rotation))
        out = env.step(stop_action if a == 0 else a)
        if a == 0:
            return out
    raise AssertionError("the follower did not arrive")


def test_instance_imagenav_env_oracle_succeeds_with_the_files_goal_image(files):
    env = gym.make("navbench/InstanceImageNav-v0", dataset=files["instance_imagenav"],
                   scene_dir=files["scene_datasets"], config=EnvConfig(rgb=False, depth=False, max_steps=1000))
    u = env.unwrapped
    assert u.actions == ("STOP", "MOVE_FORWARD", "TURN_LEFT", "TURN_RIGHT", "LOOK_UP", "LOOK_DOWN")
    assert u.success_distance == 0.1
    for i, ep in enumerate(u.dataset.episodes):
        obs, info = env.reset(options={"episode": i})
        g = ep.image_goal
        assert obs["instance_imagegoal"].shape == (g.height, g.width, 3) and obs["instance_imagegoal"].std() > 5
        assert obs["instance_imagegoal_hfov"].tolist() == [g.hfov_deg]
        # the file's geodesic (here the straight line to the nearest view point, in an open room)
        assert info["geodesic_distance"] == pytest.approx(ep.info["geodesic_distance"], rel=0.03)
        _, _, terminated, _, info = follow(env, 0.1)
        assert terminated and info["success"] == 1.0 and info["spl"] > 0.8
        assert info["distance_to_goal"] < 0.1
    env.close()


def test_goat_env_sequences_subtasks_and_scores_as_goat_bench(files):
    env = gym.make("navbench/GOAT-v0", dataset=files["goat_bench"], scene_dir=files["scene_datasets"],
                   config=EnvConfig(rgb=False, depth=False, max_steps=5000))
    u = env.unwrapped
    assert env.action_space.n == 7 and u.actions[6] == "SUBTASK_STOP"
    obs, info = env.reset(options={"episode": 0})
    assert obs["current_subtask"].tolist() == [0] and obs["subtask_category"] == "armchair"
    assert obs["subtask_description"] == "" and not obs["subtask_image"].any()
    seen = []
    info = None
    for k in range(5):
        seen.append((int(obs["current_subtask"][0]), obs["subtask_category"], obs["subtask_description"][:14],
                     obs["subtask_image"].shape, bool(obs["subtask_image"].any())))
        obs, _, terminated, truncated, info = follow(env, 0.25, stop_action=6)
        assert terminated == (k == 4) and not truncated
        if k < 4:  # the next subtask starts where this one stopped: its d0 is from here to its goals
            fresh = u._motion.distance_field(u.episode.subtask_goal_positions(k + 1)).distance(u.agent_position)
            assert info["d0_by_subtask"][k + 1] == pytest.approx(fresh) and info["distance_to_goal"] == \
                pytest.approx(fresh)
    assert seen == [(0, "armchair", "", (224, 224, 3), False), (1, "tv", "The television", (224, 224, 3), False),
                    (2, "armchair", "", (224, 224, 3), True), (0, "tv", "", (224, 224, 3), False),
                    (1, "armchair", "The green armc", (224, 224, 3), False)]
    assert obs["current_subtask"].tolist() == [3]
    assert info["subtask_success"] == [1.0] * 5 and info["partial_success"] == 1.0
    assert info["composite_success"] == 1.0 and info["task_success"] == 0.0 and info["task_success_corrected"] == 1.0
    assert info["success"] == info["partial_success"] and 0.8 < info["composite_spl"] <= 1.0
    assert info["object_success"] == 1.0 and info["image_success"] == 1.0
    with pytest.raises(RuntimeError):
        env.step(1)


def test_goat_plain_stop_ends_the_episode(files):
    env = gym.make("navbench/GOAT-v0", dataset=files["goat_bench"], scene_dir=files["scene_datasets"],
                   config=EnvConfig(rgb=False, depth=False, max_steps=5000))
    env.reset(options={"episode": 0})
    follow(env, 0.25, stop_action=6)
    _, _, terminated, truncated, info = env.step(0)
    assert terminated and not truncated
    assert info["subtask_success"] == [1.0, 0.0, 0.0, 0.0, 0.0] and info["partial_success"] == 0.2
    assert info["object_success"] == 0.5 and info["description_success"] == 0.0 and info["image_success"] == 0.0
    assert np.isnan(info["d0_by_subtask"][2]) and json.dumps([v for v in info["spl_by_subtask"]])


def test_goat_env_needs_subtask_stop(files):
    with pytest.raises(ValueError, match="SUBTASK_STOP as action 6"):
        gym.make("navbench/GOAT-v0", dataset=files["goat_bench"], scene_dir=files["scene_datasets"],
                 config=EnvConfig.load("habitat-challenge-imagenav-2023"))


def test_goat_snapshot_restores_the_active_subtask(files):
    def make():
        return gym.make("navbench/GOAT-v0", dataset=files["goat_bench"], scene_dir=files["scene_datasets"],
                        config=EnvConfig(rgb=False, depth=False, max_steps=5000))
    env = make()
    env.reset(options={"episode": 0})
    follow(env, 0.25, stop_action=6)
    env.step(1)
    snap = json.loads(json.dumps(env.unwrapped.snapshot()))
    other = make()
    obs = other.unwrapped.restore(snap)
    assert obs["current_subtask"].tolist() == [1] and obs["subtask_description"].startswith("The television")
    a, b = (follow(e.unwrapped, 0.25, stop_action=6)[4] for e in (env, other))  # the restored env, unwrapped
    assert a["subtask_success"] == b["subtask_success"] == [1.0, 1.0, 0.0, 0.0, 0.0]
    assert a["composite_spl"] == pytest.approx(b["composite_spl"])
    assert a["d0_by_subtask"][:3] == pytest.approx(b["d0_by_subtask"][:3])


@pytest.mark.parametrize("gym_id,task", [("navbench/GOAT-v0", "goat"), ("navbench/InstanceImageNav-v0",
                                                                         "instance_imagenav")])
def test_a_task_without_bundled_splits_asks_for_a_file(gym_id, task, monkeypatch):
    import dataclasses

    from navbench.api import resolve_episodes
    from navbench.tasks import TASKS

    monkeypatch.setitem(TASKS, task, dataclasses.replace(TASKS[task], splits=(), default_split=""))  # bundling none
    with pytest.raises(ValueError, match="bundles no split: pass dataset="):
        gym.make(gym_id)
    with pytest.raises(ValueError, match="bundles no split: give a file of its episodes with --episodes FILE"):
        resolve_episodes(task, None, None)
