"""VLN-CE's measures transcribed from the reference code, to check navbench.metrics against: the classes of
jacobkrantz/VLN-CE habitat_extensions/measures.py (PathLength, OracleSuccess, StepsTaken, NDTW, SDTW) and
habitat-lab v0.1.7 habitat/tasks/nav/nav.py (DistanceToGoal, Success, SPL), kept as close to the original
lines as a simulator-less harness allows. ``run_reference`` plays a scripted list of float32 positions through
them as habitat's Env does: reset_metric in config order at reset, update_metric after every action."""

import numpy as np
from fastdtw import fastdtw


def euclidean_distance(pos_a, pos_b):
    return np.linalg.norm(np.array(pos_b) - np.array(pos_a), ord=2)


class Sim:
    def __init__(self, geodesic):
        self.position = None
        self.geodesic = geodesic

    def get_agent_state_position(self):
        return self.position


class DistanceToGoal:
    def __init__(self, sim):
        self._sim = sim

    def reset_metric(self, task):
        self._previous_position = None
        self._metric = None
        self.update_metric(task)

    def update_metric(self, task):
        current_position = self._sim.get_agent_state_position()
        if self._previous_position is None or not np.allclose(self._previous_position, current_position, atol=1e-4):
            self._metric = self._sim.geodesic(current_position)
            self._previous_position = current_position


class Success:
    def __init__(self, success_distance):
        self.sd = success_distance

    def reset_metric(self, task):
        self.update_metric(task)

    def update_metric(self, task):
        d = task.measures["distance_to_goal"]._metric
        self._metric = 1.0 if task.is_stop_called and d < self.sd else 0.0


class SPL:
    def __init__(self, sim):
        self._sim = sim

    def reset_metric(self, task):
        self._previous_position = self._sim.get_agent_state_position()
        self._agent_episode_distance = 0.0
        self._start_end_episode_distance = task.measures["distance_to_goal"]._metric
        self.update_metric(task)

    def update_metric(self, task):
        ep_success = task.measures["success"]._metric
        current_position = self._sim.get_agent_state_position()
        # ``0.0 + float32`` is float64 under the reference's NumPy 1.x (float32 under NumPy 2's NEP 50);
        # np.float64 keeps the NumPy 1.x result here
        self._agent_episode_distance = np.float64(self._agent_episode_distance) + np.linalg.norm(
            current_position - self._previous_position, ord=2)
        self._previous_position = current_position
        self._metric = ep_success * (self._start_end_episode_distance
                                     / max(self._start_end_episode_distance, self._agent_episode_distance))


class NDTW:
    def __init__(self, sim, gt_locations, success_distance):
        self._sim, self.gt, self.sd = sim, gt_locations, success_distance

    def reset_metric(self, task):
        self.locations = []
        self.gt_locations = self.gt
        self.update_metric(task)

    def update_metric(self, task):
        current_position = self._sim.get_agent_state_position().tolist()
        if len(self.locations) == 0:
            self.locations.append(current_position)
        else:
            if current_position == self.locations[-1]:
                return
            self.locations.append(current_position)
        dtw_distance = fastdtw(self.locations, self.gt_locations, dist=euclidean_distance)[0]
        self._metric = np.exp(-dtw_distance / (len(self.gt_locations) * self.sd))


class PathLength:
    def __init__(self, sim):
        self._sim = sim

    def reset_metric(self, task):
        self._previous_position = self._sim.get_agent_state_position()
        self._metric = 0.0

    def update_metric(self, task):
        current_position = self._sim.get_agent_state_position()
        # float64 accumulation, as under the reference's NumPy 1.x (see SPL)
        self._metric = np.float64(self._metric) + euclidean_distance(current_position, self._previous_position)
        self._previous_position = current_position


class OracleSuccess:
    def __init__(self, success_distance):
        self.sd = success_distance

    def reset_metric(self, task):
        self._metric = 0.0
        self.update_metric(task)

    def update_metric(self, task):
        d = task.measures["distance_to_goal"]._metric
        self._metric = float(self._metric or d < self.sd)


class StepsTaken:
    def reset_metric(self, task):
        self._metric = 0.0

    def update_metric(self, task):
        self._metric += 1.0


class SDTW:
    def reset_metric(self, task):
        self.update_metric(task)

    def update_metric(self, task):
        self._metric = task.measures["success"]._metric * task.measures["ndtw"]._metric


class Task:
    def __init__(self, geodesic, gt_locations, success_distance=3.0):
        self.sim = Sim(geodesic)
        self.is_stop_called = False
        # vlnce_task.yaml's order, with SDTW after its dependencies
        self.measures = {
            "distance_to_goal": DistanceToGoal(self.sim), "success": Success(success_distance),
            "spl": SPL(self.sim), "ndtw": NDTW(self.sim, gt_locations, success_distance),
            "path_length": PathLength(self.sim), "oracle_success": OracleSuccess(success_distance),
            "steps_taken": StepsTaken(), "sdtw": SDTW(),
        }


def run_reference(positions, actions, geodesic, gt_locations, max_steps=500):
    """The final-step measures of an episode: ``positions[0]`` at reset, ``positions[i+1]`` after
    ``actions[i]`` (0 = STOP ends the episode, as does the step limit)."""
    task = Task(geodesic, gt_locations)
    task.sim.position = np.asarray(positions[0], np.float32)
    for m in task.measures.values():
        m.reset_metric(task)
    for i, action in enumerate(actions[:max_steps]):
        if action == 0:
            task.is_stop_called = True
        task.sim.position = np.asarray(positions[i + 1], np.float32)
        for m in task.measures.values():
            m.update_metric(task)
        if task.is_stop_called:
            break
    return {k: float(m._metric) for k, m in task.measures.items()}
