"""Instance goal images: a pinhole camera at the file's full world pose, with its hfov and size."""

import numpy as np
import pytest

from navbench.episodes.instance_imagenav import (
    ImageGoal,
    InstanceImageEpisode,
    InstanceImageGoal,
    instance_imagegoal_observations,
)
from navbench.episodes.types import AgentState, ViewPoint
from navbench.render.goal_images import GoalImageCache, render_image_goal
from navbench.scene.asset import load_scene

POS = (0.5, 1.3, 0.5)  # inside the smoke house (bounds x, z in +-6, y in [-0.1, 2.7])


def q(axis, deg):
    h = np.radians(deg) / 2.0
    v = np.zeros(4)
    v[axis], v[3] = np.sin(h), np.cos(h)
    return v


def qmul(a, b):
    x1, y1, z1, w1 = a
    x2, y2, z2, w2 = b
    return np.array([w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2, w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2, w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2])


def goal(rot, hfov=70.0, h=48, w=64):
    return ImageGoal(POS, tuple(float(v) for v in rot), hfov, h, w)


@pytest.fixture(scope="module")
def asset(scene_path):
    return load_scene(scene_path)


def test_image_has_the_files_size_and_hfov(asset):
    g = goal(qmul(q(1, 30), q(0, -20)), hfov=65.0, h=40, w=72)
    ep = InstanceImageEpisode(
        "1", "x.glb", [0, 0, 0], [0, 0, 0, 1], object_category="chair", goal_object_id="3", goal_image_id=0,
        goals=[InstanceImageGoal([0, 0, 0], 3, "chair", view_points=[ViewPoint(AgentState([0, 0, 0], [0, 0, 0, 1]))],
                                 image_goals=[g])])
    obs = instance_imagegoal_observations(asset, ep)
    img = obs["instance_imagegoal"]
    assert img.shape == (40, 72, 3) and img.dtype == np.uint8 and img.std() > 5  # not blank
    assert obs["instance_imagegoal_hfov"].dtype == np.float32 and obs["instance_imagegoal_hfov"].tolist() == [65.0]


def test_rotated_180_degrees_is_another_image(asset):
    a = render_image_goal(asset, goal(q(1, 0)))
    b = render_image_goal(asset, goal(q(1, 180)))
    assert (np.abs(a.astype(int) - b.astype(int)).max(axis=2) > 8).mean() > 0.3


def test_pitch_is_honoured(asset):
    level = render_image_goal(asset, goal(q(1, 45)))
    down = render_image_goal(asset, goal(qmul(q(1, 45), q(0, -30))))
    assert (np.abs(level.astype(int) - down.astype(int)).max(axis=2) > 8).mean() > 0.15


def test_roll_is_honoured(asset):
    # a camera rolled 180 degrees about its optical axis (-z) sees the level image upside down and mirrored
    base = qmul(q(1, 45), q(0, -10))
    level = render_image_goal(asset, goal(base))
    rolled = render_image_goal(asset, goal(qmul(base, q(2, 180))))
    assert (np.abs(level.astype(int) - rolled.astype(int)).max(axis=2) > 8).mean() > 0.15
    same = np.abs(np.rot90(level, 2).astype(int) - rolled.astype(int)).max(axis=2) <= 8
    assert same.mean() > 0.97
    # and a 90 degree roll of a square image is the level image turned a quarter (counter-clockwise roll of
    # the camera turns the picture clockwise)
    sq = dict(h=48, w=48)
    level = render_image_goal(asset, goal(base, **sq))
    rolled = render_image_goal(asset, goal(qmul(base, q(2, 90)), **sq))
    assert (np.abs(np.rot90(level, -1).astype(int) - rolled.astype(int)).max(axis=2) <= 8).mean() > 0.95


def test_cache_renders_once_per_key(asset):
    cache = GoalImageCache()
    g = goal(q(1, 0))
    a = cache.get(("scene", "1"), asset, g)
    assert cache.get(("scene", "1"), asset, g) is a and cache.renders == 1
    cache.get(("scene", "2"), asset, g)
    assert cache.renders == 2
