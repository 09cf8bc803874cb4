"""Goal images are rendered once per episode (ImageNav, InstanceImageNav) and once per image subtask (GOAT),
never per step, on the files ``navbench bench`` writes; and the bench reports the goal-image tasks' figures.
Renders are counted, not timed."""

from __future__ import annotations

import numpy as np
import pytest

import navbench.render.goal_images as goal_images
from navbench.bench.goal_tasks import GOAL_IMAGE, TASKS, goal_task_figures, write_goal_task_files
from navbench.bench.speed import _bench_dataset, format_report
from navbench.env.config import EnvConfig
from navbench.env.make import task_env
from navbench.episodes.goat import SUBTASK_STOP, load_goat
from navbench.episodes.instance_imagenav import load_instance_imagenav
from navbench.scene.cache import load_scene_and_navgrid

MOVES = (1, 2, 1, 3, 1, 2, 1)
NO_SENSORS = EnvConfig(rgb=False, depth=False)  # the goal images are what is counted


@pytest.fixture(scope="module")
def grid(scene_path):
    return load_scene_and_navgrid(scene_path)[1]


@pytest.fixture(scope="module")
def files(tmp_path_factory, scene_path, grid):
    return write_goal_task_files(scene_path, grid, tmp_path_factory.mktemp("goal_tasks"), episodes=4)


@pytest.fixture
def renders(monkeypatch):
    """Every goal image rendered at a file's camera pose (InstanceImageNav's and GOAT's), in order."""
    calls = []
    real = goal_images.render_image_goal

    def counted(asset, goal, platform="auto"):
        calls.append(goal)
        return real(asset, goal, platform)
    monkeypatch.setattr(goal_images, "render_image_goal", counted)
    return calls


def test_the_benchs_files_are_read_by_the_tasks_readers(files):
    iin = load_instance_imagenav(files["instance_imagenav"])
    assert len(iin.episodes) == 4 and {e.goal_image_id for e in iin.episodes} == {0}
    g = iin.episodes[0].image_goal
    assert (g.height, g.width, g.hfov_deg) == (*GOAL_IMAGE["image_dimensions"], GOAL_IMAGE["hfov"])
    goat = load_goat(files["goat"])
    assert len(goat.episodes) == 4
    assert [t.type for t in goat.episodes[0].tasks] == ["image", "object", "description", "image", "object"]
    assert all(len(e.subtask_goal_positions(k)) > 1 for e in goat.episodes for k in range(e.num_goals))


def test_imagenav_renders_its_goal_image_once_per_episode(scene_path, grid):
    env = task_env("imagenav", _bench_dataset(scene_path, grid, n=3), scene_dir="/", config=NO_SENSORS)
    calls = []
    real = env.render_rgb
    env.render_rgb = lambda position, rotation: calls.append(1) or real(position, rotation)
    obs, _ = env.reset(seed=0, options={"episode": 0})
    first = obs["imagegoal"].copy()
    for a in MOVES:
        obs, *_ = env.step(a)
        assert np.array_equal(obs["imagegoal"], first)
    assert len(calls) == 1
    env.reset(options={"episode": 1})
    env.step(1)
    assert len(calls) == 2
    env.close()


def test_instance_imagenav_renders_its_goal_image_once_per_episode(files, scene_path, renders):
    env = task_env("instance_imagenav", files["instance_imagenav"], scene_dir=scene_path.parent, config=NO_SENSORS)
    obs, _ = env.reset(seed=0, options={"episode": 0})
    first = obs["instance_imagegoal"].copy()
    assert first.shape == (512, 512, 3) and first.std() > 1  # the scene, not an empty frame
    obs["instance_imagegoal"][:] = 0  # the caller's copy: the env's stays
    for a in (*MOVES, 4, 5, 4):  # LOOK_UP / LOOK_DOWN tilt the agent's camera, not the goal's
        obs, *_ = env.step(a)
        assert np.array_equal(obs["instance_imagegoal"], first)
    assert renders == [env.episode.image_goal]
    env.reset(options={"episode": 1})
    for a in MOVES:
        env.step(a)
    assert len(renders) == 2 and renders[1] is env.episode.image_goal
    env.close()


def test_goat_renders_each_image_subtasks_goal_image_once(files, scene_path, renders):
    env = task_env("goat", files["goat"], scene_dir=scene_path.parent, config=NO_SENSORS)
    obs, _ = env.reset(seed=0, options={"episode": 0})
    ep = env.episode
    assert obs["current_subtask"].tolist() == [2] and len(renders) == 1  # the first subtask is an image one
    first = obs["subtask_image"].copy()
    assert first.std() > 1
    obs["subtask_image"][:] = 0  # the caller's copy: the env's stays
    seen = []
    for k in range(ep.num_goals):
        for a in MOVES:
            obs, *_ = env.step(a)
            seen.append(len(renders))
            if k == 0:
                assert np.array_equal(obs["subtask_image"], first)
        obs, _, terminated, _, _ = env.step(SUBTASK_STOP)
        assert terminated == (k == ep.num_goals - 1)
    # subtasks image, object, description, image, object: a render when each image subtask starts, none per step
    per_subtask = [seen[k * len(MOVES):(k + 1) * len(MOVES)] for k in range(ep.num_goals)]
    assert per_subtask == [[1] * len(MOVES), [1] * len(MOVES), [1] * len(MOVES), [2] * len(MOVES),
                           [2] * len(MOVES)]
    assert renders == [ep.image_goals[0], ep.image_goals[3]]
    env.reset(options={"episode": 1})
    assert len(renders) == 3
    env.close()


def test_the_bench_reports_each_goal_tasks_figures(scene_path, grid):
    r = goal_task_figures(scene_path, _bench_dataset(scene_path, grid, n=3), EnvConfig(width=64, height=64),
                          seconds=0.05, repeats=1, slices=1)
    for t in TASKS:
        assert r[f"{t}_steps_per_s"] > 0 and r[f"{t}_reset_ms"] > 0 and r[f"{t}_goal_obs_us"] > 0
    assert all(r[f"{t}_goal_image_ms"] > 0 for t in TASKS[1:]) and "pointnav_goal_image_ms" not in r
    assert r["goat_measures_ms_at_5000"] > 0
    report = format_report({"scene": "s.glb", "scene_triangles": 3, "grid_shape": "2x2", "cpu": "x", **r})
    assert sum(line.startswith("goal image, ") for line in report.splitlines()) == 3
    assert any(line.startswith("env steps/s, RGB-D, GOAT") for line in report.splitlines())
