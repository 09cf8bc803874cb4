"""DAgger collection speed: frames per second of ``navbench.policy.train.Collector.collect`` with the shipped policy.

    python benchmarks/collect_speed.py                       # 4,000 frames after a 400-frame warm-up
    python benchmarks/collect_speed.py --frames 8000 --beta 0.1 --repeat 3

Collection is most of a DAgger iteration: 8 depth-only envs on ``train_large`` (the 2-hour recipe's DAgger
settings), the policy's batched forward pass (which also gives the stored encoder outputs), the geodesic
expert's label for every step. The warm-up call loads the first scenes; the timed calls still switch scene
on most resets, as training does. Prints one JSON line per timed call, and the share of the time spent in
the policy's forward pass (the rest is rendering, the expert and Python).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import torch

from navbench.paths import POLICIES_DIR
from navbench.policy.checkpoint import load_checkpoint
from navbench.policy.net import InferenceConfig, PointNavAgentPolicy
from navbench.policy.rollout import make_envs
from navbench.policy.train import Collector, TrainConfig


class TimedLearner(PointNavAgentPolicy):
    """The learner, adding up the seconds its forward passes take."""

    seconds = 0.0

    def act_and_encode(self, *args, **kwargs):
        t = time.perf_counter()
        out = super().act_and_encode(*args, **kwargs)
        self.seconds += time.perf_counter() - t
        return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=4000)
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--beta", type=float, default=0.5, help="the expert's share of the executed actions")
    parser.add_argument("--split", default="train_large")
    args = parser.parse_args()
    torch.set_num_threads(2)
    policy = load_checkpoint(POLICIES_DIR / "pointnav_navbench.pth")
    cfg = TrainConfig(train_split=args.split, expert_success_distance=0.1, collision_weight=3, endgame_weight=3)
    collector = Collector(make_envs(cfg.num_envs, cfg.train_split, 60), cfg, np.random.default_rng(0), policy)
    learner = TimedLearner(policy, num_envs=cfg.num_envs, config=InferenceConfig(channels_last=False))
    collector.learner = lambda: learner  # the same acting policy, timed, on every call
    collector.collect(400, args.beta)
    for _ in range(args.repeat):
        learner.seconds = 0.0
        t = time.perf_counter()
        collector.collect(args.frames, args.beta)
        dt = time.perf_counter() - t
        print(json.dumps({"frames_per_s": round(args.frames / dt, 1), "seconds": round(dt, 2),
                          "policy_share": round(learner.seconds / dt, 3)}))
    for env in collector.envs:
        env.close()


if __name__ == "__main__":
    main()
