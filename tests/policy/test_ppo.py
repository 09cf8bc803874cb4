"""PPO fine-tuning: habitat's PointNav reward, GAE, the critic warm-up, resumable runs and the expert term."""

import copy
import dataclasses

import numpy as np
import pytest
import torch

from navbench.policy.checkpoint import load_checkpoint, save_checkpoint
from navbench.policy.net import PointNavResNetPolicy, PolicyNetConfig
from navbench.policy.ppo import PPOConfig, Rollout, actor_lr, gae, ppo_update, step_reward, train_ppo
from navbench.policy.train import make_envs


def test_reward_is_progress_plus_slack_plus_the_success_bonus():
    cfg = PPOConfig()
    assert step_reward(3.0, 2.75, 0.25, False, cfg) == pytest.approx(0.25 - 0.01)
    assert step_reward(3.0, 3.0, 0.0, False, cfg) == pytest.approx(-0.01)  # blocked or turning
    assert step_reward(3.0, 3.1, 0.25, False, cfg) == pytest.approx(-0.1 - 0.01)  # habitat: no path term
    assert step_reward(0.15, 0.15, 0.0, True, cfg) == pytest.approx(2.5 - 0.01)


def test_waste_weight_charges_the_metres_that_made_no_progress():
    cfg = PPOConfig(waste_weight=2.0)
    assert step_reward(3.0, 2.75, 0.25, False, cfg) == pytest.approx(0.25 - 0.01)  # straight at the goal
    assert step_reward(3.0, 2.9, 0.25, False, cfg) == pytest.approx(0.1 - 0.01 - 2.0 * 0.15)  # sideways
    assert step_reward(3.0, 3.0, 0.0, False, cfg) == pytest.approx(-0.01)  # turns cost only the slack


def test_collision_penalty_charges_only_refused_forwards():
    cfg = PPOConfig(collision_penalty=0.05)
    assert step_reward(3.0, 3.0, 0.0, False, cfg, collided=True) == pytest.approx(-0.01 - 0.05)
    assert step_reward(3.0, 3.0, 0.0, False, cfg) == pytest.approx(-0.01)  # a turn
    assert step_reward(3.0, 3.0, 0.0, False, PPOConfig(), collided=True) == pytest.approx(-0.01)  # off by default


def test_success_spl_scales_only_the_success_bonus_by_the_episode_spl():
    cfg = PPOConfig(success_spl=True)
    assert step_reward(0.15, 0.15, 0.0, True, cfg, spl=0.6) == pytest.approx(2.5 * 0.6 - 0.01)
    assert step_reward(3.0, 2.75, 0.25, False, cfg, spl=0.0) == pytest.approx(0.25 - 0.01)  # no bonus to scale
    assert step_reward(0.15, 0.15, 0.0, True, PPOConfig(), spl=0.6) == pytest.approx(2.5 - 0.01)  # off by default


def test_cosine_schedule_holds_the_rate_through_the_warmup_then_decays_it_to_lr_min_at_the_last_update():
    cfg = PPOConfig(lr=2e-5, lr_min=1e-6, lr_schedule="cosine", updates=110, critic_warmup=10)
    rates = [actor_lr(cfg, u) for u in range(cfg.updates)]
    assert rates[0] == rates[10] == pytest.approx(2e-5)
    assert rates[60] == pytest.approx(1e-6 + 0.5 * (2e-5 - 1e-6) * (1 + np.cos(np.pi * 50 / 99)))
    assert rates[-1] == pytest.approx(1e-6)
    assert all(a >= b for a, b in zip(rates, rates[1:]))
    assert {actor_lr(PPOConfig(lr=3e-5), u) for u in (0, 50, 299)} == {3e-5}
    with pytest.raises(ValueError, match="linear"):
        actor_lr(PPOConfig(lr_schedule="linear"), 0)


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
    assert any(not torch.allclose(after[n], final[n], atol=1e-4)
               for n in final if n.startswith(("action_distribution.", "net.state_encoder.")))
    assert all(torch.equal(after[n], final[n]) for n in final if n.startswith("net.visual_encoder."))
    assert len((tmp_path / "ppo.log.csv").read_text().strip().splitlines()) == 3  # header + two updates


