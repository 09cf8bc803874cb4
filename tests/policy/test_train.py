"""DAgger training: collection labels every step with the expert, and a few updates reduce the loss."""

import csv
import dataclasses

import numpy as np
import pytest
import torch

from navbench.policy.net import (
    InferenceConfig,
    PointNavAgentPolicy,
    PointNavResNetPolicy,
    PolicyNetConfig,
    prepare_depth,
)
from navbench.policy.rollout import make_envs
from navbench.policy.train import Collector, EpisodeBuffer, TrainConfig, evaluate, iteration_lr, train, train_step


def _collect(cfg: TrainConfig, frames: int, beta: float = 1.0):
    """An untrained policy's rollouts (beta: the expert's share of the executed actions)."""
    torch.manual_seed(0)
    policy = PointNavResNetPolicy(PolicyNetConfig())
    envs = make_envs(cfg.num_envs, "train", seed=0)
    segments, successes = Collector(envs, cfg, np.random.default_rng(0), policy).collect(frames, beta=beta)
    for env in envs:
        env.close()
    return policy, segments, successes


def test_oracle_rollouts_are_whole_labelled_episodes():
    cfg = TrainConfig(num_envs=2, random_action_prob=0.0, max_episode_steps=200)
    policy, segments, successes = _collect(cfg, frames=400)
    assert segments, "at least one finished episode"
    for seg in segments:
        assert not seg["mask"][0] and seg["mask"][1:].all()  # starts at the episode's first step
        assert seg["prev"][0] == 0 and (seg["prev"][1:] == seg["label"][:-1]).all()  # beta=1: oracle acts
        assert "depth" not in seg and seg["feat"].dtype == np.float16  # the frozen encoder's outputs
        assert seg["feat"].shape[1:] == (int(np.prod(policy.net.visual_encoder.output_shape)),)
        assert seg["label"][-1] == 0 or len(seg["label"]) == cfg.max_episode_steps  # STOP or cut
    assert successes == [1.0] * len(segments)  # the expert reaches every goal it stops at


def _frozen_encoder_batch(cfg: TrainConfig):
    """An untrained policy with its encoder frozen, and a batch of whole episodes from its rollouts."""
    policy, segments, _ = _collect(cfg, frames=90)
    policy.net.visual_encoder.requires_grad_(False)
    buffer = EpisodeBuffer(10_000)
    for seg in segments:
        buffer.add(seg)
    return policy, buffer.sample(np.random.default_rng(0), cfg.batch_episodes)


@pytest.mark.parametrize("bf16", [False, True])
def test_a_few_updates_reduce_the_imitation_loss(bf16):
    cfg = TrainConfig(num_envs=2, max_episode_steps=30, batch_episodes=4, lr=1e-3, bf16=bf16)
    policy, batch = _frozen_encoder_batch(cfg)
    assert batch["feat"].shape[:2] == batch["label"].shape
    opt = torch.optim.Adam([p for p in policy.parameters() if p.requires_grad], lr=cfg.lr)
    policy.train()
    losses = [train_step(policy, opt, batch, cfg)[0] for _ in range(15)]
    assert losses[-1] < 0.7 * losses[0]
    assert all(p.dtype == torch.float32 for p in policy.parameters())  # autocast leaves the weights fp32


def test_bf16_updates_run_the_forward_pass_in_bfloat16_and_track_fp32():
    cfg = TrainConfig(num_envs=2, max_episode_steps=30, batch_episodes=4, lr=1e-3)
    policy, batch = _frozen_encoder_batch(cfg)
    state = {k: v.clone() for k, v in policy.state_dict().items()}
    first, logits_dtype = {}, {}
    policy.action_distribution.linear.register_forward_hook(
        lambda _module, _inputs, out: logits_dtype.__setitem__(bf16, out.dtype))
    for bf16 in (False, True):
        policy.load_state_dict(state)
        opt = torch.optim.Adam([p for p in policy.parameters() if p.requires_grad], lr=cfg.lr)
        first[bf16] = train_step(policy, opt, batch, dataclasses.replace(cfg, bf16=bf16))[0]
    assert logits_dtype == {False: torch.float32, True: torch.bfloat16}
    # bfloat16 keeps 8 bits of mantissa: the loss may move in the third digit, not the first. (Whether it moves
    # at all depends on the CPU: an untrained policy's logits are near 0, and on an AVX2-only EPYC the loss came
    # out equal to fp32's to the last digit, where AVX512-BF16 kernels moved it.)
    assert first[True] == pytest.approx(first[False], rel=0.02)


