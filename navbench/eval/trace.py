"""Per-step trace of an episode, kept in its record so maps and videos can be drawn without re-running.

``record["trace"]`` = ``{"actions": "1131...", "poses": [[x, z, yaw], ...], "decisions": [[step, ...], ...]}``:
one action digit per step (0 STOP, 1 FORWARD, 2 LEFT, 3 RIGHT); the pose after reset and after each
step (metres rounded to mm, yaw in radians rounded to mrad); the agent's ``decision()`` (what it is
driving to) at the steps where it changes, for agents that have one.
"""

from __future__ import annotations

from typing import Any


def _pose(env) -> list[float]:
    p = env.agent_position
    return [round(float(p[0]), 3), round(float(p[2]), 3), round(float(env.agent_yaw), 3)]


class Trace:
    """Collects one episode's trace; reads the env's pose and the agent's decision, changes neither."""

    def __init__(self, env, agent: Any = None):
        self.actions: list[str] = []
        self.poses = [_pose(env)]
        self.decisions: list[list] = []
        self._decide = getattr(agent, "decision", None)
        self._last: Any = None

    def step(self, action: int, env) -> None:
        """After ``env.step(action)``: record the action, the new pose and the decision behind the action."""
        self.actions.append(str(int(action)))
        self.poses.append(_pose(env))
        if callable(self._decide):
            d = self._decide()
            if d is not None and d != self._last:
                self.decisions.append([len(self.actions), *d])
                self._last = d

    def record(self) -> dict[str, Any]:
        out: dict[str, Any] = {"actions": "".join(self.actions), "poses": self.poses}
        if self.decisions:
            out["decisions"] = self.decisions
        return out
