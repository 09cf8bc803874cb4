"""The memory agent on image and language goals: the localiser's query for each task's goal, and GOAT-Bench's
subtasks answered one after another from one memory, each closed with SUBTASK_STOP where it would STOP."""

import numpy as np
import pytest

import navbench
from navbench.agents.memory_agent import MemoryAgent, MemoryAgentConfig
from navbench.agents.perceive import goal_query
from navbench.env.config import STOP, TURN_LEFT
from navbench.episodes.goat import SUBTASK_STOP, load_goat
from navbench.episodes.instance_imagenav import load_instance_imagenav
from navbench.localize.backends.oracle import centre_instance
from navbench.paths import SCENES_DIR, split_file
from navbench.scene.asset import load_scene
from tests.agents.test_memory_agent import ENV, EPISODE, ScriptedPolicy, cand, obs_at, plane_points, wall_depth


def _asset(ep):
    return lambda: load_scene(SCENES_DIR / ep.scene_id)


def test_an_objectnav_goal_is_its_category_text():
    query, positions = goal_query(EPISODE)
    assert (query.type, query.text, positions) == ("object", "chair", None)


def test_an_instance_goal_is_its_goal_image_not_its_category():
    ep = load_instance_imagenav(split_file("instance_imagenav", "val")).episodes[0]
    query, _ = goal_query(ep, asset=_asset(ep))
    assert query.type == "image" and query.text is None and query.image.shape == (224, 224, 3)
    assert centre_instance(query.image_ids) == int(ep.goal_object_id)  # oracle perception's view of the image


def test_each_goat_subtask_asks_its_own_goal():
    ep = load_goat(split_file("goat", "val")).episodes[0]
    for k, task in enumerate(ep.tasks):
        query, positions = goal_query(ep, k, _asset(ep))
        assert query.type == {"object": "object", "description": "language", "image": "image"}[task.type]
        if task.type == "object":
            assert query.text == task.category
        if task.type == "description":
            assert query.text == ep.descriptions[k]
        if task.type == "image":
            assert centre_instance(query.image_ids) == task.instance_id
        assert positions == [list(g.position) for g in ep.subtask_goals[k]]


class _Goat:
    """A GOAT-Bench episode's shape as the agent reads it (three subtasks)."""

    def __init__(self):
        from navbench.episodes.goat import GoatEpisode, GoatSubtask
        self.episode = GoatEpisode("0", EPISODE.scene_id, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0],
                                   tasks=[GoatSubtask("chair", "object", 1), GoatSubtask("bed", "object", 2),
                                          GoatSubtask("sofa", "object", 3)])


def test_goat_subtasks_are_closed_with_subtask_stop_and_asked_in_turn():
    asked = []

    def localize(ep, subtask=None):
        asked.append(subtask)
        return [cand(plane_points(-0.7))]

    policy = ScriptedPolicy(TURN_LEFT)
    agent = MemoryAgent(localize, policy, MemoryAgentConfig(), ENV, seed=1)
    goat = _Goat().episode
    agent.reset(goat)
    actions = [agent.act(obs_at(wall_depth(0.7))) for _ in range(3)]
    assert actions == [SUBTASK_STOP] * 3 and STOP not in actions  # a plain STOP would end the whole episode
    assert asked == [0, 1, 2]  # one localisation per subtask, from the memory the localiser keeps
    log = agent.episode_log()
    assert [s["subtask"] for s in log["subtasks"]] == [0, 1, 2]
    assert [e["subtask"] for e in log["events"] if e["event"] == "subtask_stop"] == [0, 1, 2]
    assert len(set(map(str, policy.seeds))) == 3  # the policy starts each subtask afresh


def test_a_goat_subtask_starts_with_its_own_state():
    far, near = cand(plane_points(-6.0)), cand(plane_points(-0.7))
    goals = {0: [near], 1: [far]}
    agent = MemoryAgent(lambda ep, subtask=0: goals[subtask], ScriptedPolicy(TURN_LEFT), MemoryAgentConfig(), ENV)
    agent.reset(_Goat().episode)
    agent.rejected.add(123)
    assert agent.act(obs_at(wall_depth(0.7))) == SUBTASK_STOP
    assert agent.rejected == set() and agent.current == 0 and agent.candidates == [far]
    assert np.allclose(agent.goal[2], -6.0, atol=0.5)


def test_objectnav_logs_keep_their_shape():
    agent = MemoryAgent(lambda ep: [cand(plane_points(-0.7))], ScriptedPolicy(TURN_LEFT), MemoryAgentConfig(), ENV)
    agent.reset(EPISODE)
    assert agent.act(obs_at(wall_depth(0.7))) == STOP
    assert list(agent.episode_log())[:3] == ["candidates", "routes", "events"]


@pytest.mark.slow
def test_the_memory_agent_answers_every_goat_subtask_from_one_memory(tmp_path):
    summary = navbench.evaluate("memory", task="goat", per_scene=1, limit=1, out=tmp_path / "run")
    assert summary["num_episodes"] == 1 and summary["num_failed"] == 0
    import json
    rec = json.loads((tmp_path / "run" / "episodes.jsonl").read_text().splitlines()[0])
    n = len(rec["subtask_success"])
    assert rec["trace"]["actions"].count("6") == n and "0" not in rec["trace"]["actions"]
    assert [s["subtask"] for s in rec["log"]["subtasks"]] == list(range(n))
    assert len({s["memory_build_s"] for s in rec["log"]["subtasks"]}) == 1  # one memory for every subtask


def test_the_live_detector_looks_for_an_instance_goal_by_its_images_caption():
    """The frontier agent's detector: the caption the localiser would prompt with, not the file's category."""
    from navbench.agents.perceive import LiveDetector, PerceptionConfig
    from navbench.localize.describe import ground

    ep = load_instance_imagenav(split_file("instance_imagenav", "val")).episodes[0]
    det = LiveDetector(SCENES_DIR)
    det.reset(ep)
    assert det.query != ep.object_category and ep.object_category.replace("_", " ") in det.query
    assert ground(det.query, load_scene(SCENES_DIR / ep.scene_id).objects) == [int(ep.goal_object_id)]
    det.reset(EPISODE)
    assert det.query == "chair" and PerceptionConfig().perception == "oracle"


def test_the_live_detector_looks_for_each_goat_subtasks_goal():
    """The frontier agent's detector on GOAT-Bench: a subtask's category, its description text, or its goal
    image's caption (the localiser's prompts)."""
    from navbench.agents.perceive import LiveDetector

    ep = load_goat(split_file("goat", "val")).episodes[0]
    assert {t.type for t in ep.tasks} == {"object", "description", "image"}
    det = LiveDetector(SCENES_DIR)
    for k, task in enumerate(ep.tasks):
        det.reset(ep, subtask=k)
        if task.type == "object":
            assert det.query == task.category
        elif task.type == "description":
            assert det.query == ep.descriptions[k].strip()
        else:
            assert det.query not in (task.category, "") and task.category.replace("_", " ") in det.query