def test_a_cosine_run_sets_and_logs_the_actor_rate_each_update_and_ends_at_lr_min(tmp_path):
    init = save_checkpoint(tmp_path / "init.pth", PointNavResNetPolicy(PolicyNetConfig()), {}, fp16=False)
    cfg = PPOConfig(train_split="train", num_envs=2, rollout_steps=4, updates=3, critic_warmup=1, save_every=1,
                    lr=2.5e-5, lr_min=1.25e-6, lr_schedule="cosine")
    last = train_ppo(cfg, tmp_path / "ppo.pth", init, state_dir=tmp_path / "state", log_every=lambda _: None)
    assert float(last["lr"]) == pytest.approx(1.25e-6)
    header, *lines = (tmp_path / "ppo.log.csv").read_text().strip().splitlines()
    col = header.split(",").index("lr")
    assert [float(line.split(",")[col]) for line in lines] == pytest.approx([2.5e-5, 2.5e-5, 1.25e-6])
    state = torch.load(tmp_path / "state" / "ppo_state.pt", weights_only=False)
    assert [g["lr"] for g in state["optimizer"]["param_groups"]] == pytest.approx([1.25e-6, cfg.critic_lr])


def test_train_encoder_rolls_out_depth_and_moves_the_encoder_only_once_the_actor_trains(tmp_path):
    torch.manual_seed(0)
    init = save_checkpoint(tmp_path / "init.pth", PointNavResNetPolicy(PolicyNetConfig()), {}, fp16=False)
    before = _params(load_checkpoint(init))
    cfg = PPOConfig(train_split="train", num_envs=2, rollout_steps=4, updates=1, critic_warmup=1, save_every=1,
                    train_encoder=True, lr=1e-3)
    out, state = tmp_path / "ppo.pth", tmp_path / "state"
    train_ppo(cfg, out, init, state_dir=state, log_every=lambda _: None)
    warm = torch.load(state / "ppo_state.pt", weights_only=False)["policy"]  # fp32, unlike the fp16 checkpoint
    encoder = [n for n in before if n.startswith("net.visual_encoder.")]
    assert encoder and all(torch.equal(before[n], warm[n]) for n in encoder)
    train_ppo(dataclasses.replace(cfg, updates=2), out, init, resume=True, state_dir=state, log_every=lambda _: None)
    st = torch.load(state / "ppo_state.pt", weights_only=False)
    assert [n for n in encoder if not torch.equal(warm[n], st["policy"][n])]
    opt = st["optimizer"]
    assert [g["lr"] for g in opt["param_groups"]] == pytest.approx([1e-3, cfg.critic_lr, 1e-4])

    policy = load_checkpoint(init)
    envs = make_envs(2, "train", 3)
    data = Rollout(envs, cfg, policy, torch.Generator().manual_seed(0)).collect()
    for e in envs:
        e.close()
    assert "feat" not in data and data["depth"].shape == (4, 2, 224, 224, 1) and data["depth"].dtype == torch.float16


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
        return Rollout(envs, cfg, policy, torch.Generator().manual_seed(0)).collect()
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
    for _ in range(10):
        last = ppo_update(policy, opt, data, cfg, actor=True, rng=np.random.default_rng(0))["bc_loss"]
    assert last < 0.8 * first  # 1.39 (uniform over 4 actions) -> 0.98 here
    assert "bc_loss" not in ppo_update(policy, opt, data, PPOConfig(num_minibatches=1), actor=True,
                                       rng=np.random.default_rng(0))


def test_bf16_changes_nothing_in_a_frozen_encoder_update():
    # --bf16 covers only the encoder's pass, which a frozen-encoder update (stored features) does not make
    policy = _frozen_encoder_policy()
    data = _rollout(policy, PPOConfig(num_envs=2, rollout_steps=4))
    assert "feat" in data and "depth" not in data
    weights = {}
    for bf16 in (False, True):
        learner = copy.deepcopy(policy)  # frozen encoder included
        opt = torch.optim.Adam([p for p in learner.parameters() if p.requires_grad], lr=1e-3)
        ppo_update(learner, opt, data, PPOConfig(bf16=bf16, ppo_epochs=1, num_minibatches=1), actor=True,
                   rng=np.random.default_rng(0))
        weights[bf16] = learner.state_dict()
    assert any(not torch.equal(weights[False][k], v) for k, v in policy.state_dict().items())  # the update moved it
    assert all(torch.equal(weights[False][k], weights[True][k]) for k in weights[False])


