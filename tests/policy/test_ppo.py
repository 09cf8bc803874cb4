"""PPO fine-tuning: habitat's PointNav reward, GAE, the critic warm-up, resumable runs and the expert term."""


import numpy as np
import pytest
import torch

from navbench.policy.checkpoint import load_checkpoint, save_checkpoint
from navbench.policy.net import PointNavResNetPolicy, PolicyNetConfig
from navbench.policy.ppo import PPOConfig, Rollout, gae, ppo_update, step_reward, train_ppo
from navbench.policy.rollout import make_envs


def test_reward_is_progress_plus_slack_plus_the_success_bonus():
    cfg = PPOConfig()
    assert step_reward(3.0, 2.75, False, cfg) == pytest.approx(0.25 - 0.01)
    assert step_reward(3.0, 3.0, False, cfg) == pytest.approx(-0.01)  # blocked or turning
    assert step_reward(3.0, 3.1, False, cfg) == pytest.approx(-0.1 - 0.01)  # habitat: no path term
    assert step_reward(0.15, 0.15, True, cfg) == pytest.approx(2.5 - 0.01)


def test_gae_bootstraps_within_an_episode_and_not_across_its_end():
    gamma, lam = 0.9, 0.5
    rewards = np.array([[1.0], [2.0], [0.5]], np.float32)
    values = np.array([[0.5], [1.0], [2.0]], np.float32)
    dones = np.array([[0.0], [1.0], [0.0]], np.float32)  # the episode ends at step 1; step 2 starts another
    adv = gae(rewards, values, dones, np.array([4.0], np.float32), gamma, lam)
    d2 = 0.5 + gamma * 4.0 - 2.0  # bootstraps from the value after the rollout
    d1 = 2.0 - 1.0  # terminal: no bootstrap from step 2, which belongs to the next episode
    d0 = 1.0 + gamma * 1.0 - 0.5
    np.testing.assert_allclose(adv[:, 0], [d0 + gamma * lam * d1, d1, d2], rtol=1e-6)


def _params(policy):
    return {n: p.detach().clone() for n, p in policy.named_parameters()}


def test_warmup_trains_only_the_critic_then_the_actor_moves_and_runs_resume(tmp_path):
    torch.manual_seed(0)
    init = save_checkpoint(tmp_path / "init.pth", PointNavResNetPolicy(PolicyNetConfig()), {}, fp16=False)
    before = _params(load_checkpoint(init))
    cfg = PPOConfig(train_split="train", num_envs=2, rollout_steps=8, updates=1, critic_warmup=1, save_every=1)
    out, state = tmp_path / "ppo.pth", tmp_path / "state"
    first = train_ppo(cfg, out, init, state_dir=state, log_every=lambda _: None)
    assert first["update"] == 1 and first["frames"] == 16 and first["actor"] == 0
    after = _params(load_checkpoint(out))  # fp16 as stored; the unchanged weights came from fp32 ones
    moved = {n for n in before if not torch.allclose(before[n], after[n], atol=1e-3)}
    assert moved and all(n.startswith("critic.") for n in moved)

    cfg2 = PPOConfig(train_split="train", num_envs=2, rollout_steps=8, updates=2, critic_warmup=1, save_every=1,
                    lr=1e-3)
    second = train_ppo(cfg2, out, init, resume=True, state_dir=state, log_every=lambda _: None)
    assert second["update"] == 2 and second["frames"] == 32 and second["actor"] == 1
    final = _params(load_checkpoint(out))
    # stored as fp16 from the same fp32 weights, an unchanged tensor reads back equal
    assert any(not torch.equal(after[n], final[n])
               for n in final if n.startswith(("action_distribution.", "net.state_encoder.")))
    assert all(torch.equal(after[n], final[n]) for n in final if n.startswith("net.visual_encoder."))
    assert len((tmp_path / "ppo.log.csv").read_text().strip().splitlines()) == 3  # header + two updates


def test_a_run_without_init_or_state_to_resume_is_refused_by_name(tmp_path):
    with pytest.raises(ValueError, match="--init"):
        train_ppo(PPOConfig(), tmp_path / "ppo.pth", None, resume=True, state_dir=tmp_path / "none",
                  log_every=lambda _: None)


