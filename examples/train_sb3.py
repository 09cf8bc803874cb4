"""Train PPO from Stable-Baselines3 on ``navbench/PointNav-v0``, then evaluate it with navbench's harness.

    pip install navbench[rl]
    python examples/train_sb3.py --steps 20000 --out runs/sb3_ppo.zip

Depth goes through :class:`navbench.env.wrappers.DepthUint8`, so SB3's ``MultiInputPolicy`` sends it
through its CNN (a float image would be flattened into a dense network); :class:`HabitatReward` gives
habitat-lab's PointNav reward (the env's own is 0). Images are 64x64 here to keep CPU training quick
(``--size``). The trained policy is then scored (success, SPL from ``info``) on a few ``val`` episodes.
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import navbench  # noqa: F401  (registers the env ids)
from navbench.env.config import EnvConfig
from navbench.env.wrappers import DepthUint8, HabitatReward


def make_env(size: int, max_steps: int = 500) -> gym.Env:
    config = EnvConfig(rgb=False, depth=True, width=size, height=size, max_steps=max_steps)
    return HabitatReward(DepthUint8(gym.make("navbench/PointNav-v0", config=config)))


def evaluate(model, env: gym.Env, episodes: int) -> dict:
    """Mean success and SPL of the model's deterministic actions over ``episodes`` episodes of ``env``."""
    rows = []
    obs, info = env.reset(seed=1)
    for _ in range(episodes):
        done = False
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, _, terminated, truncated, info = env.step(int(action))
            done = terminated or truncated
        rows.append((info["success"], info["spl"]))
        obs, info = env.reset()
    return {"success": float(np.mean([r[0] for r in rows])), "spl": float(np.mean([r[1] for r in rows]))}


def main(argv: list[str] | None = None) -> dict:
    from stable_baselines3 import PPO

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=20000, help="environment steps of training")
    p.add_argument("--size", type=int, default=64, help="depth image side (pixels)")
    p.add_argument("--episodes", type=int, default=5, help="val episodes to evaluate on")
    p.add_argument("--max-steps", type=int, default=500, help="episode length limit (Habitat's: 500)")
    p.add_argument("--out", help="save the model here (.zip)")
    args = p.parse_args(argv)

    env = make_env(args.size, args.max_steps)
    model = PPO("MultiInputPolicy", env, n_steps=min(256, args.steps), batch_size=64, n_epochs=2, seed=0,
                device="cpu", verbose=0)
    model.learn(total_timesteps=args.steps)
    if args.out:
        model.save(args.out)
    summary = evaluate(model, env, args.episodes)
    print(f"after {args.steps} steps: SR {summary['success']:.3f}, SPL {summary['spl']:.3f}")
    return summary


if __name__ == "__main__":
    main()