def test_stored_features_are_the_encoder_output_and_acting_matches_the_full_forward_pass():
    # Collection stores what act_and_encode hands out instead of encoding each frame again, so that
    # must be the encoder's output on the frame, and the split forward pass must act as forward() does.
    torch.manual_seed(0)
    policy = PointNavResNetPolicy(PolicyNetConfig()).eval()
    learner = PointNavAgentPolicy(policy, num_envs=3, config=InferenceConfig(channels_last=False))
    rng = np.random.default_rng(0)
    hidden, prev, masks = policy.initial_hidden(3), torch.zeros(3, dtype=torch.long), torch.zeros(3, dtype=torch.bool)
    for _ in range(3):
        depth = rng.random((3, 256, 256, 1), dtype=np.float32)
        goal = rng.random((3, 2), dtype=np.float32) * [5, 6] - [0, 3]
        actions, visual = learner.act_and_encode(depth, goal)
        with torch.inference_mode():
            x = prepare_depth(depth)
            torch.testing.assert_close(visual, policy.net.encode_depth(x))
            logits, _, hidden = policy(x, torch.from_numpy(goal), prev, masks, hidden)
        np.testing.assert_array_equal(actions, logits.argmax(-1).numpy())
        torch.testing.assert_close(learner.hidden, hidden)
        prev, masks = torch.from_numpy(actions), torch.ones(3, dtype=torch.bool)


def test_the_expert_reaches_the_goal_of_a_train_episode_and_stops_where_told():
    from navbench.policy.rollout import make_expert

    env = make_envs(1, "train", seed=1)[0]
    assert make_expert(env, 0.1, 0.15).success_distance == 0.1
    follower = make_expert(env, 0.2, 0.15)
    while True:
        _, _, term, trunc, info = env.step(follower.next_action(env.agent_position, env.agent_rotation))
        if term or trunc:
            break
    env.close()
    assert info["success"] and info["distance_to_goal"] < 0.2


def test_whole_episode_batches_group_similar_lengths():
    buffer = EpisodeBuffer(10_000)
    for L in (5, 6, 7, 50, 52, 200):
        buffer.add({"feat": np.zeros((L, 4), np.float16), "goal": np.zeros((L, 2), np.float32),
                    "prev": np.zeros(L, np.int64), "mask": np.arange(L) > 0, "label": np.ones(L, np.int64),
                    "weight": np.ones(L, np.float32)})
    rng = np.random.default_rng(0)
    for _ in range(20):
        batch = buffer.sample(rng, 3)
        lengths = batch["weight"].sum(0)
        assert batch["label"].shape[0] == lengths.max()  # padded to the longest of the three only
        assert batch["weight"].sum() == lengths.sum()  # padding weighs nothing
    assert {int(buffer.sample(np.random.default_rng(s), 3)["label"].shape[0]) for s in range(30)} \
        == {7, 50, 52, 200}


def test_buffer_drops_its_oldest_episodes_beyond_the_cap_set_on_the_command_line():
    from navbench.cli import build_parser

    args = build_parser().parse_args(["train", "dagger", "--buffer-frames", "100", "--lr", "1e-4"])
    cfg = TrainConfig(buffer_frames=args.buffer_frames, lr=args.lr, iterations=args.iterations)
    assert (cfg.buffer_frames, cfg.lr, cfg.iterations) == (100, 1e-4, TrainConfig().iterations)
    buffer = EpisodeBuffer(cfg.buffer_frames)
    for i, L in enumerate((40, 30, 50, 20)):
        buffer.add({"label": np.full(L, i, np.int64)})
    # 40 + 30 + 50 = 120 > 100 drops the first; + 20 = 100 keeps the rest
    assert [int(e["label"][0]) for e in buffer.episodes] == [1, 2, 3] and buffer.frames == 100


def test_the_learner_trains_everything_but_the_visual_encoder():
    from navbench.policy.train import build_learner

    policy = build_learner(TrainConfig())
    assert not any(p.requires_grad for p in policy.net.visual_encoder.parameters())
    others = [p for n, p in policy.named_parameters() if not n.startswith("net.visual_encoder.")]
    assert others and all(p.requires_grad for p in others)


def test_steps_after_a_blocked_forward_weigh_collision_weight():
    # Learner-only rollouts of an untrained policy bump into things; the step after each blocked FORWARD
    # (its point goal unchanged) carries collision_weight on top of the inflection weight.
    _, segments, _ = _collect(TrainConfig(num_envs=2, max_episode_steps=40, random_action_prob=0.5,
                                          collision_weight=5.0, inflection_weight=1.0), frames=160, beta=0.0)
    blocked = 0
    for seg in segments:
        for t in range(1, len(seg["label"])):
            weighted = seg["weight"][t] == 5.0
            assert weighted or seg["weight"][t] == 1.0
            assert not weighted or seg["prev"][t] == 1  # only FORWARDs collide
            if seg["prev"][t] == 1 and np.allclose(seg["goal"][t], seg["goal"][t - 1]):
                assert weighted  # did not move at all: blocked
            blocked += weighted
        assert seg["weight"][0] == 1.0
    assert blocked > 0, "the scripted rollouts must hit something for this test to mean anything"


def test_steps_near_the_goal_weigh_endgame_weight():
    # Expert-driven rollouts reach their goals; the steps within endgame_radius of the goal (where the
    # STOP is decided) carry endgame_weight, all others 1.
    cfg = TrainConfig(num_envs=2, max_episode_steps=120, random_action_prob=0.0, endgame_weight=4.0,
                      inflection_weight=1.0)
    _, segments, _ = _collect(cfg, frames=240)
    near = np.concatenate([seg["goal"][:, 0] < cfg.endgame_radius for seg in segments])
    weights = np.concatenate([seg["weight"] for seg in segments])
    assert near.any(), "the expert must reach a goal for this test to mean anything"
    assert np.array_equal(weights, np.where(near, 4.0, 1.0).astype(np.float32))


