"""VLN-CE's measures (navbench.metrics) against the reference's measure classes transcribed in
tests/vlnce_reference.py, on scripted paths."""

import math
import random

import numpy as np
import pytest

from navbench.metrics import (
    dtw_distance,
    habitat_distances,
    ndtw,
    ndtw_points,
    vlnce_episode_metrics,
    vlnce_path_length,
)

pytest.importorskip("fastdtw", reason="fastdtw is a navbench dependency (the reference's nDTW library)")
from tests.vlnce_reference import run_reference  # noqa: E402

GOAL = np.array([4.0, 0.0, 1.0])


def geodesic(p):
    """A stand-in for the navmesh's geodesic: a detour around a wall at x = 2 (any function of the position
    serves, as long as both sides use the same one)."""
    p = np.asarray(p, np.float64)
    if p[0] < 2.0:
        return float(np.linalg.norm(p - [2.0, 0.0, 3.0]) + np.linalg.norm([2.0, 0.0, 3.0] - GOAL))
    return float(np.linalg.norm(p - GOAL))


def navbench(positions, actions, gt, max_steps=500):
    actions = list(actions[:max_steps])
    if 0 in actions:
        actions = actions[:actions.index(0) + 1]
    pts = positions[:len(actions) + 1]
    stop = bool(actions) and actions[-1] == 0
    return vlnce_episode_metrics(pts, habitat_distances(pts, geodesic), stop, gt)


def assert_same(ours, ref):
    for k, v in ref.items():
        assert ours[k] == pytest.approx(v, rel=1e-12, abs=1e-12), k


def walk(start, moves):
    """Positions after each scripted action: 'f' forward 0.25 m along +x, 'b' blocked (no move), 't' turn,
    'u' a step up a stair (+x 0.25, +y 0.1), 'w' a wiggle below habitat's 1e-4 distance-recompute tolerance,
    's' stop. Returns positions (start first) and Habitat action ids."""
    pos, out, acts = np.array(start, np.float64), [list(start)], []
    for m in moves:
        if m == "f":
            pos = pos + [0.25, 0, 0]
        elif m == "u":
            pos = pos + [0.25, 0.1, 0]
        elif m == "w":
            pos = pos + [0, 0, 5e-5]
        out.append(pos.tolist())
        acts.append({"f": 1, "u": 1, "w": 1, "b": 1, "t": 2, "s": 0}[m])
    return out, acts


GT = [[0.0, 0.0, 1.0 + 0.0]] + [[0.25 * i, 0.0, 1.0] for i in range(1, 17)]


@pytest.mark.parametrize("moves", [
    "s",                                   # STOP at once
    "ffffttffffbbffffffff" + "ffff" + "s",  # to the goal with turns and blocked moves
    "fftwwtfwf" + "s",                      # sub-tolerance wiggles: d_t is not recomputed, nDTW sees them
    "uuuffff" + "s",                        # vertical change counts in TL and nDTW
    "fff",                                  # cut short without STOP
    "ffffffffffffffffff" + "t" * 6 + "s",   # overshoot and stop more than 3 m away
])
def test_scripted_episodes_match_the_reference(moves):
    positions, actions = walk([0.0, 0.0, 1.0], moves)
    ours = navbench(positions, actions, GT)
    ref = run_reference(positions, actions, geodesic, GT)
    assert_same(ours, ref)


def test_stop_at_once():
    positions, actions = walk([0.0, 0.0, 1.0], "s")
    m = navbench(positions, actions, GT)
    ref = run_reference(positions, actions, geodesic, GT)
    assert m["steps_taken"] == 1 and m["path_length"] == 0 and m["success"] == 0 and m["spl"] == 0
    assert m["distance_to_goal"] == pytest.approx(geodesic([0, 0, 1.0]))
    assert m["oracle_success"] == 0
    # one agent point against the whole reference: DTW is the sum of its distances to every gt location
    d = sum(math.dist([0, 0, 1.0], g) for g in GT)
    assert m["ndtw"] == pytest.approx(math.exp(-d / (len(GT) * 3.0))) == pytest.approx(ref["ndtw"])
    assert m["ndtw_exact"] == pytest.approx(m["ndtw"])


