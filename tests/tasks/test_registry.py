"""The task registry: every part of navbench reads a task from its definition, so a new one runs through the
env, the worker, the runner and the CLI without any of them naming it."""

import json

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

import navbench
from navbench.cli import build_parser, main
from navbench.env.make import task_env
from navbench.tasks import TASKS, GoalSensor, Task, get_task, task_names


def test_every_task_has_a_gym_id_a_bundled_default_split_and_a_known_default_agent():
    from navbench.agents.registry import AGENTS
    assert {"pointnav", "objectnav"} <= set(TASKS)
    for t in TASKS.values():
        assert t.gym_id.startswith("navbench/") and t.gym_id.endswith("-v0") and t.gym_id in gym.registry
        # a task that bundles no split (rxr_ce: RxR-CE's files are the user's) runs on the user's files only
        assert not t.splits or (t.default_split in t.splits and t.split_file(t.default_split).is_file()), t.name
        assert t.default_agent in AGENTS and t.goal_sensors and t.actions[0] == "STOP"
    # tasks may share a Gymnasium id (navbench/VLNCE-v0: r2r_ce, and rxr_ce with task="rxr_ce") only with one env
    envs: dict[str, set[str]] = {}
    for t in TASKS.values():
        envs.setdefault(t.gym_id, set()).add(t.env_class)
    assert all(len(v) == 1 for v in envs.values()) and sum(bool(t.splits) for t in TASKS.values()) >= 4


def test_unknown_task_is_one_line_naming_the_known_ones():
    with pytest.raises(ValueError, match="unknown task 'nope': choose from pointnav, objectnav"):
        get_task("nope")
    with pytest.raises(ValueError, match="unknown task"):
        navbench.evaluate("oracle", task="nope")


def test_a_task_definition_is_checked():
    with pytest.raises(ValueError, match="distance_to"):
        Task("x", "navbench/X-v0", "", "", (), distance_to="CENTRE")
    with pytest.raises(ValueError, match="default split"):
        Task("x", "navbench/X-v0", "", "", (), splits=("val",), default_split="test")


def test_every_task_flag_takes_its_choices_from_the_registry(capsys):
    parser = build_parser()
    for command in ("run", "serve-agent", "check-agent"):
        sub = parser._subparsers._group_actions[0].choices[command]
        flag = next(a for a in sub._actions if "--task" in a.option_strings)
        assert tuple(flag.choices) == task_names(), command
    assert main(["tasks"]) == 0
    out = capsys.readouterr().out
    for t in TASKS.values():
        line = next(ln for ln in out.splitlines() if ln.startswith(t.name + " "))
        assert t.gym_id in line and f" {t.max_steps} " in line
        assert line.split()[-2:] == [t.default_split or "--episodes", t.default_agent]
        assert f"{t.success_distance:g} m" in line


def test_objectnav_scores_ovon_style_splits_and_files_at_ovons_distance(objectnav_file):
    from navbench.api import resolve_episodes
    assert resolve_episodes("objectnav", "val_unseen", None)[3] == 0.25
    assert resolve_episodes(None, "select", None)[:2] == ("pointnav", "select")
    assert resolve_episodes(None, None, objectnav_file)[0] == "objectnav"
    assert resolve_episodes("pointnav", None, None)[3] == 0.2


# A task that exists only in this test: PointNav's episodes, the goal given as its Euclidean distance.
def _distance(ctx) -> np.ndarray:
    goal = np.asarray(ctx.episode.goals[0].position, np.float64)
    return np.array([np.linalg.norm((goal - ctx.agent_position)[[0, 2]])], np.float32)


def _distance_space(dataset, config) -> spaces.Box:
    return spaces.Box(0, np.inf, (1,), np.float32)


def _straight_line(ctx, info) -> dict:
    """A measure of the toy's own: the straight-line distance left, and whether STOP came within 1 m of it."""
    left = float(_distance(ctx)[0])
    return {"straight_line": left, "near_stop": float(info["stop_called"] and left < 1.0)}


