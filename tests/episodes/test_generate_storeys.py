"""Episodes on a two-storey house (tests/scene/storeys.py): view points on their object's storey, PointNav and
ObjectNav episodes that start on either storey with the layered geodesic the env measures, and goals on a storey
nothing joins never drawn."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from navbench.env.config import EnvConfig
from navbench.episodes.generate import SceneGoals, objectnav_episodes, pointnav_episodes
from navbench.episodes.io import save_dataset
from navbench.episodes.types import EpisodeDataset
from navbench.episodes.viewpoints import ViewPointFinder
from navbench.scene.cache import load_scene_and_layers

sys.path.insert(0, str(Path(__file__).parents[1] / "scene"))
from storeys import OBJECTS, UPPER, drive, write_house


@pytest.fixture(scope="module")
def scenes(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("storeys")
    for join in ("stairs", None):
        write_house(d, join)
    return d


@pytest.fixture(autouse=True)
def _cache(tmp_path_factory, monkeypatch):
    monkeypatch.setenv("NAVBENCH_CACHE", str(tmp_path_factory.getbasetemp() / "cache"))


def test_view_points_lie_on_their_objects_storey(scenes):
    asset, nav = load_scene_and_layers(scenes / "stairs.glb")
    finder = ViewPointFinder(asset, nav)
    (down, up, bed) = (finder.find(asset.objects[i])[0] for i, *_ in OBJECTS)
    assert len(down) and len(up) and len(bed)
    assert np.all(down[:, 1] == 0.0)
    assert np.allclose(up[:, 1], UPPER) and np.allclose(bed[:, 1], UPPER)  # never the floor below, nor the bed top
    # The chairs stand at the same xz on open floors, one above the other: the same view points, 2.8 m apart.
    assert np.array_equal(up[:, [0, 2]], down[:, [0, 2]])
    for p in up[::50]:  # each on the upper floor's own navigable surface
        s = nav.span_of(p, max_dist=0.0)
        assert s >= 0 and nav.height[s] == pytest.approx(UPPER)


def test_view_points_on_a_storey_nothing_joins_never_count(scenes):
    sg = SceneGoals(scenes / "none.glb", scenes, layered=True)
    chairs = sg.goals("chair")
    assert [g.object_id for g in chairs] == [1, 2]  # both have view points, each on its own storey
    start = np.array([1.45, 0.0, 2.6])  # 2 m in front of the lower chair, 2 m below-and-before the upper one
    lower = chairs[0].view_point_positions()
    both = np.concatenate([lower, chairs[1].view_point_positions()])
    assert sg.grid.geodesic_distance(start, both) == sg.grid.geodesic_distance(start, lower)
    assert sg.grid.geodesic_distance(start, chairs[1].view_point_positions()) == math.inf


def _env(scene_dir: Path, episodes: EpisodeDataset, task: str):
    from navbench.env.objectnav import ObjectNavEnv
    from navbench.env.pointnav import PointNavEnv

    path = scene_dir / f"{task}_eps.json.gz"
    save_dataset(episodes, path)
    config = EnvConfig(rgb=False, depth=False)
    env = (PointNavEnv if task == "pointnav" else ObjectNavEnv)(path, scene_dir=scene_dir, config=config)
    return env, config


def test_pointnav_episodes_start_on_either_storey_with_the_layered_geodesic(scenes):
    from navbench.agents.oracle import OracleAgent

    eps = pointnav_episodes(scenes / "stairs.glb", scenes, 12, np.random.default_rng(0), layered=True)
    again = pointnav_episodes(scenes / "stairs.glb", scenes, 12, np.random.default_rng(0), layered=True)
    assert eps == again  # seeded
    _, nav = load_scene_and_layers(scenes / "stairs.glb")
    starts = {round(e.start_position[1], 3) for e in eps}
    assert starts == {0.0, UPPER}
    cross = [e for e in eps if abs(e.start_position[1] - e.goals[0].position[1]) > 1.0]
    assert cross
    for e in eps:
        s, g = np.array(e.start_position), np.array(e.goals[0].position)
        geo = e.info["geodesic_distance"]
        assert geo == nav.distance_field(g).distance(s)  # what the env measures on the joined surfaces
        assert geo == pytest.approx(nav.geodesic_distance(s, g), rel=0.01)
        assert e.info["euclidean_distance"] == pytest.approx(float(np.linalg.norm(g - s)))  # 3-D, as Habitat's
        assert 1.0 <= geo <= 20.0

    # The env measures a cross-storey episode's d0 as the generator did, and the oracle climbs to its goal.
    ds = EpisodeDataset(episodes=cross[:1])
    env, config = _env(scenes, ds, "pointnav")
    obs, info = env.reset(options={"episode": 0})
    assert info["distance_to_goal"] == pytest.approx(cross[0].info["geodesic_distance"], abs=1e-9)
    agent = OracleAgent(scenes, env.success_distance, config)
    agent.reset(env.episode)
    info = drive(env, agent, obs)
    assert info["success"] == 1.0 and info["spl"] > 0.9, info
    assert env.agent_position[1] == pytest.approx(cross[0].goals[0].position[1], abs=1e-6)


def test_pointnav_goals_on_a_storey_nothing_joins_are_never_drawn(scenes):
    eps = pointnav_episodes(scenes / "none.glb", scenes, 8, np.random.default_rng(1), layered=True)
    assert {round(e.start_position[1], 3) for e in eps} == {0.0, UPPER}  # starts on both storeys...
    assert all(e.start_position[1] == e.goals[0].position[1] for e in eps)  # ...each with a goal on its own


def test_objectnav_episodes_score_against_the_reachable_instances(scenes):
    for join, name in (("stairs", "stairs"), (None, "none")):
        sg = SceneGoals(scenes / f"{name}.glb", scenes, layered=True)
        eps, table = objectnav_episodes(sg, ["chair", "bed"], 8, np.random.default_rng(2))
        for e in eps:
            goals = sg.goals(e.object_category)
            vps = np.concatenate([g.view_point_positions() for g in goals])
            s = np.array(e.start_position)
            assert e.info["geodesic_distance"] == sg.grid.distance_field(vps).distance(s)
            closest = next(g for g in goals if g.object_id == e.info["closest_goal_object_id"])
            assert math.isfinite(sg.grid.geodesic_distance(s, closest.view_point_positions()))
            if join is None:  # nothing joins the storeys: the goal is always on the start's own
                assert closest.position[1] - s[1] == pytest.approx(0.25 if closest.object_category == "chair"
                                                                   else 0.3, abs=1e-6)
        if join == "stairs":
            assert any(abs(e.start_position[1] - next(
                g for g in sg.goals(e.object_category) if g.object_id == e.info["closest_goal_object_id"]
            ).position[1]) > 2.0 for e in eps)  # some episode crosses the storeys