class _Episodes:
    """A stand-in env for the replay logic: fresh draws are numbered, a replay resets to the one given."""

    def __init__(self):
        self.draws, self.episode = 0, None

    def reset(self, options=None):
        if options and "episode" in options:
            self.episode = options["episode"]
        else:
            self.draws += 1
            self.episode = f"fresh{self.draws}"
        return {"episode": self.episode}, {}


def test_replay_failures_brings_back_failed_episodes_once_each_and_never_successes():
    env = _Episodes()
    env.reset()
    always = Rollout.__new__(Rollout)  # only the replay bookkeeping is exercised: no policy, no rendering
    always.cfg = PPOConfig(replay_failures=1.0, replay_buffer=2)
    always.rng, always.failed = np.random.default_rng(0), []
    obs, replay = always._next_episode(env, success=True)  # nothing failed yet: a fresh draw
    assert (obs["episode"], replay) == ("fresh2", False)
    obs, replay = always._next_episode(env, success=False)  # fresh2 failed: replayed at once
    assert (obs["episode"], replay) == ("fresh2", True) and always.failed == []
    obs, replay = always._next_episode(env, success=True)  # the replay succeeded: not queued again
    assert (obs["episode"], replay) == ("fresh3", False)

    queued = Rollout.__new__(Rollout)  # queues failures but (practically) never replays them
    queued.cfg = PPOConfig(replay_failures=1e-12, replay_buffer=2)
    queued.rng, queued.failed = np.random.default_rng(0), []
    for _ in range(3):  # three failures into a buffer of two: the oldest is dropped
        queued._next_episode(env, success=False)
    assert queued.failed == ["fresh4", "fresh5"]

    never = Rollout.__new__(Rollout)
    never.cfg, never.rng, never.failed = PPOConfig(), np.random.default_rng(0), []
    assert [never._next_episode(env, success=False)[1] for _ in range(5)] == [False] * 5
    assert never.failed == [] and env.episode == "fresh11"


def test_collision_penalty_reaches_the_rollout_rewards_at_refused_forwards():
    torch.manual_seed(0)
    policy = PointNavResNetPolicy(PolicyNetConfig())
    with torch.no_grad():  # an actor that always drives forward: it reaches a wall within the rollout
        policy.action_distribution.linear.weight.zero_()
        policy.action_distribution.linear.bias.copy_(torch.tensor([-30.0, 30.0, -30.0, -30.0]))
    rewards = []
    for penalty in (0.0, 1.0):
        envs = make_envs(2, "train", 5)  # the same episodes and, with the same generator, the same actions
        try:
            cfg = PPOConfig(num_envs=2, rollout_steps=60, collision_penalty=penalty)
            rewards.append(Rollout(envs, cfg, policy, torch.Generator().manual_seed(0)).collect()["reward"])
            # STOP adds no collision and reports the episode's count (the always-forward episodes run on)
            collisions = sum(e.step(0)[4]["collisions"] for e in envs)
        finally:
            for e in envs:
                e.close()
    diff = (rewards[1] - rewards[0]).numpy()
    assert set(np.round(diff, 6).ravel()) <= {0.0, -1.0} and (diff < 0).any()
    assert int((diff < 0).sum()) == collisions


def test_tight_starts_begin_the_first_and_every_later_rollout_episode_beside_an_obstacle():
    torch.manual_seed(0)
    policy = PointNavResNetPolicy(PolicyNetConfig())
    with torch.no_grad():  # an actor that always calls STOP: every step ends an episode and draws the next
        policy.action_distribution.linear.weight.zero_()
        policy.action_distribution.linear.bias.copy_(torch.tensor([30.0, -30.0, -30.0, -30.0]))
    envs = make_envs(2, "train", 5)
    try:
        rollout = Rollout(envs, PPOConfig(num_envs=2, rollout_steps=3, tight_starts=1.0), policy,
                          torch.Generator().manual_seed(0))
        firsts = [e.episode.episode_id for e in envs]
        rollout.collect()
        assert len(rollout.finished) == 6
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