TOY = Task(name="toydistance", gym_id="navbench/ToyDistance-v0", title="a toy", reference="none",
           goal_sensors=(GoalSensor("goal_distance", _distance_space, _distance),),
           measures=("distance_to_goal", "success", "spl", "soft_spl", "straight_line", "near_stop"),
           extra_info=_straight_line,
           success_distance=0.3, max_steps=40, splits=("val",), default_split="val", default_agent="oracle")


@pytest.fixture
def toy_task(monkeypatch):
    monkeypatch.setitem(TASKS, TOY.name, TOY)
    return TOY


def test_a_registered_task_runs_through_env_worker_and_runner_unchanged(toy_task, pointnav_file, tmp_path):
    env = task_env(toy_task.name, pointnav_file)
    obs, info = env.reset(seed=0)
    assert set(env.observation_space.spaces) >= {"goal_distance"} and "pointgoal_with_gps_compass" not in obs
    assert env.success_distance == 0.3 and env.config.max_steps == 40
    env.close()
    summary = navbench.evaluate("oracle", task=toy_task.name, episodes=pointnav_file, out=tmp_path / "run")
    cfg = json.loads((tmp_path / "run" / "config.json").read_text())
    assert summary["task"] == cfg["task"] == "toydistance" and cfg["success_distance"] == 0.3
    assert cfg["env"] == {"max_steps": 40}  # the task's step limit, recorded
    assert summary["success"] == 1.0 and summary["num_episodes"] > 0
    # the task's own measures: in every record (from the last info) and averaged in the summary
    records = [json.loads(line) for line in (tmp_path / "run" / "episodes.jsonl").read_text().splitlines()]
    assert all(r["near_stop"] == 1.0 and 0 <= r["straight_line"] < 0.3 for r in records)
    assert summary["near_stop"] == 1.0
    assert summary["straight_line"] == pytest.approx(sum(r["straight_line"] for r in records) / len(records))


def test_env_takes_its_action_list_and_limit_from_the_task(pointnav_file):
    env = task_env("pointnav", pointnav_file)
    assert env.actions == ("STOP", "MOVE_FORWARD", "TURN_LEFT", "TURN_RIGHT") and env.action_space.n == 4
    env.close()


@pytest.mark.parametrize("agent, task, fits", [("frontier", "imagenav", "objectnav"),
                                               ("frontier", "pointnav", "objectnav"),
                                               ("pointnav", "objectnav", "pointnav")])
def test_a_builtin_agent_is_refused_a_task_whose_goal_it_cannot_read(agent, task, fits, capsys):
    assert main(["run", "--task", task, "--agent", agent, "--limit", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"task '{task}' gives" in err[0] and f"--task {fits}" in err[0]


def test_frontier_is_refused_imagenav_naming_the_agents_that_run_it():
    from navbench.agents.registry import check_task
    from navbench.env.config import EnvConfig
    check_task("memory", "imagenav", EnvConfig())  # the memory agent reads imagegoal
    with pytest.raises(ValueError, match=r"\(imagenav's: memory\)"):
        check_task("frontier", "imagenav", EnvConfig())


def test_the_oracle_and_the_random_agent_run_any_task():
    from navbench.agents.registry import check_task
    from navbench.env.config import EnvConfig
    for name in TASKS:
        for agent in ("oracle", "random"):
            check_task(agent, name, EnvConfig())


def test_image_and_goat_task_definitions_state_their_readers_constants():
    from navbench.episodes import goat, instance_imagenav
    from navbench.tasks import goat as goat_task
    from navbench.tasks import instance_imagenav as iin_task
    assert (iin_task.SUCCESS_DISTANCE, iin_task.MAX_EPISODE_STEPS) == (instance_imagenav.SUCCESS_DISTANCE,
                                                                       instance_imagenav.MAX_EPISODE_STEPS)
    assert (goat_task.SUCCESS_DISTANCE, goat_task.MAX_EPISODE_STEPS, goat_task.DONE) == (
        goat.SUCCESS_DISTANCE, goat.MAX_EPISODE_STEPS, goat.DONE)
    assert goat_task.ACTIONS.index("SUBTASK_STOP") == goat.SUBTASK_STOP