def test_cosine_schedule_runs_from_lr_to_lr_min_and_constant_stays():
    cfg = TrainConfig(iterations=5, lr=4e-4, lr_min=2e-5, lr_schedule="cosine")
    rates = [iteration_lr(cfg, i) for i in range(cfg.iterations)]
    assert rates[0] == pytest.approx(4e-4) and rates[-1] == pytest.approx(2e-5)
    assert rates[2] == pytest.approx(0.5 * (4e-4 + 2e-5))  # half way down the cosine
    assert all(a > b for a, b in zip(rates, rates[1:]))
    assert iteration_lr(dataclasses.replace(cfg, lr_schedule="constant"), 3) == 4e-4
    with pytest.raises(ValueError, match="linear"):
        iteration_lr(dataclasses.replace(cfg, lr_schedule="step"), 0)


def test_tight_starts_keep_the_goal_and_start_beside_an_obstacle():
    from navbench.policy.rollout import TIGHT_CLEARANCE, TIGHT_MIN_DISTANCE, reset_maybe_tight

    env = make_envs(1, "train", seed=3)[0]
    rng = np.random.default_rng(0)
    state = rng.bit_generator.state
    reset_maybe_tight(env, rng, 0.0)  # off: the env's own draw, and the generator is not touched
    assert rng.bit_generator.state == state and not env.episode.episode_id.endswith("-tight")
    env.reset(seed=3)
    starts = []
    for _ in range(6):
        obs = reset_maybe_tight(env, rng, 1.0)
        ep = env.episode
        assert ep.episode_id.endswith("-tight")
        original = next(e for e in env.dataset.episodes if e.episode_id == ep.episode_id[:-len("-tight")])
        assert ep.goals == original.goals and ep.scene_id == original.scene_id
        clearance = env.navgrid.navigable_clearance()
        i, j = env.navgrid.world_to_grid(np.asarray(ep.start_position))
        assert 0 < clearance[i, j] <= TIGHT_CLEARANCE + 1e-9
        assert TIGHT_MIN_DISTANCE <= env.distance_to_goal() < np.inf
        assert np.allclose(env.agent_position[[0, 2]], np.asarray(ep.start_position)[[0, 2]])
        assert np.isclose(obs["pointgoal_with_gps_compass"][0], np.linalg.norm(
            (np.asarray(ep.goals[0].position) - np.asarray(ep.start_position))[[0, 2]]), atol=1e-4)
        starts.append(tuple(ep.start_position))
    assert len(set(starts)) == 6
    env.close()


def test_act_bf16_collects_the_same_expert_episodes_with_bfloat16_rounded_features():
    # The expert acts (beta = 1, no random actions), so the episodes are the same; only the stored encoder
    # outputs change, by bf16's rounding.
    cfg = TrainConfig(num_envs=2, random_action_prob=0.0, max_episode_steps=40)
    runs = {act_bf16: _collect(dataclasses.replace(cfg, act_bf16=act_bf16), frames=80)[1] for act_bf16 in (False, True)}
    assert len(runs[False]) == len(runs[True]) >= 2
    for a, b in zip(runs[False], runs[True]):
        np.testing.assert_array_equal(a["label"], b["label"])
        np.testing.assert_array_equal(a["goal"], b["goal"])
        fa, fb = a["feat"].astype(np.float32), b["feat"].astype(np.float32)
        assert b["feat"].dtype == np.float16 and not np.array_equal(fa, fb)
        assert np.linalg.norm(fa - fb) / np.linalg.norm(fa) < 0.05


def test_an_iteration_in_which_no_whole_episode_ends_makes_no_update_and_the_run_goes_on(tmp_path):
    # 8 envs x 10 steps an iteration against 30-step episodes: they first end in the third collection
    cfg = TrainConfig(num_envs=8, iterations=3, frames_per_iteration=80, max_episode_steps=30, monitor_episodes=0,
                      batch_episodes=2, random_action_prob=0.0)
    last = train(cfg, tmp_path / "dagger.pth", state_dir=tmp_path / "state", log_every=lambda _: None)
    with open(tmp_path / "dagger.log.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["updates"] for r in rows[:2]] == ["0", "0"] and rows[0]["loss"] == "nan"  # nothing handed over yet
    assert last["iteration"] == 3 and last["updates"] >= 1 and last["frames"] == 240


def test_the_monitor_scores_select_episodes_never_val(monkeypatch):
    import navbench.policy.train as train_module

    asked = []
    real = train_module.split_file
    monkeypatch.setattr(train_module, "split_file",
                        lambda task, split: asked.append((task, split)) or real(task, split))
    torch.manual_seed(0)
    result = evaluate(PointNavResNetPolicy(PolicyNetConfig()), episodes=1, max_steps=3)
    assert asked == [("pointnav", "select")]
    assert set(result) == {"select_sr", "select_spl"}
