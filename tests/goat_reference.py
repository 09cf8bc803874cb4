"""A line-by-line port of goat-bench's GOAT measures and task stepping, on a fake simulator, for tests only.

Transcribed from Ram81/goat-bench (74c41d1) ``goat_bench/measurements/nav.py`` (``GoatDistanceToGoal``
L133-234, ``GoatSuccess`` L237-320, ``GoatSPL`` L323-416, ``GoatSoftSPL`` L419-512) and
``goat_bench/task/goat_task.py`` (``GoatTask`` L73-113, ``SubtaskStopAction`` L116-130), with habitat-lab
v0.2.3's step order (``habitat/core/env.py`` ``Env.step``: task step, ``_check_episode_is_active``, measures
in config order, then the step limit). Kept apart from ``navbench.metrics.goat_metrics`` so each checks
the other: nothing here is shared with navbench.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np


class FakeSim:
    """An agent on a plane: MOVE_FORWARD 0.25 m along its heading, turns of 90 degrees, geodesic
    distance = the Euclidean distance to the nearest of the points asked for."""

    def __init__(self, position, heading=(0.0, 0.0, -1.0)):
        self.position = np.array(position, dtype=np.float64)
        self.heading = np.array(heading, dtype=np.float64)

    def get_agent_state(self):
        return self

    def act(self, action):
        if action == 1:
            self.position = self.position + 0.25 * self.heading
        elif action in (2, 3):  # about +y: left turns x toward -z
            x, _, z = self.heading
            self.heading = np.array([z, 0.0, -x]) if action == 2 else np.array([-z, 0.0, x])
        # 4, 5 (look up / down) leave the position as it is

    def geodesic_distance(self, position_a, position_b, episode=None):
        return float(min(np.linalg.norm(np.asarray(p, dtype=np.float64) - position_a) for p in position_b))


class Episode:
    def __init__(self, tasks, goals):
        self.tasks = tasks  # [[category, type, instance_id, image_index], ...]
        self.goals = goals  # per kept task: a list of {"view_points": [{"agent_state": {"position": ...}}]}
        self._shortest_path_cache = None


class StopAction:
    pass


class SubtaskStopAction:
    pass


class Measurements:
    def __init__(self):
        self.measures = {}


class GoatDistanceToGoal:
    cls_uuid = "distance_to_goal"

    def __init__(self, sim):
        self._previous_position = None
        self._sim = sim
        self._episode_view_points = None
        self._current_subtask_idx = 0
        self.prev_distance_to_target = 0

    def get_metric(self):
        return self._metric

    def reset_metric(self, episode, task):
        self._previous_position = None
        self._metric = {"distance_to_target": 0, "prev_distance_to_target": 0}
        self._current_subtask_idx = 0
        self.prev_distance_to_target = 0
        self.update_metric(episode=episode, task=task)

    def update_metric(self, episode, task):
        current_position = self._sim.get_agent_state().position

        self.prev_distance_to_target = self._metric["distance_to_target"]
        if self._current_subtask_idx != task.active_subtask_idx:
            self._previous_position = None
            self._current_subtask_idx = task.active_subtask_idx
            episode._shortest_path_cache = None

        if self._current_subtask_idx == len(episode.tasks):
            self._metric = {
                "distance_to_target": self._metric["distance_to_target"],
                "prev_distance_to_target": self.prev_distance_to_target,
                "episode_ended": True,
            }
            return

        viewpoints = [
            view_point["agent_state"]["position"]
            for goal in episode.goals[task.active_subtask_idx]
            for view_point in goal["view_points"]
        ]
        distance_to_target = self._sim.geodesic_distance(current_position, viewpoints, episode)
        self._previous_position = (current_position[0], current_position[1], current_position[2])
        self._metric = {
            "distance_to_target": distance_to_target,
            "prev_distance_to_target": self.prev_distance_to_target,
            "episode_ended": False,
        }


class GoatSuccess:
    cls_uuid = "success"

    def __init__(self, success_distance=0.25):
        self.success_distance = success_distance

    def get_metric(self):
        return self._metric

    def reset_metric(self, episode, task):
        self._metric = None
        self._current_subtask_idx = 0
        self._success_by_subtasks = defaultdict(int)
        self._subtask_counts = defaultdict(int)
        self._subtask_success = [0.0] * len(episode.tasks)
        for t in episode.tasks:
            self._subtask_counts[t[1]] += 1
        self.update_metric(episode=episode, task=task)

    def update_metric(self, episode, task):
        if self._current_subtask_idx == len(episode.tasks):
            return

        distance_to_target = task.measurements.measures[GoatDistanceToGoal.cls_uuid].get_metric()

        if task._subtask_stop_called() and distance_to_target["prev_distance_to_target"] < self.success_distance:
            self._success_by_subtasks[episode.tasks[self._current_subtask_idx][1]] += 1
            self._subtask_success[self._current_subtask_idx] = 1.0

        success_by_subtask = {}
        for k in ["object", "image", "description"]:
            if self._success_by_subtasks[k] == 0:
                success_by_subtask[f"{k}_success"] = 0.0
            else:
                success_by_subtask[f"{k}_success"] = (
                    self._success_by_subtasks[k] / self._subtask_counts[k])

        num_subtask_success = sum(self._subtask_success) == len(episode.tasks)
        self._metric = {
            "task_success": num_subtask_success and getattr(task, "is_stop_called", False),
            "composite_success": num_subtask_success,
            "partial_success": sum(self._success_by_subtasks.values()) / sum(self._subtask_counts.values()),
            "subtask_success": self._subtask_success,
            **success_by_subtask,
        }

        if self._current_subtask_idx != task.active_subtask_idx:
            self._current_subtask_idx = task.active_subtask_idx


class GoatSPL:
    cls_uuid = "spl"

    def __init__(self, sim):
        self._sim = sim

    def get_metric(self):
        return self._metric

    def reset_metric(self, episode, task):
        self._previous_position = self._sim.get_agent_state().position
        self._agent_episode_distance = 0.0
        self._start_end_episode_distance = task.measurements.measures[
            GoatDistanceToGoal.cls_uuid].get_metric()["distance_to_target"]
        self._current_subtask_idx = 0
        self._spl_by_subtasks = defaultdict(int)
        self._subtask_counts = defaultdict(int)
        self._subtask_spl = [0] * len(episode.tasks)
        for t in episode.tasks:
            self._subtask_counts[t[1]] += 1
            self._spl_by_subtasks[f"{t[1]}_spl"] = 0
        self.update_metric(episode=episode, task=task)

    def _euclidean_distance(self, position_a, position_b):
        return np.linalg.norm(position_b - position_a, ord=2)

    def update_metric(self, episode, task):
        ep_success = task.measurements.measures[GoatSuccess.cls_uuid].get_metric()["subtask_success"]
        current_position = self._sim.get_agent_state().position
        self._agent_episode_distance += self._euclidean_distance(current_position, self._previous_position)
        self._previous_position = current_position

        if task._subtask_stop_called():
            spl = ep_success[self._current_subtask_idx] * (
                self._start_end_episode_distance
                / max(self._start_end_episode_distance, self._agent_episode_distance))
            self._spl_by_subtasks[episode.tasks[self._current_subtask_idx][1]] += spl
            self._subtask_spl[self._current_subtask_idx] = spl

        self._metric = {
            "composite_spl": sum(self._spl_by_subtasks.values()) / sum(self._subtask_counts.values()),
            "spl_by_subtask": self._subtask_spl,
        }

        if self._current_subtask_idx != task.active_subtask_idx:
            self._current_subtask_idx = task.active_subtask_idx
            self._start_end_episode_distance = task.measurements.measures[
                GoatDistanceToGoal.cls_uuid].get_metric()["distance_to_target"]
            self._agent_episode_distance = 0


class GoatSoftSPL:
    cls_uuid = "soft_spl"

    def __init__(self, sim):
        self._sim = sim

    def get_metric(self):
        return self._metric

    def reset_metric(self, episode, task):
        self._previous_position = self._sim.get_agent_state().position
        self._agent_episode_distance = 0.0
        self._start_end_episode_distance = task.measurements.measures[
            GoatDistanceToGoal.cls_uuid].get_metric()["distance_to_target"]
        self._current_subtask_idx = 0
        self._softspl_by_subtasks = defaultdict(int)
        self._subtask_counts = defaultdict(int)
        for t in episode.tasks:
            self._subtask_counts[t[1]] += 1
            self._softspl_by_subtasks[f"{t[1]}_softspl"] = 0
        self.update_metric(episode=episode, task=task)

    def _euclidean_distance(self, position_a, position_b):
        return np.linalg.norm(position_b - position_a, ord=2)

    def update_metric(self, episode, task):
        distance_to_target = task.measurements.measures[
            GoatDistanceToGoal.cls_uuid].get_metric()["prev_distance_to_target"]
        current_position = self._sim.get_agent_state().position
        self._agent_episode_distance += self._euclidean_distance(current_position, self._previous_position)
        self._previous_position = current_position

        if task._subtask_stop_called():
            ep_soft_success = max(0, (1 - distance_to_target / self._start_end_episode_distance))
            soft_spl = ep_soft_success * (
                self._start_end_episode_distance
                / max(self._start_end_episode_distance, self._agent_episode_distance))
            self._softspl_by_subtasks[episode.tasks[self._current_subtask_idx][1]] += soft_spl

        self._metric = {
            "composite_softspl": sum(self._softspl_by_subtasks.values()) / sum(self._subtask_counts.values()),
        }

        if self._current_subtask_idx != task.active_subtask_idx:
            self._current_subtask_idx = task.active_subtask_idx
            self._start_end_episode_distance = task.measurements.measures[
                GoatDistanceToGoal.cls_uuid].get_metric()["distance_to_target"]
            self._agent_episode_distance = 0


class GoatTask:
    """``GoatTask`` with habitat-lab's ``NavigationTask`` parts it uses (``is_stop_called``)."""

    def __init__(self, sim, success_distance=0.25):
        self._sim = sim
        self.measurements = Measurements()
        # the order of config/tasks/goat_stretch_hm3d.yaml's measurements
        for m in (GoatDistanceToGoal(sim), GoatSuccess(success_distance), GoatSPL(sim), GoatSoftSPL(sim)):
            self.measurements.measures[m.cls_uuid] = m

    def reset(self, episode):
        self.is_sub_task_stop_called = False
        self.active_subtask_idx = 0
        self.last_action = None
        self.is_stop_called = False
        self._is_episode_active = True
        for m in self.measurements.measures.values():
            m.reset_metric(episode=episode, task=self)

    def _subtask_stop_called(self):
        return isinstance(self.last_action, SubtaskStopAction)

    def _check_episode_is_active(self, episode):
        return not getattr(self, "is_stop_called", False) and self.active_subtask_idx < len(episode.goals)

    def step(self, action, episode):
        if action == 0:
            task_action = StopAction()
            self.is_stop_called = True  # StopAction.step
        elif action == 6:
            task_action = SubtaskStopAction()
            self.is_sub_task_stop_called = True  # SubtaskStopAction.step
            self.active_subtask_idx += 1
        else:
            task_action = None
            self._sim.act(action)
        self._is_episode_active = self._check_episode_is_active(episode)
        self.last_action = task_action


class Env:
    """habitat-lab's ``Env.step`` order: the task's step, its measures, then the step limit."""

    def __init__(self, sim, episode, max_episode_steps=5000, success_distance=0.25):
        self.sim, self.episode, self.max_episode_steps = sim, episode, max_episode_steps
        self.task = GoatTask(sim, success_distance)

    def reset(self):
        self.elapsed_steps = 0
        self.episode_over = False
        self.task.reset(self.episode)

    def step(self, action):
        assert not self.episode_over, "Episode over, call reset before calling step"
        self.task.step(action, self.episode)
        for m in self.task.measurements.measures.values():
            m.update_metric(episode=self.episode, task=self.task)
        self.elapsed_steps += 1
        self.episode_over = not self.task._is_episode_active or self.elapsed_steps >= self.max_episode_steps

    def metrics(self):
        return {k: m.get_metric() for k, m in self.task.measurements.measures.items()}
