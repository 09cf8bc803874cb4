"""Score your own agent with navbench's episodes, metrics and run directories.

    python examples/evaluate_agent.py            # 10 episodes of the PointNav val split
    navbench run --task pointnav --split val --agent examples.evaluate_agent:GoalSeeker --agent-opt turn=0.2

An agent is any object with ``reset(episode)`` and ``act(observations) -> int`` (0 STOP, 1 MOVE_FORWARD,
2 TURN_LEFT, 3 TURN_RIGHT); ``sensors`` says which images it reads, so the env renders only those.
"""

from __future__ import annotations

import navbench

STOP, MOVE_FORWARD, TURN_LEFT, TURN_RIGHT = 0, 1, 2, 3


class GoalSeeker:
    """Turns toward the point goal, walks while the way ahead is clear, stops within 0.2 m."""

    sensors = ("depth",)  # no RGB rendered for this agent

    def __init__(self, turn: float = 0.3, clearance: float = 0.03):
        self.turn, self.clearance = turn, clearance  # radians; normalised depth (0.03 = 0.3 m of 10 m)

    def reset(self, episode) -> None:
        pass

    def act(self, observations) -> int:
        distance, angle = observations["pointgoal_with_gps_compass"]
        if distance < 0.2:
            return STOP
        if abs(angle) > self.turn:
            return TURN_LEFT if angle > 0 else TURN_RIGHT
        depth = observations["depth"]
        h, w = depth.shape[:2]
        ahead = depth[h // 3:2 * h // 3, w // 3:2 * w // 3].min()
        return TURN_LEFT if ahead < self.clearance else MOVE_FORWARD


def main(limit: int = 10, out: str | None = None) -> dict:
    summary = navbench.evaluate(GoalSeeker, task="pointnav", split="val", options={"turn": 0.3}, limit=limit,
                                out=out)
    print(f"{summary['num_episodes']} episodes: SR {summary['success']:.2f}, SPL {summary['spl']:.2f}")
    return summary


if __name__ == "__main__":
    main()
