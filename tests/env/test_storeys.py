"""Cross-storey episodes in the env: a goal upstairs is measured through the stairs (or the ramp), the agent
climbs them, and a goal on a storey nothing joins is unreachable."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from navbench.env.config import MOVE_FORWARD, STOP, EnvConfig
from navbench.env.pointnav import PointNavEnv

sys.path.insert(0, str(Path(__file__).parents[1] / "scene"))
from storeys import BUILDINGS, RISE, UPPER, X0, X1, building, building_name, building_pairs, drive, house

START, GOAL = [1.0, 0.0, 2.6], [9.0, UPPER, 2.6]
FACING_PLUS_X = [0.0, -math.sqrt(0.5), 0.0, math.sqrt(0.5)]  # yaw -90 deg: the agent faces +x


def _episodes(tmp_path: Path, join: str | None) -> Path:
    house(join).export(tmp_path / f"{join}.glb")
    data = {"episodes": [{"episode_id": "0", "scene_id": f"{join}.glb", "start_position": START,
                          "start_rotation": FACING_PLUS_X, "goals": [{"position": GOAL, "radius": None}],
                          "info": {}}]}
    path = tmp_path / f"{join}.json"
    path.write_text(json.dumps(data))
    return path


@pytest.mark.parametrize("join", ["stairs", "ramp"])
def test_goal_upstairs_is_measured_and_reached_over_the_join(tmp_path, join):
    env = PointNavEnv(_episodes(tmp_path, join), scene_dir=tmp_path, config=EnvConfig(rgb=False, depth=False))
    _, info = env.reset(options={"episode": 0})
    rise = RISE / 2 if join == "stairs" else 0.0  # stairs: the pitch line through the risers' middles
    pts = np.array([START, [X0, rise, 2.6], [X1, UPPER - rise, 2.6], GOAL])
    analytic = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())
    assert info["distance_to_goal"] == pytest.approx(analytic, rel=0.03)
    heights = []
    for _ in range(32):  # 8 m straight along the flight's axis, 0.25 m a step
        _, _, _, _, info = env.step(MOVE_FORWARD)
        heights.append(env.agent_position[1])
    assert info["collisions"] == 0 and heights[-1] == pytest.approx(UPPER)
    assert all(b >= a - 1e-9 and b - a <= 0.2 + 1e-9 for a, b in zip([0.0, *heights], heights))  # climbs only
    _, _, done, _, info = env.step(STOP)
    assert done and info["success"] == 1.0
    # Path length is 3-D: the climb counts, so it is the analytic path's length to the lattice's error.
    assert info["path_length"] == pytest.approx(analytic, rel=0.03) and info["spl"] > 0.95


def test_goal_on_a_storey_nothing_joins_is_unreachable(tmp_path):
    env = PointNavEnv(_episodes(tmp_path, None), scene_dir=tmp_path, config=EnvConfig(rgb=False, depth=False))
    _, info = env.reset(options={"episode": 0})
    assert info["distance_to_goal"] == math.inf
    for _ in range(40):
        env.step(MOVE_FORWARD)
    assert env.agent_position[1] == pytest.approx(0.0)  # the ground floor's edge stops it
    _, _, _, _, info = env.step(STOP)
    assert info["success"] == 0.0


@pytest.mark.parametrize("join", ["stairs", "ramp"])
@pytest.mark.parametrize(("start", "goal"), [([1.0, 0.0, 1.0], [8.5, UPPER, 5.0]),
                                           ([9.0, UPPER, 1.0], [1.0, 0.0, 5.0])])
def test_oracle_climbs_to_a_goal_upstairs_and_back_down(tmp_path, join, start, goal):
    from navbench.agents.oracle import OracleAgent

    house(join).export(tmp_path / f"{join}.glb")
    data = {"episodes": [{"episode_id": "0", "scene_id": f"{join}.glb", "start_position": start,
                          "start_rotation": [0.0, 0.0, 0.0, 1.0], "goals": [{"position": goal, "radius": None}],
                          "info": {}}]}
    (tmp_path / "eps.json").write_text(json.dumps(data))
    config = EnvConfig(rgb=False, depth=False)
    env = PointNavEnv(tmp_path / "eps.json", scene_dir=tmp_path, config=config)
    obs, info = env.reset(options={"episode": 0})
    agent = OracleAgent(tmp_path, env.success_distance, config)
    agent.reset(env.episode)
    d0 = info["distance_to_goal"]
    assert math.isfinite(d0) and d0 > 8.0
    info = drive(env, agent, obs)
    assert info["success"] == 1.0 and info["spl"] > 0.9, info


@pytest.mark.parametrize("join", ["stairs", None])
def test_objectnav_category_on_two_storeys_scores_against_the_reachable_instance(tmp_path, join):
    """Chairs on both storeys: one 0.3 m (in xz) above the start, one upstairs beyond the flight, one far
    away on the ground floor. With stairs the one beyond the flight is nearest by path; without, neither
    upstairs chair counts and the ground floor's is the goal."""
    from navbench.agents.oracle import OracleAgent
    from navbench.env.objectnav import ObjectNavEnv

    name = join or "none"
    house(join).export(tmp_path / f"{name}.glb")
    chairs = [[1.3, UPPER, 2.6], [8.5, UPPER, 2.6], [9.5, 0.0, 5.5]]
    goals = [{"object_id": i, "object_category": "chair", "position": [p[0], p[1] + 0.5, p[2]],
              "view_points": [{"agent_state": {"position": p, "rotation": [0.0, 0.0, 0.0, 1.0]}, "iou": 1.0}]}
             for i, p in enumerate(chairs)]
    data = {"episodes": [{"episode_id": "0", "scene_id": f"{name}.glb", "start_position": START,
                          "start_rotation": FACING_PLUS_X, "object_category": "chair", "goals": goals, "info": {}}]}
    (tmp_path / "eps.json").write_text(json.dumps(data))
    config = EnvConfig(rgb=False, depth=False)
    env = ObjectNavEnv(tmp_path / "eps.json", scene_dir=tmp_path, config=config)
    obs, info = env.reset(options={"episode": 0})
    if join == "stairs":
        pts = np.array([START, [X0, RISE / 2, 2.6], [X1, UPPER - RISE / 2, 2.6], chairs[1]])
        expected, end_y = float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()), UPPER
    else:
        expected, end_y = math.dist(START, chairs[2]), 0.0
    assert info["distance_to_goal"] == pytest.approx(expected, rel=0.03)
    agent = OracleAgent(tmp_path, env.success_distance, config)
    agent.reset(env.episode)
    info = drive(env, agent, obs)
    assert info["success"] == 1.0 and env.agent_position[1] == pytest.approx(end_y), info


