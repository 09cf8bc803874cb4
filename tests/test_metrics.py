import math

import pytest

from navbench.metrics import aggregate, episode_metrics, is_success, soft_spl, spl


def test_success_needs_stop_and_distance():
    assert is_success(True, 0.05, 0.1)
    assert not is_success(False, 0.05, 0.1)  # no STOP, no success
    assert not is_success(True, 0.1, 0.1)    # strictly less than the success distance
    assert not is_success(True, math.inf, 0.1)


@pytest.mark.parametrize("success,d0,path,expected", [
    (True, 4.0, 5.0, 0.8),     # detour: 4 / 5
    (True, 4.0, 4.0, 1.0),     # optimal
    (True, 4.0, 3.9, 1.0),     # shorter than d0 (stopped inside the radius): capped at 1
    (False, 4.0, 4.0, 0.0),
    (True, 0.0, 0.0, 1.0),     # started on the goal and stopped at once
    (True, 0.0, 1.0, 0.0),     # started on the goal, wandered, came back
    (True, math.inf, 3.0, 0.0),
])
def test_spl_hand_computed(success, d0, path, expected):
    assert spl(success, d0, path) == pytest.approx(expected)


def test_soft_spl_hand_computed():
    # ended 1 m short of a 4 m episode after walking 5 m: (1 - 1/4) * 4/5 = 0.6
    assert soft_spl(1.0, 4.0, 5.0) == pytest.approx(0.6)
    # ended farther away than the start: soft success clamps at 0
    assert soft_spl(6.0, 4.0, 2.0) == 0.0
    assert soft_spl(0.0, 0.0, 0.0) == 1.0
    assert soft_spl(math.inf, math.inf, 1.0) == 0.0


def test_episode_metrics_and_aggregate():
    a = dict(episode_id="1", scene_id="s", object_category="chair",
             **episode_metrics(True, 0.05, 2.0, 2.5, 0.1))
    b = dict(episode_id="2", scene_id="s", object_category="bed",
             **episode_metrics(False, 1.0, 2.0, 3.0, 0.1))
    c = dict(episode_id="3", scene_id="s", object_category="bed", skipped=True)
    assert a["success"] == 1.0 and a["spl"] == pytest.approx(0.8)
    assert b["success"] == 0.0 and b["soft_spl"] == pytest.approx(0.5 * 2 / 3)
    out = aggregate([b, c, a], by="object_category")
    assert out["num_episodes"] == 2 and out["num_skipped"] == 1
    assert out["success"] == pytest.approx(0.5)
    assert out["spl"] == pytest.approx(0.4)
    assert out["by_object_category"]["chair"]["success"] == 1.0
    assert out["by_object_category"]["bed"]["num_episodes"] == 1
    # order of records does not change the result
    assert aggregate([a, b]) == aggregate([b, a])
