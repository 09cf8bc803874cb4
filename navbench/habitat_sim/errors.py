"""habitat-sim's ``habitat_sim.errors``."""

from __future__ import annotations


class GreedyFollowerError(RuntimeError):
    """The greedy follower found no path to the goal (``next_action_along`` with an unreachable goal)."""


class InvalidConstraintError(RuntimeError):
    pass


def assert_obj_valid(obj, *args) -> None:
    """habitat-sim checks a scene-graph object still exists; Python objects here always do."""
