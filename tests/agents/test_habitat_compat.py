"""Agents written against ``habitat.Agent`` run unchanged: ``reset()`` without the episode, ``act``
returning an id, a name or ``{"action": ...}``, habitat-baselines' constructor arguments."""

import json
import os
import sys
import textwrap
import warnings

import numpy as np
import pytest

import navbench
from navbench.agents.habitat_compat import HabitatAgent, action_id, adapt, check_agent
from navbench.cli import main
from navbench.eval.rundir import RunError

# A stand-in for habitat-lab's `habitat.Agent` and habitat-baselines' simple agents, written the way those
# files are: an abstract base whose reset() takes no episode, actions from a HabitatSimActions namespace
# returned as {"action": id}, and a GoalFollower built with (success_distance, goal_sensor_uuid) that
# turns towards the goal's bearing and steps forward once within 15 degrees of it.
HABITAT_MODULE = textwrap.dedent('''
    from math import pi
    from typing import Any, Dict, Union

    import numpy as np


    class Agent:
        def reset(self) -> None:
            raise NotImplementedError

        def act(self, observations) -> Union[int, str, Dict[str, Any]]:
            raise NotImplementedError


    class _SimActions:
        STOP, MOVE_FORWARD, TURN_LEFT, TURN_RIGHT = 0, 1, 2, 3
        stop, move_forward, turn_left, turn_right = 0, 1, 2, 3


    HabitatSimActions = _SimActions()


    class RandomAgent(Agent):
        def __init__(self, success_distance: float, goal_sensor_uuid: str) -> None:
            self.dist_threshold_to_stop = success_distance
            self.goal_sensor_uuid = goal_sensor_uuid

        def reset(self) -> None:
            pass

        def is_goal_reached(self, observations):
            return observations[self.goal_sensor_uuid][0] <= self.dist_threshold_to_stop

        def act(self, observations):
            if self.is_goal_reached(observations):
                return {"action": HabitatSimActions.STOP}
            choice = np.random.choice([HabitatSimActions.MOVE_FORWARD, HabitatSimActions.TURN_LEFT,
                                       HabitatSimActions.TURN_RIGHT])
            return {"action": choice}


    class GoalFollower(RandomAgent):
        def __init__(self, success_distance: float, goal_sensor_uuid: str) -> None:
            super().__init__(success_distance, goal_sensor_uuid)
            self.pos_th = self.dist_threshold_to_stop
            self.angle_th = float(np.deg2rad(15))

        def normalize_angle(self, angle):
            if angle < -pi:
                angle = angle + 2.0 * pi
            if angle > pi:
                angle = angle - 2.0 * pi
            return angle

        def turn_towards_goal(self, angle_to_goal):
            if angle_to_goal > pi or -pi < angle_to_goal < 0:
                return HabitatSimActions.TURN_RIGHT
            return HabitatSimActions.TURN_LEFT

        def act(self, observations):
            if self.is_goal_reached(observations):
                action = HabitatSimActions.STOP
            else:
                angle = self.normalize_angle(np.array(observations[self.goal_sensor_uuid][1]))
                action = HabitatSimActions.MOVE_FORWARD if abs(angle) < self.angle_th else \\
                    self.turn_towards_goal(angle)
            return {"action": action}


    class NamedFollower(GoalFollower):
        """Answers with Habitat's action names, upper-case as older habitat-lab spells them."""
        names = ("STOP", "MOVE_FORWARD", "TURN_LEFT", "TURN_RIGHT")

        def act(self, observations):
            return self.names[super().act(observations)["action"]]


    class FlyingAgent(Agent):
        def reset(self):
            pass

        def act(self, observations):
            return {"action": "fly"}


    class TwoArgReset(Agent):
        def reset(self, episode, other):
            pass

        def act(self, observations):
            return 0


    class NoObsAct(Agent):
        def reset(self):
            pass

        def act(self):
            return 0
''')


@pytest.fixture
def habitat_dir(tmp_path, monkeypatch):
    root = tmp_path / "hab"
    root.mkdir()
    (root / "simple_agents_standin.py").write_text(HABITAT_MODULE)
    monkeypatch.syspath_prepend(str(root))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(root), os.environ.get("PYTHONPATH", "")]))
    yield root
    sys.modules.pop("simple_agents_standin", None)


