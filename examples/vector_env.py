"""Step a batch of PointNav envs with one batched policy forward pass per step (Gymnasium vector API).

    python examples/vector_env.py                      # 4 envs in worker processes ("async")
    python examples/vector_env.py --mode sync --num-envs 2 --steps 50

``gymnasium.make_vec`` builds ``num_envs`` copies of ``navbench/PointNav-v0`` (bundled ``val`` split);
``reset(seed=s)`` seeds sub-env ``i`` with ``s + i``, so each draws its own episodes, the same ones on
every run. Autoreset is Gymnasium's default (next step): the step after an episode ends ignores that
env's action and returns the first observation of its next episode, so the policy's recurrent state
for that env restarts there. The shipped checkpoint drives all envs through one
:class:`~navbench.policy.net.PointNavAgentPolicy`, whose ``act`` takes the batch of depth frames
(N, H, W, 1) and point goals (N, 2).
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import navbench  # noqa: F401  (registers the envs)
from navbench.agents.pointnav import DEFAULT_CHECKPOINT
from navbench.env.config import EnvConfig
from navbench.policy.checkpoint import load_checkpoint
from navbench.policy.net import PointNavAgentPolicy


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--num-envs", type=int, default=4)
    p.add_argument("--mode", choices=("async", "sync"), default="async")
    p.add_argument("--steps", type=int, default=200)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)

    envs = gym.make_vec("navbench/PointNav-v0", num_envs=args.num_envs, vectorization_mode=args.mode,
                        config=EnvConfig(rgb=False, depth=True))  # the policy reads depth only
    policy = PointNavAgentPolicy(load_checkpoint(DEFAULT_CHECKPOINT), num_envs=args.num_envs)
    obs, info = envs.reset(seed=args.seed)
    episodes = [[str(e)] for e in info["episode_id"]]
    ended = np.zeros(args.num_envs, bool)  # which envs' previous step ended an episode
    finished = []
    for _ in range(args.steps):
        for i in np.flatnonzero(ended):  # this step's observation starts env i's next episode
            policy.reset(int(i))
        actions = policy.act(obs["depth"], obs["pointgoal_with_gps_compass"])  # one forward pass for all
        obs, _, terminated, truncated, info = envs.step(actions)
        for i in np.flatnonzero(ended):
            episodes[i].append(str(info["episode_id"][i]))
        done = terminated | truncated
        for i in np.flatnonzero(done):
            finished.append((int(i), str(info["episode_id"][i]), float(info["success"][i]), float(info["spl"][i])))
        ended = done
    envs.close()
    for i, ep, sr, spl in finished:
        print(f"env {i} episode {ep}: success {sr:.0f} SPL {spl:.2f}")
    print(f"{args.num_envs} envs ({args.mode}), {args.steps} steps, {len(finished)} episodes finished; "
          f"episodes per env: {episodes}")
    return {"episodes": episodes, "finished": finished}


if __name__ == "__main__":
    main()
