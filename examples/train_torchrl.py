"""Train a blind PointNav agent with TorchRL's PPO on ``navbench/PointNav-v0`` (GPS, compass and the goal
only: nothing is rendered, so it trains fast on a CPU).

    pip install navbench[rl]
    python examples/train_torchrl.py --frames 20000

The Gymnasium env goes through navbench's :class:`~navbench.env.wrappers.HabitatReward` (habitat-lab's
PointNav reward; the env's own is 0) and :class:`~navbench.env.wrappers.NumpyInfo` (``info`` numbers as
numpy scalars, which TorchRL's ``default_info_dict_reader`` needs), then TorchRL's ``GymWrapper`` with
integer actions. ``success``, ``spl`` and ``distance_to_goal`` are read from ``info`` into each step's
tensordict; the script prints the success rate of the episodes each batch finished.
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import torch

import navbench  # noqa: F401  (registers the env ids)
from navbench.env.config import EnvConfig
from navbench.env.wrappers import HabitatReward, NumpyInfo

GOAL_KEYS = ["pointgoal_with_gps_compass", "gps", "compass"]


def make_env(max_steps: int = 500):
    from torchrl.envs import CatTensors, GymWrapper, TransformedEnv
    from torchrl.envs.libs.gym import default_info_dict_reader

    config = EnvConfig(rgb=False, depth=False, max_steps=max_steps)
    env = GymWrapper(NumpyInfo(HabitatReward(gym.make("navbench/PointNav-v0", config=config))),
                     categorical_action_encoding=True)
    env.set_info_dict_reader(default_info_dict_reader(["success", "spl", "distance_to_goal"]))
    return TransformedEnv(env, CatTensors(GOAL_KEYS, "observation", del_keys=False))


def main(argv: list[str] | None = None) -> list[float]:
    from tensordict.nn import TensorDictModule
    from torchrl.collectors import Collector
    from torchrl.modules import MLP, ProbabilisticActor, ValueOperator
    from torchrl.objectives import ClipPPOLoss
    from torchrl.objectives.value import GAE

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--frames", type=int, default=20000, help="environment steps of training")
    p.add_argument("--batch", type=int, default=500, help="steps collected per update")
    p.add_argument("--max-steps", type=int, default=500, help="episode length limit (Habitat's: 500)")
    args = p.parse_args(argv)
    torch.manual_seed(0)

    env = make_env(args.max_steps)
    env.set_seed(0)
    n_obs, n_act = 5, 4
    actor = ProbabilisticActor(
        TensorDictModule(MLP(in_features=n_obs, out_features=n_act, num_cells=[64, 64]), ["observation"], ["logits"]),
        in_keys=["logits"], distribution_class=torch.distributions.Categorical, return_log_prob=True,
        spec=env.action_spec)
    critic = ValueOperator(MLP(in_features=n_obs, out_features=1, num_cells=[64, 64]), in_keys=["observation"])
    loss = ClipPPOLoss(actor, critic, entropy_coeff=0.01)
    advantage = GAE(gamma=0.99, lmbda=0.95, value_network=critic)
    optim = torch.optim.Adam(loss.parameters(), lr=3e-4)
    collector = Collector(env, actor, frames_per_batch=args.batch, total_frames=args.frames,
                          auto_register_policy_transforms=False)

    rates = []
    for i, batch in enumerate(collector):
        with torch.no_grad():
            advantage(batch)
        for _ in range(4):
            out = loss(batch.reshape(-1))
            total = out["loss_objective"] + out["loss_critic"] + out["loss_entropy"]
            optim.zero_grad()
            total.backward()
            optim.step()
        ended = batch["next", "done"].squeeze(-1)
        success = batch["next", "success"][ended]
        rate = float(success.float().mean()) if len(success) else float("nan")
        rates.append(rate)
        print(f"batch {i}: {int(ended.sum())} episodes ended, success rate {rate:.2f}")
    collector.shutdown()
    return rates


if __name__ == "__main__":
    main()