@pytest.mark.parametrize("answer, expected", [
    (2, 2), (np.int64(3), 3), ("move_forward", 1), ("STOP", 0), ("Turn_Right", 3), ({"action": 2}, 2),
    ({"action": "turn_left", "action_args": {}}, 2), ({"action": np.int64(1)}, 1), (7, 7),
    ("look_up", 4), ({"action": "LOOK_DOWN"}, 5),  # Habitat's ids; the env's action space decides if they run
    ("subtask_stop", 6), ({"action": "SUBTASK_STOP"}, 6),  # GOAT-Bench's
])
def test_every_habitat_answer_becomes_its_id(answer, expected):
    assert action_id(answer) == expected  # an id is passed as is: the runner checks its range


@pytest.mark.parametrize("answer, needle", [
    ({"action": "fly"}, "act returned {'action': 'fly'}: 'fly' is not an action"),
    ("jump", "'jump' is not an action"),
    ({"move": 1}, "a dict needs an 'action' key"),
])
def test_an_answer_naming_no_action_says_what_was_returned_and_what_is_allowed(answer, needle):
    with pytest.raises(ValueError, match="expected an action id 0-6, a name") as exc:
        action_id(answer)
    assert needle in str(exc.value) and "move_forward" in str(exc.value)


def test_reset_gets_the_episode_only_if_it_takes_one():
    seen = []

    class Habitat:
        def reset(self):
            seen.append("no-arg")

        def act(self, obs):
            return "stop"

    class Navbench:
        sensors = ("depth",)

        def reset(self, episode):
            seen.append(episode)

        def act(self, obs):
            return 1

    a, b = adapt(Habitat()), adapt(Navbench())
    a.reset("ep"), b.reset("ep")
    assert seen == ["no-arg", "ep"] and a.act({}) == 0 and b.act({}) == 1 and b.sensors == ("depth",)
    assert isinstance(a, HabitatAgent) and adapt(a) is a


@pytest.mark.slow  # an end-to-end run (seconds to tens of seconds): make test-slow
def test_goal_follower_runs_unchanged_from_the_cli_and_evaluate(habitat_dir, pointnav10_file, tmp_path):
    out = tmp_path / "cli"
    assert main(["run", "--episodes", str(pointnav10_file), "--agent", "simple_agents_standin:GoalFollower",
                 "--workers", "1", "-q", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["num_episodes"] == 10 and summary["num_failed"] == 0 and summary["success"] > 0

    import simple_agents_standin as hab
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no failed episode, so no warning
        api = navbench.evaluate(hab.GoalFollower, episodes=pointnav10_file, out=tmp_path / "api")
    assert api["num_failed"] == 0 and api["success"] == summary["success"]
    named = navbench.evaluate(hab.NamedFollower(0.2, "pointgoal_with_gps_compass"), episodes=pointnav10_file,
                              out=tmp_path / "named")
    assert named["num_failed"] == 0 and named["spl"] == summary["spl"]


@pytest.mark.parametrize("name, needle", [
    ("TwoArgReset", "reset(episode, other) cannot be called as reset() or reset(episode)"),
    ("NoObsAct", "act() cannot be called as act(observations)"),
])
def test_a_signature_that_cannot_work_is_refused_before_the_run(habitat_dir, pointnav_file, tmp_path, name,
                                                                  needle, capsys):
    out = tmp_path / "run"
    assert main(["run", "--episodes", str(pointnav_file), "--agent", f"simple_agents_standin:{name}",
                 "--workers", "1", "-q", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and needle in err, err
    assert not out.exists()
    import simple_agents_standin as hab
    with pytest.raises(ValueError, match="cannot be called"):
        navbench.evaluate(getattr(hab, name), episodes=pointnav_file, out=tmp_path / "api")
    with pytest.raises(ValueError, match="cannot be called"):
        check_agent("x", getattr(hab, name)())


def test_evaluate_warns_of_failed_episodes_and_fail_fast_raises(habitat_dir, pointnav_file, tmp_path):
    import simple_agents_standin as hab
    with pytest.warns(RuntimeWarning, match=r"episode\(s\) failed .*'fly' is not an action") as caught:
        summary = navbench.evaluate(hab.FlyingAgent, episodes=pointnav_file, out=tmp_path / "warn")
    assert summary["num_failed"] == summary["num_episodes"] > 0 and len(caught) == 1
    with pytest.raises(RunError, match="'fly' is not an action; expected an action id 0-6"):
        navbench.evaluate(hab.FlyingAgent, episodes=pointnav_file, out=tmp_path / "fast", fail_fast=True)