@pytest.mark.parametrize(("join", "start", "goal"), [("stairs", [1.0, 0.0, 1.0], [8.5, UPPER, 5.0]),
                                                     ("ramp", [8.5, UPPER, 5.0], [1.0, 0.0, 1.0])])
def test_optimistic_agent_plans_over_the_join_to_a_goal_on_another_storey(tmp_path, join, start, goal):
    from navbench.agents.oracle import OptimisticOracleAgent

    house(join).export(tmp_path / f"{join}.glb")
    data = {"episodes": [{"episode_id": "0", "scene_id": f"{join}.glb", "start_position": start,
                          "start_rotation": [0.0, 0.0, 0.0, 1.0], "goals": [{"position": goal, "radius": None}],
                          "info": {}}]}
    (tmp_path / "eps.json").write_text(json.dumps(data))
    config = EnvConfig(rgb=False, depth=True, width=64, height=64)
    env = PointNavEnv(tmp_path / "eps.json", scene_dir=tmp_path, config=config)
    obs, info = env.reset(options={"episode": 0})
    agent = OptimisticOracleAgent(tmp_path, env.success_distance, config)
    agent.reset(env.episode)
    info = drive(env, agent, obs)
    assert info["success"] == 1.0 and info["spl"] > 0.9, info
    assert env.agent_position[1] == pytest.approx(goal[1], abs=1e-6)