def test_step_limit_ends_without_success_but_keeps_the_rest():
    positions, actions = walk([3.0, 0.0, 1.0], "f" * 2 + "b" * 600)
    m = navbench(positions, actions, GT, max_steps=500)
    ref = run_reference(positions, actions, geodesic, GT, max_steps=500)
    assert_same(m, ref)
    assert m["steps_taken"] == 500 and m["success"] == 0 and m["oracle_success"] == 1 and m["ndtw"] > 0


def test_random_walks_match_the_reference():
    rng = random.Random(7)
    for _ in range(25):
        pos, positions, actions = np.array([rng.uniform(-1, 1), 0.0, rng.uniform(0, 2)]), [], []
        positions.append(pos.tolist())
        heading = rng.uniform(0, 2 * math.pi)
        for _ in range(rng.randint(1, 80)):
            a = rng.choice([1, 1, 1, 2, 3])
            if a == 1 and rng.random() < 0.8:
                pos = pos + 0.25 * np.array([math.cos(heading), 0, math.sin(heading)])
            elif a != 1:
                heading += (0.26 if a == 2 else -0.26)
            positions.append(pos.tolist())
            actions.append(a)
        if rng.random() < 0.7:
            positions.append(pos.tolist())
            actions.append(0)
        gt = [[rng.uniform(-2, 5), 0.0, rng.uniform(-1, 3)] for _ in range(rng.randint(1, 40))]
        assert_same(navbench(positions, actions, gt), run_reference(positions, actions, geodesic, gt))


def test_ndtw_points_drop_consecutive_repeats_only():
    a, b = [0, 0, 0], [0.25, 0, 0]
    assert ndtw_points([a, a, b, b, a, a]) == [a, b, a]
    # float32 as habitat holds positions: differences below float32's resolution are repeats
    assert ndtw_points([[1.0, 0, 0], [1.0 + 1e-9, 0, 0]]) == [[1.0, 0, 0]]


def test_exact_dtw_matches_a_brute_force_recursion_and_fastdtw_can_differ():
    from fastdtw import dtw as fastdtw_exact

    rng = random.Random(3)

    def brute(a, b):
        from functools import lru_cache

        @lru_cache(None)
        def d(i, j):
            c = math.dist(a[i], b[j])
            if i == 0 and j == 0:
                return c
            opts = [d(i - 1, j) if i else math.inf, d(i, j - 1) if j else math.inf,
                    d(i - 1, j - 1) if i and j else math.inf]
            return c + min(opts)
        return d(len(a) - 1, len(b) - 1)

    differs = False
    for _ in range(30):
        a = [[rng.uniform(0, 5), 0, rng.uniform(0, 5)] for _ in range(rng.randint(1, 12))]
        b = [[rng.uniform(0, 5), 0, rng.uniform(0, 5)] for _ in range(rng.randint(1, 12))]
        exact = dtw_distance(a, b)
        assert exact == pytest.approx(brute(a, b))
        assert exact == pytest.approx(fastdtw_exact(a, b, dist=lambda x, y: math.dist(x, y))[0])
        differs |= ndtw(a, b) != pytest.approx(ndtw(a, b, exact=True))
        assert ndtw(a, b) <= ndtw(a, b, exact=True) + 1e-12  # an approximation never beats the optimum
    assert differs  # radius 1 is an approximation, and the scripted cases show it


def test_path_length_is_euclidean_3d():
    assert vlnce_path_length([[0, 0, 0], [3, 4, 0], [3, 4, 0], [3, 4, 12]]) == pytest.approx(17.0)
    assert vlnce_path_length([[1, 2, 3]]) == 0.0


def test_without_gt_the_dtw_measures_are_nan():
    positions, actions = walk([0.0, 0.0, 1.0], "ffs")
    m = navbench(positions, actions, None)
    assert math.isnan(m["ndtw"]) and math.isnan(m["sdtw"]) and m["steps_taken"] == 3
