"""The retraining levers (configs/pointnav/v2.toml uses the DAgger ones), each a config field that does what its help
says."""

import dataclasses

import numpy as np
import pytest
import torch

from navbench.policy.checkpoint import read_train_state, save_checkpoint
from navbench.policy.config import PPOConfig, TrainConfig
from navbench.policy.net import PointNavResNetPolicy, PolicyNetConfig
from navbench.policy.ppo import step_reward, train_ppo, update_lr_factor
from navbench.policy.recipe import load_recipe
from navbench.policy.rollout import make_envs
from navbench.policy.train import Collector, iteration_lr


def test_terminal_reward_spl_scales_the_success_bonus_by_the_episodes_spl():
    flat, spl = PPOConfig(), PPOConfig(terminal_reward="spl")
    assert step_reward(0.3, 0.1, True, flat, spl=0.6) == pytest.approx(0.2 - 0.01 + 2.5)
    assert step_reward(0.3, 0.1, True, spl, spl=0.6) == pytest.approx(0.2 - 0.01 + 2.5 * 0.6)
    assert step_reward(0.3, 0.1, False, spl, spl=0.6) == pytest.approx(0.2 - 0.01)  # no bonus without success


def test_ppo_linear_lr_decay_reaches_the_last_update_at_one_step_of_the_rate(tmp_path):
    cfg = PPOConfig(updates=4, lr_schedule="linear")
    assert [update_lr_factor(cfg, u) for u in range(4)] == [1.0, 0.75, 0.5, 0.25]
    assert update_lr_factor(dataclasses.replace(cfg, lr_schedule="constant"), 3) == 1.0
    torch.manual_seed(0)
    init = save_checkpoint(tmp_path / "init.pth", PointNavResNetPolicy(PolicyNetConfig()), {})
    run = PPOConfig(train_split="train", num_envs=1, rollout_steps=3, updates=2, critic_warmup=0, save_every=1,
                    num_minibatches=1, lr_schedule="linear", threads=1)
    train_ppo(run, tmp_path / "o.pth", init, state_dir=tmp_path / "s", log_every=lambda _: None)
    groups = read_train_state(tmp_path / "s" / "ppo_state.pt")["optimizer"]["param_groups"]
    assert [g["lr"] for g in groups] == pytest.approx([run.lr * 0.5, run.critic_lr * 0.5])  # the second update's


def test_dagger_linear_lr_runs_straight_from_lr_to_lr_min():
    cfg = TrainConfig(iterations=5, lr=4e-4, lr_min=2e-5, lr_schedule="linear")
    rates = [iteration_lr(cfg, i) for i in range(5)]
    np.testing.assert_allclose(rates, np.linspace(4e-4, 2e-5, 5))


def test_dagger_with_beta_zero_drives_on_its_own_states_labelled_by_the_expert(monkeypatch):
    """beta0 = beta_min = 0: every executed action is the learner's; the labels stay the expert's."""
    cfg = TrainConfig(num_envs=1, beta0=0.0, beta_min=0.0, random_action_prob=0.0, max_episode_steps=12)
    torch.manual_seed(0)
    envs = make_envs(1, "train", seed=0)
    collector = Collector(envs, cfg, np.random.default_rng(0), PointNavResNetPolicy(PolicyNetConfig()))
    real = collector.learner

    def turning_learner():  # a learner that always turns left
        agent = real()
        agent.act_and_encode = lambda depth, goal: (np.full(len(depth), 2), real().act_and_encode(depth, goal)[1])
        return agent

    monkeypatch.setattr(collector, "learner", turning_learner)
    eps, _ = collector.collect(12, beta=max(cfg.beta_min, cfg.beta0))
    for env in envs:
        env.close()
    assert eps and (eps[0]["prev"][1:] == 2).all()  # what was executed: the learner's turns
    assert (eps[0]["label"] != 2).any()  # what was learned: the expert's actions from those states


def test_the_v2_recipe_is_dagger_on_own_states_in_a_stage_of_at_most_two_hours():
    recipe = load_recipe("pointnav/v2")
    assert [s.trainer for s in recipe.stages] == ["dagger"]  # starts from a trained policy (--init)
    c = recipe.stages[0].config
    assert c.beta0 == 0.0 and c.beta_min == 0.0 and c.lr_schedule == "linear" and c.train_split == "train_large"
    # ~150 s per 8,000-frame iteration on the slowest 2-core machine the model card lists (50 s on Sapphire Rapids)
    assert c.iterations * c.frames_per_iteration / 8000 * 150 <= 2 * 3600
