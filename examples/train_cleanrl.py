"""A CleanRL-style single-file PPO on ``navbench/PointNav-v0``: the shape of CleanRL's ``ppo.py`` (a Gymnasium
vector env, a rollout buffer, GAE, clipped minibatch updates) with navbench's env dropped in. Blind: the
policy reads GPS, compass and the goal, so nothing is rendered and it trains fast on a CPU.

    python examples/train_cleanrl.py --total-timesteps 50000 --num-envs 4

CleanRL's scripts expect a flat ``Box`` observation: ``FlattenObservation`` turns the env's ``Dict`` of
``compass`` (1), ``gps`` (2) and ``pointgoal_with_gps_compass`` (2) into 5 numbers (keys in sorted order).
:class:`~navbench.env.wrappers.HabitatReward` gives habitat-lab's PointNav reward (the env's own is 0);
the success rate of the episodes each update's rollout finished (their ``info["success"]``) is printed.
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np
import torch
from torch import nn

import navbench  # noqa: F401  (registers the env ids)
from navbench.env.config import EnvConfig
from navbench.env.wrappers import HabitatReward


def make_env(max_steps: int):
    def thunk():
        env = gym.make("navbench/PointNav-v0", config=EnvConfig(rgb=False, depth=False, max_steps=max_steps))
        return gym.wrappers.FlattenObservation(HabitatReward(env))
    return thunk


class Agent(nn.Module):
    def __init__(self, n_obs: int, n_actions: int):
        super().__init__()
        self.critic = nn.Sequential(nn.Linear(n_obs, 64), nn.Tanh(), nn.Linear(64, 64), nn.Tanh(), nn.Linear(64, 1))
        self.actor = nn.Sequential(nn.Linear(n_obs, 64), nn.Tanh(), nn.Linear(64, 64), nn.Tanh(),
                                   nn.Linear(64, n_actions))

    def value(self, x: torch.Tensor) -> torch.Tensor:
        return self.critic(x).squeeze(-1)

    def action_and_value(self, x: torch.Tensor, action: torch.Tensor | None = None):
        dist = torch.distributions.Categorical(logits=self.actor(x))
        if action is None:
            action = dist.sample()
        return action, dist.log_prob(action), dist.entropy(), self.value(x)


def main(argv: list[str] | None = None) -> list[float]:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--total-timesteps", type=int, default=50000)
    p.add_argument("--num-envs", type=int, default=4)
    p.add_argument("--num-steps", type=int, default=128, help="steps per env per rollout")
    p.add_argument("--max-steps", type=int, default=500, help="episode length limit (Habitat's: 500)")
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    gamma, lam, clip, epochs, minibatches, lr = 0.99, 0.95, 0.2, 4, 4, 2.5e-4
    torch.manual_seed(args.seed)

    # SAME_STEP: an ended episode's env is reset within the step, so every stored transition is a real one
    envs = gym.vector.SyncVectorEnv([make_env(args.max_steps) for _ in range(args.num_envs)],
                                    autoreset_mode=gym.vector.AutoresetMode.SAME_STEP)
    n_obs, n_act = envs.single_observation_space.shape[0], int(envs.single_action_space.n)
    agent = Agent(n_obs, n_act)
    optim = torch.optim.Adam(agent.parameters(), lr=lr, eps=1e-5)
    T, N = args.num_steps, args.num_envs
    obs_buf = torch.zeros((T, N, n_obs))
    act_buf, logp_buf, rew_buf, done_buf, val_buf = (torch.zeros((T, N)) for _ in range(5))

    obs, _ = envs.reset(seed=args.seed)
    obs, done = torch.as_tensor(obs, dtype=torch.float32), torch.zeros(N)
    rates = []
    for update in range(max(1, args.total_timesteps // (T * N))):
        successes = []
        for t in range(T):
            obs_buf[t], done_buf[t] = obs, done
            with torch.no_grad():
                action, logp, _, value = agent.action_and_value(obs)
            act_buf[t], logp_buf[t], val_buf[t] = action, logp, value
            obs, reward, terminated, truncated, info = envs.step(action.numpy())
            rew_buf[t] = torch.as_tensor(reward, dtype=torch.float32)
            ended = np.logical_or(terminated, truncated)
            if ended.any():  # the ended episodes' last info is under "final_info"
                successes += [float(info["final_info"]["success"][i]) for i in np.flatnonzero(ended)]
            obs, done = torch.as_tensor(obs, dtype=torch.float32), torch.as_tensor(ended, dtype=torch.float32)
        with torch.no_grad():  # GAE
            next_value, adv, last = agent.value(obs), torch.zeros((T, N)), torch.zeros(N)
            for t in reversed(range(T)):
                nonterminal = 1.0 - (done if t == T - 1 else done_buf[t + 1])
                nv = next_value if t == T - 1 else val_buf[t + 1]
                delta = rew_buf[t] + gamma * nv * nonterminal - val_buf[t]
                adv[t] = last = delta + gamma * lam * nonterminal * last
            ret = adv + val_buf
        b_obs, b_act, b_logp = obs_buf.reshape(-1, n_obs), act_buf.reshape(-1), logp_buf.reshape(-1)
        b_adv, b_ret = adv.reshape(-1), ret.reshape(-1)
        for _ in range(epochs):
            for mb in torch.randperm(T * N).chunk(minibatches):
                _, logp, entropy, value = agent.action_and_value(b_obs[mb], b_act[mb].long())
                ratio = (logp - b_logp[mb]).exp()
                a = (b_adv[mb] - b_adv[mb].mean()) / (b_adv[mb].std() + 1e-8)
                pg = torch.max(-a * ratio, -a * ratio.clamp(1 - clip, 1 + clip)).mean()
                loss = pg + 0.5 * ((value - b_ret[mb]) ** 2).mean() - 0.01 * entropy.mean()
                optim.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(agent.parameters(), 0.5)
                optim.step()
        rate = float(np.mean(successes)) if successes else float("nan")
        rates.append(rate)
        print(f"update {update}: {len(successes)} episodes ended, success rate {rate:.2f}")
    envs.close()
    return rates


if __name__ == "__main__":
    main()