def _frozen_encoder_policy() -> PointNavResNetPolicy:
    torch.manual_seed(0)
    policy = PointNavResNetPolicy(PolicyNetConfig())
    policy.net.visual_encoder.requires_grad_(False)
    return policy


def _rollout(policy: PointNavResNetPolicy, cfg: PPOConfig) -> dict[str, torch.Tensor]:
    """One rollout of ``cfg.num_envs`` train envs seeded alike every call."""
    envs = make_envs(cfg.num_envs, "train", 5)
    try:
        return Rollout(envs, cfg, policy, torch.Generator().manual_seed(0), np.random.default_rng(0)).collect()[0]
    finally:
        for e in envs:
            e.close()


def test_bc_weight_labels_the_rollout_with_the_expert_and_pulls_the_actor_towards_it():
    policy = _frozen_encoder_policy()
    assert "label" not in _rollout(policy, PPOConfig(num_envs=2, rollout_steps=4))
    cfg = PPOConfig(num_envs=2, rollout_steps=8, bc_weight=1.0, lr=1e-3, ppo_epochs=1, num_minibatches=1)
    data = _rollout(policy, cfg)
    assert data["label"].shape == data["action"].shape and int(data["label"].max()) <= 3
    data["adv"].zero_()  # no advantage: only the imitation term can move the actor
    opt = torch.optim.Adam([p for p in policy.parameters() if p.requires_grad], lr=1e-3)
    first = ppo_update(policy, opt, data, cfg, actor=True, rng=np.random.default_rng(0))["bc_loss"]
    for _ in range(20):
        last = ppo_update(policy, opt, data, cfg, actor=True, rng=np.random.default_rng(0))["bc_loss"]
    assert last < 0.8 * first  # 1.39 (uniform over 4 actions) -> 0.66 here
    assert "bc_loss" not in ppo_update(policy, opt, data, PPOConfig(num_minibatches=1), actor=True,
                                       rng=np.random.default_rng(0))


def test_tight_starts_begin_the_first_and_every_later_rollout_episode_beside_an_obstacle():
    torch.manual_seed(0)
    policy = PointNavResNetPolicy(PolicyNetConfig())
    with torch.no_grad():  # an actor that always calls STOP: every step ends an episode and draws the next
        policy.action_distribution.linear.weight.zero_()
        policy.action_distribution.linear.bias.copy_(torch.tensor([30.0, -30.0, -30.0, -30.0]))
    envs = make_envs(2, "train", 5)
    try:
        rollout = Rollout(envs, PPOConfig(num_envs=2, rollout_steps=3, tight_starts=1.0), policy,
                          torch.Generator().manual_seed(0), np.random.default_rng(0))
        firsts = [e.episode.episode_id for e in envs]
        _, finished = rollout.collect()
        assert len(finished) == 6
        for ids in (firsts, [e.episode.episode_id for e in envs]):
            assert all(i.endswith("-tight") for i in ids)
        clearance = [e.navgrid.navigable_clearance()[tuple(e.navgrid.world_to_grid(np.asarray(
            e.episode.start_position)))] for e in envs]
        assert all(0 < c <= 0.1 + 1e-9 for c in clearance)
    finally:
        for e in envs:
            e.close()


def test_act_bf16_encodes_the_rollout_in_bfloat16_and_keeps_the_logits_fp32():
    torch.manual_seed(0)
    policy = PointNavResNetPolicy(PolicyNetConfig()).eval()
    steps = {}
    for act_bf16 in (False, True):  # the same first frames: envs seeded alike
        envs = make_envs(2, "train", 5)
        try:
            rollout = Rollout(envs, PPOConfig(num_envs=2, rollout_steps=2, act_bf16=act_bf16), policy,
                              torch.Generator().manual_seed(0), np.random.default_rng(0))
            steps[act_bf16] = rollout._step_policy()
        finally:
            for e in envs:
                e.close()
    (f32, goal32, logits32, _, _), (fbf, goal_bf, logits_bf, value_bf, _) = steps[False], steps[True]
    assert torch.equal(goal32, goal_bf)
    assert fbf.dtype == logits_bf.dtype == value_bf.dtype == torch.float32
    assert not torch.equal(f32, fbf) and float((f32 - fbf).norm() / f32.norm()) < 0.05
    assert not torch.equal(logits32, logits_bf) and torch.allclose(logits32, logits_bf, atol=0.05)