def _inside_a_solid(mesh, p) -> bool:
    """Whether ``p`` (0.3 m above it) is inside a closed solid: the first face hit looking along +-x and +-z is a
    back face in at least three of the four directions."""
    origin = np.array([p[0], p[1] + 0.3, p[2]])
    dirs = np.array([[1.0, 0, 0], [-1.0, 0, 0], [0, 0, 1.0], [0, 0, -1.0]])
    _, ray, tri = mesh.ray.intersects_location(np.tile(origin, (4, 1)), dirs, multiple_hits=False)
    return int((np.einsum("ij,ij->i", mesh.face_normals[tri], dirs[ray]) > 0).sum()) >= 3


def _building_env(tmp_path: Path, join: str, angle: float, walled: bool):
    mesh = building(join, angle, walled)
    mesh.export(tmp_path / "b.glb")
    pairs = building_pairs(join, angle)
    eps = [{"episode_id": str(k), "scene_id": "b.glb", "start_position": a, "start_rotation": [0.0, 0.0, 0.0, 1.0],
            "goals": [{"position": b, "radius": None}], "info": {}} for k, (a, b) in enumerate(pairs)]
    (tmp_path / "eps.json").write_text(json.dumps({"episodes": eps}))
    config = EnvConfig(rgb=False, depth=False)
    return mesh, PointNavEnv(tmp_path / "eps.json", scene_dir=tmp_path, config=config), config


@pytest.mark.parametrize(("join", "angle", "walled"), BUILDINGS)
def test_composed_buildings_accept_every_start_and_measure_d0_as_detour(tmp_path, join, angle, walled):
    """Buildings of touching boxes (walls on slabs, a walled or open flight, ramps of 10-30 deg): every start on
    either storey is accepted and d0 to its goal on the other storey is within 3% of Detour's
    (``tests/scene/detour_buildings.json``, from ``PYTHONPATH=$PWD python benchmarks/detour_agreement.py
    --storeys DIR --json FILE``: habitat-sim's navmesh settings through ``shared/detour-anchor``)."""
    detour = json.loads((Path(__file__).parents[1] / "scene" / "detour_buildings.json").read_text())
    _, env, _ = _building_env(tmp_path, join, angle, walled)
    for k in range(len(env.dataset.episodes)):
        _, info = env.reset(options={"episode": k})
        assert info["distance_to_goal"] == pytest.approx(detour[f"{building_name(join, angle, walled)}-{k}"],
                                                         rel=0.03), k


@pytest.mark.parametrize(("join", "angle", "walled"),
                         [BUILDINGS[0], *(pytest.param(*b, marks=pytest.mark.slow) for b in BUILDINGS[1:])])
def test_the_oracle_climbs_composed_buildings_and_never_stands_in_a_wall(tmp_path, join, angle, walled):
    """The oracle reaches the goal on the other storey, up and down, without a recorded pose inside a solid."""
    from navbench.agents.oracle import OracleAgent

    mesh, env, config = _building_env(tmp_path, join, angle, walled)
    for k in (0, 4):  # up from the ground floor's far room, down from upstairs
        obs, info = env.reset(options={"episode": k})
        agent = OracleAgent(tmp_path, env.success_distance, config)
        agent.reset(env.episode)
        done, inside = False, 0
        while not done:
            obs, _, term, trunc, info = env.step(agent.act(obs))
            done = term or trunc
            inside += _inside_a_solid(mesh, env.agent_position)
        assert info["success"] == 1.0 and inside == 0, (k, info, inside)
