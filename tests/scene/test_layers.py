"""LayeredNav: two-storey houses joined by stairs (0.175 m risers) or a ramp, geodesics against hand-derived
3-D paths through them, and storeys that nothing joins."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from navbench.scene.layers import LayeredNav
from navbench.scene.navigability import NavGridConfig

sys.path.insert(0, str(Path(__file__).parent))
from storeys import RISE, UPPER, X0, X1, Z0, Z1, box, house


def path_length(*pts) -> float:
    p = np.asarray(pts, float)
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())


@pytest.fixture(scope="module")
def stairs() -> LayeredNav:
    return LayeredNav.from_mesh(house("stairs"))


@pytest.fixture(scope="module")
def ramp() -> LayeredNav:
    return LayeredNav.from_mesh(house("ramp"))


A, B = (1.0, 0.0, 2.6), (9.0, UPPER, 2.6)  # on the flight's axis, 2 m before it and 1.5 m beyond it


def test_stairs_join_the_storeys_and_measure_the_climb(stairs):
    # By hand: straight along the axis, up the stair's pitch line through the middles of the first and last
    # risers ((3.0, 0.0875) to (7.5, 2.7125): 15 treads of 0.3 m, 15 risers of 0.175 m).
    analytic = path_length(A, (X0, RISE / 2, 2.6), (X1, UPPER - RISE / 2, 2.6), B)
    assert analytic == pytest.approx(8.714, abs=1e-3)
    assert stairs.geodesic_distance(A, B) == pytest.approx(analytic, rel=0.03)
    assert stairs.geodesic_distance(B, A) == pytest.approx(analytic, rel=0.03)
    assert stairs.connected(A, B)


def test_ramp_joins_the_storeys_and_measures_its_slope(ramp):
    analytic = path_length(A, (X0, 0.0, 2.6), (X1, UPPER, 2.6), B)  # 2 + sqrt(4.5^2 + 2.8^2) + 1.5
    assert analytic == pytest.approx(8.800, abs=1e-3)
    assert ramp.geodesic_distance(A, B) == pytest.approx(analytic, rel=0.03)


def test_path_from_beside_the_flight_cuts_across_it(stairs):
    # Start on the ground 1 m before the foot and 1.6 m off the axis. Unfolded about the pitch line (the
    # flight's 4.5 m run stretched by k to its 3-D length) the shortest path is straight wherever it may be:
    # to the foot's corner of the navigable band (z = Z1 - r), then straight across the flight to B.
    r = NavGridConfig().agent_radius
    s, corner = (2.0, 0.0, 4.2), (X0, Z1 - r)
    k = math.hypot(X1 - X0, UPPER - RISE) / (X1 - X0)
    analytic = math.hypot(corner[0] - s[0], corner[1] - s[2]) + math.hypot(k * (X1 - X0) + B[0] - X1, corner[1] - B[2])
    assert analytic == pytest.approx(8.270, abs=1e-3)
    assert stairs.geodesic_distance(s, B) == pytest.approx(analytic, rel=0.03)


def test_flat_floor_geodesics_stay_straight_lines(stairs):
    for a, b in (((0.5, 0.0, 0.5), (9.5, 0.0, 1.6)), ((0.5, UPPER, 0.5), (9.5, UPPER, 1.6))):  # clear of the flight
        assert stairs.geodesic_distance(a, b) == pytest.approx(math.dist(a, b), rel=0.02)  # 32 directions: <= 1.3%


def test_storeys_nothing_joins_are_unreachable_from_each_other():
    nav = LayeredNav.from_mesh(house(None))
    assert nav.geodesic_distance(A, B) == math.inf
    assert not nav.connected(A, B)
    # A category on both storeys: the view point above the agent (0.3 m away in xz) never counts.
    above, far = (1.3, UPPER, 2.6), (9.0, 0.0, 2.6)
    assert nav.geodesic_distance(A, [above, far]) == pytest.approx(8.0, rel=0.01)


def test_goal_on_two_storeys_scores_against_the_nearer_by_path(stairs):
    # A view point right above the start (3 m of stairs away) and one 5.5 m away on the ground floor.
    up, ground = (1.0, UPPER, 1.0), (6.5, 0.0, 2.6 + 2.0)
    d_up = stairs.geodesic_distance(A, up)
    d_ground = stairs.geodesic_distance(A, ground)
    assert stairs.geodesic_distance(A, [up, ground]) == pytest.approx(min(d_up, d_ground))
    assert d_ground == pytest.approx(math.dist(A, ground), rel=0.015) and d_up > 8.0


def test_a_ledge_higher_than_max_climb_is_not_joined():
    # A 0.3 m platform: above the 0.2 m climb, so its top is its own surface.
    nav = LayeredNav.from_mesh(trimesh.util.concatenate([box((0, -0.1, 0), (4, 0, 4)), box((2, 0, 0), (4, 0.3, 4))]))
    assert nav.geodesic_distance((1.0, 0.0, 2.0), (3.0, 0.3, 2.0)) == math.inf
    low = LayeredNav.from_mesh(trimesh.util.concatenate([box((0, -0.1, 0), (4, 0, 4)), box((2, 0, 0), (4, 0.15, 4))]))
    assert low.geodesic_distance((1.0, 0.0, 2.0), (3.0, 0.15, 2.0)) == pytest.approx(math.hypot(2.0, 0.15), rel=0.02)


def test_radius_applies_on_the_stairs(stairs):
    # The flight is 1.2 m wide with open sides: its navigable middle is 1.2 - 2 x 0.18 m wide (to a cell).
    r = NavGridConfig().agent_radius
    for z, ok in ((2.6, True), (Z0 + r + 0.05, True), (Z0 + r - 0.08, False), (Z1 - r + 0.08, False)):
        s = stairs.span_of((5.0, 1.4, z), max_dist=0.0)
        assert (s >= 0) == ok, z


def test_field_under_a_goal_upstairs_is_the_path_not_the_drop(stairs):
    field = stairs.distance_field([(1.3, UPPER, 2.6)])
    below = field.distance((1.3, 0.0, 2.6))
    assert below == pytest.approx(stairs.geodesic_distance((1.3, 0.0, 2.6), (1.3, UPPER, 2.6)), rel=0.01)
    assert below > 10.0 and field.distance((1.3, UPPER, 2.7)) == pytest.approx(0.1, abs=1e-9)
    assert field.distance((1.3, UPPER, 2.83)) == pytest.approx(0.23, abs=1e-9)  # success is decided exactly
