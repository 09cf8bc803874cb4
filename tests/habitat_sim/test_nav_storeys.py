"""PathFinder on a two-storey house: points on either storey and on the flight between them are located, a goal
upstairs is measured over the stairs as navbench's env measures it, and the agent climbs them; without stairs
the upper storey is navigable but unreachable."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from navbench.habitat_sim.nav import MultiGoalShortestPath, PathFinder, ShortestPath

sys.path.insert(0, str(Path(__file__).parents[1] / "scene"))
from storeys import RISE, UPPER, X0, X1, house  # noqa: E402

START, GOAL = [1.0, 0.0, 2.6], [9.0, UPPER, 2.6]
ON_FLIGHT = [5.0, 7 * RISE, 2.6]  # on the 7th tread
UPSTAIRS = ([1.0, UPPER, 1.0], [9.0, UPPER, 5.0])  # an episode on the upper storey, round the stairwell
FACING_PLUS_X = [0.0, -math.sqrt(0.5), 0.0, math.sqrt(0.5)]


@pytest.fixture(scope="module", params=["stairs", None])
def setup(request, tmp_path_factory):
    """(join, PathFinder over the house, navbench's own PointNav env on it with the same body)."""
    import json

    from navbench.env.config import EnvConfig
    from navbench.env.pointnav import PointNavEnv
    from navbench.scene.cache import load_scene_and_navgrid

    join = request.param
    d = tmp_path_factory.mktemp(f"house_{join}")
    house(join).export(d / "house.glb")
    episodes = {"episodes": [{"episode_id": str(k), "scene_id": "house.glb", "start_position": start,
                              "start_rotation": FACING_PLUS_X, "goals": [{"position": goal, "radius": None}],
                              "info": {}} for k, (start, goal) in enumerate([(START, GOAL), UPSTAIRS])]}
    (d / "eps.json").write_text(json.dumps(episodes))
    env = PointNavEnv(d / "eps.json", scene_dir=d, config=EnvConfig(rgb=False, depth=False))
    asset, grid = load_scene_and_navgrid(d / "house.glb", env.nav_config)
    pf = PathFinder()
    pf.load_grid(grid, None, asset)
    yield join, pf, env
    env.close()


def test_points_on_each_storey_and_on_the_flight_are_located(setup):
    join, pf, _ = setup
    assert pf.is_navigable(GOAL) and np.allclose(np.asarray(pf.snap_point(GOAL)), GOAL, atol=1e-6)
    assert pf.is_navigable(START)
    assert pf.is_navigable(ON_FLIGHT) == (join == "stairs")
    if join == "stairs":  # the tread's own height
        assert np.asarray(pf.snap_point(ON_FLIGHT))[1] == pytest.approx(7 * RISE, abs=1e-3)
    assert pf.island_radius(GOAL) > 3.0


def test_goal_upstairs_is_measured_over_the_stairs_as_navbenchs_env_does(setup):
    join, pf, env = setup
    _, info = env.reset(options={"episode": 0})
    path = ShortestPath()
    # navbench's env starts an episode across storeys on its start's span centre: the same start, the same d0
    path.requested_start, path.requested_end = env.agent_position, GOAL
    reached = pf.find_path(path)
    assert reached == (join == "stairs")
    assert path.geodesic_distance == pytest.approx(info["distance_to_goal"], abs=1e-9)
    if join is None:
        assert path.geodesic_distance == math.inf and path.points == []
        return
    path.requested_start = START  # the declared start, 3.5 cm from that centre
    assert pf.find_path(path) and path.geodesic_distance == pytest.approx(info["distance_to_goal"], abs=0.036)
    pts = np.array([np.asarray(p, np.float64) for p in path.points])
    assert np.allclose(pts[0], START, atol=1e-6) and np.allclose(pts[-1], GOAL, atol=1e-6)
    # it climbs, over the flight only, no steeper than the flight's pitch line (35 deg)
    d = np.diff(pts, axis=0)
    assert np.all(d[:, 1] >= -1e-6) and np.all(d[:, 1] <= 0.7 * np.hypot(d[:, 0], d[:, 2]) + 1e-6)
    assert np.all((pts[:, 1] < 0.01) | ((pts[:, 0] >= X0 - 0.5) & (pts[:, 0] <= X1 + 0.5)) | (pts[:, 1] > UPPER - 0.01))
    length = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())
    assert path.geodesic_distance * 0.97 <= length <= path.geodesic_distance * 1.05
    multi = MultiGoalShortestPath()
    multi.requested_start = START
    multi.requested_ends = np.array([[60.0, 0.0, 60.0], GOAL, [1.0, UPPER, 5.5]], np.float32)
    assert pf.find_path(multi) and multi.closest_end_point_index == 1


def test_an_episode_upstairs_is_measured_on_the_upper_storeys_grid_as_navbenchs_env_does(setup):
    _, pf, env = setup
    _, info = env.reset(options={"episode": 1})
    assert not env.crosses_storeys and env.navgrid.floor_height == pytest.approx(UPPER, abs=0.01)
    path = ShortestPath()
    path.requested_start, path.requested_end = UPSTAIRS
    assert pf.find_path(path) and path.geodesic_distance == pytest.approx(info["distance_to_goal"], abs=1e-9)
    assert all(abs(float(p[1]) - UPPER) < 0.01 for p in path.points)


def test_agent_climbs_the_stairs_with_try_step(setup):
    join, pf, _ = setup
    p = np.array(START)
    heights = []
    for _ in range(34):  # 8.5 m along the flight's axis, 0.25 m a step
        p = np.asarray(pf.try_step(p, p + [0.25, 0.0, 0.0]), np.float64)
        heights.append(p[1])
    if join is None:
        assert max(heights) == 0.0  # nothing joins the storeys: the ground floor's edge stops it
        return
    assert heights[-1] == pytest.approx(UPPER, abs=1e-6) and p[0] == pytest.approx(9.5)
    # climbs only, a tread or two a step (the grid reports its first tread, within a step of the floor, at the
    # floor's height)
    assert all(0.0 <= b - a <= 2 * RISE + 1e-9 for a, b in zip([0.0, *heights], heights))


def test_topdown_view_slices_by_height(setup):
    join, pf, _ = setup
    lo = np.asarray(pf.get_bounds()[0], np.float64)

    def at(view, x, z):
        return bool(view[int((z - lo[2]) / 0.1), int((x - lo[0]) / 0.1)])

    upper, ground, flight = (pf.get_topdown_view(0.1, h) for h in (UPPER, 0.0, 7 * RISE))
    assert at(upper, 9.0, 2.6) and not at(upper, 5.0, 2.6)  # the upper floor, not the stairwell under it
    assert at(ground, 9.0, 2.6) and at(ground, 1.0, 2.6)
    assert at(flight, 5.0, 2.6) == (join == "stairs")


def test_only_a_joining_stair_sends_a_stopped_step_over_the_joined_surfaces(setup):
    join, pf, _ = setup
    assert pf._multi_storey()
    # both storeys' floors are walkable in either house; only the flight joins them
    assert pf._stairs_join(pf.grid) == (join == "stairs")
