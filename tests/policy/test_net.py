"""PointNav policy network: habitat key layout, recurrence/reset semantics, stateful wrapper."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from navbench.policy import (
    InferenceConfig,
    PointNavAgentPolicy,
    PointNavResNetPolicy,
    PolicyNetConfig,
    load_checkpoint,
    prepare_depth,
)
from navbench.policy.net import LSTMStateEncoder
from navbench.policy.resnet import GroupNorm, RunningMeanAndVar


def _block(prefix: str, cin: int, cout: int, downsample: bool) -> dict[str, tuple[int, ...]]:
    keys = {
        f"{prefix}.convs.0.weight": (cout, cin, 3, 3),
        f"{prefix}.convs.1.weight": (cout,),
        f"{prefix}.convs.1.bias": (cout,),
        f"{prefix}.convs.3.weight": (cout, cout, 3, 3),
        f"{prefix}.convs.4.weight": (cout,),
        f"{prefix}.convs.4.bias": (cout,),
    }
    if downsample:
        keys |= {
            f"{prefix}.downsample.0.weight": (cout, cin, 1, 1),
            f"{prefix}.downsample.1.weight": (cout,),
            f"{prefix}.downsample.1.bias": (cout,),
        }
    return keys


def habitat_depth_pointnav_shapes() -> dict[str, tuple[int, ...]]:
    """habitat-baselines PointNavResNetPolicy (depth 224x224x1, resnet18, 32 planes, LSTM 2x512, 4 actions).

    Written from habitat's resnet.py / resnet_policy.py / rnn_state_encoder.py / policy.py, not from our model.
    """
    bb = "net.visual_encoder.backbone"
    shapes: dict[str, tuple[int, ...]] = {
        "net.prev_action_embedding.weight": (5, 32),
        "net.tgt_embeding.weight": (32, 3),
        "net.tgt_embeding.bias": (32,),
        f"{bb}.conv1.0.weight": (32, 1, 7, 7),
        f"{bb}.conv1.1.weight": (32,),
        f"{bb}.conv1.1.bias": (32,),
    }
    widths = [32, 32, 64, 128, 256]
    for layer in range(1, 5):
        cin, cout = widths[layer - 1], widths[layer]
        shapes |= _block(f"{bb}.layer{layer}.0", cin, cout, downsample=layer > 1)
        shapes |= _block(f"{bb}.layer{layer}.1", cout, cout, downsample=False)
    shapes |= {
        # 224 -> avg pool 112 -> /32 -> ceil 4x4 = 16 cells; 2048 / 16 = 128 channels.
        "net.visual_encoder.compression.0.weight": (128, 256, 3, 3),
        "net.visual_encoder.compression.1.weight": (128,),
        "net.visual_encoder.compression.1.bias": (128,),
        "net.visual_fc.1.weight": (512, 2048),
        "net.visual_fc.1.bias": (512,),
        "net.state_encoder.rnn.weight_ih_l0": (2048, 576),
        "net.state_encoder.rnn.weight_hh_l0": (2048, 512),
        "net.state_encoder.rnn.bias_ih_l0": (2048,),
        "net.state_encoder.rnn.bias_hh_l0": (2048,),
        "net.state_encoder.rnn.weight_ih_l1": (2048, 512),
        "net.state_encoder.rnn.weight_hh_l1": (2048, 512),
        "net.state_encoder.rnn.bias_ih_l1": (2048,),
        "net.state_encoder.rnn.bias_hh_l1": (2048,),
        "action_distribution.linear.weight": (4, 512),
        "action_distribution.linear.bias": (4,),
        "critic.fc.weight": (1, 512),
        "critic.fc.bias": (1,),
    }
    return shapes


@pytest.fixture(scope="module")
def policy() -> PointNavResNetPolicy:
    torch.manual_seed(0)
    p = PointNavResNetPolicy().eval()
    # habitat initialises the actor with gain 0.01, which leaves all logits near-tied; a trained
    # policy is decisive, so spread the logits to make argmax comparisons meaningful.
    torch.nn.init.normal_(p.action_distribution.linear.weight, std=0.3)
    return p


def _obs(rng: np.random.Generator, *lead: int) -> tuple[torch.Tensor, torch.Tensor]:
    depth = torch.from_numpy(rng.random((*lead, 224, 224, 1), dtype=np.float32))
    goal = torch.from_numpy(np.stack([rng.uniform(0.5, 5, lead), rng.uniform(-3, 3, lead)], -1).astype(np.float32))
    return depth, goal


def test_state_dict_matches_habitat_layout(policy: PointNavResNetPolicy) -> None:
    ours = {k: tuple(v.shape) for k, v in policy.state_dict().items()}
    assert ours == habitat_depth_pointnav_shapes()


def test_parameter_count_is_about_8_5m(policy: PointNavResNetPolicy) -> None:
    n = sum(p.numel() for p in policy.parameters())
    assert 8_400_000 < n < 8_600_000


def test_synthetic_habitat_checkpoint_loads_every_tensor(tmp_path) -> None:
    gen = torch.Generator().manual_seed(1)
    sd = {k: torch.randn(shape, generator=gen) for k, shape in habitat_depth_pointnav_shapes().items()}
    path = tmp_path / "habitat_style.pth"
    torch.save({"state_dict": {f"actor_critic.{k}": v for k, v in sd.items()}, "config": {}}, path)
    loaded = load_checkpoint(path).state_dict()
    assert loaded.keys() == sd.keys()
    for k, v in sd.items():
        assert torch.equal(loaded[k], v), k


def test_normalizer_adds_habitat_buffers() -> None:
    with torch.device("meta"):  # shapes only; skips the slow random init
        keys = PointNavResNetPolicy(PolicyNetConfig(normalize_visual_inputs=True)).state_dict()
    assert tuple(keys["net.visual_encoder.running_mean_and_var._mean"].shape) == (1, 1, 1, 1)
    assert tuple(keys["net.visual_encoder.running_mean_and_var._var"].shape) == (1, 1, 1, 1)
    assert tuple(keys["net.visual_encoder.running_mean_and_var._count"].shape) == ()


def test_running_mean_and_var_merges_batches_and_normalises() -> None:
    gen = torch.Generator().manual_seed(0)
    batches = [torch.randn(4, 2, 5, 5, generator=gen) * 3 + 1, torch.randn(4, 2, 5, 5, generator=gen) * 2 - 1]
    norm = RunningMeanAndVar(2).train()
    for b in batches:
        norm(b)
    everything = torch.cat(batches).transpose(0, 1).reshape(2, -1)
    torch.testing.assert_close(norm._mean.flatten(), everything.mean(1))
    torch.testing.assert_close(norm._var.flatten(), everything.var(1, unbiased=False))
    assert norm._count.item() == 8
    x = torch.randn(1, 2, 5, 5, generator=gen)
    expected = (x - everything.mean(1).view(1, 2, 1, 1)) / everything.var(1, unbiased=False).sqrt().view(1, 2, 1, 1)
    torch.testing.assert_close(norm.eval()(x), expected)


def test_group_norm_is_torchs_in_fp32_and_normalises_bfloat16_in_fp32() -> None:
    gen = torch.Generator().manual_seed(0)
    ours, torchs = GroupNorm(4, 8), torch.nn.GroupNorm(4, 8)
    with torch.no_grad():
        for p in ours.parameters():
            p.copy_(torch.randn(p.shape, generator=gen))
    torchs.load_state_dict(ours.state_dict())  # the same keys and shapes
    x = (torch.randn(2, 8, 6, 6, generator=gen) * 3 + 2).contiguous(memory_format=torch.channels_last)
    assert torch.equal(ours(x), torchs(x))
    with torch.autocast("cpu", dtype=torch.bfloat16):
        y = ours(x.bfloat16())
    assert y.dtype == torch.bfloat16 and y.is_contiguous(memory_format=torch.channels_last)
    # statistics in fp32 over the bfloat16-rounded input: only the output's rounding is left
    expected = torchs(x.bfloat16().float())
    torch.testing.assert_close(y.float(), expected, rtol=1e-2, atol=1e-2)
    assert not torch.equal(y.float(), expected)  # it did hand back bfloat16


def test_sequence_mode_equals_step_by_step(policy: PointNavResNetPolicy) -> None:
    rng = np.random.default_rng(2)
    steps, n = 6, 3
    depth, goal = _obs(rng, steps, n)
    prev = torch.from_numpy(rng.integers(0, 4, (steps, n)))
    masks = torch.ones(steps, n, dtype=torch.bool)
    masks[0, 1] = False  # env 1 starts an episode in the first step
    masks[3, 0] = False  # env 0 resets mid-sequence
    masks[4, 2] = False
    hidden0 = torch.randn(n, 4, 512) * 0.5
    with torch.no_grad():
        logits_seq, value_seq, hidden_seq = policy(depth, goal, prev, masks, hidden0)
        hidden = hidden0
        for t in range(steps):
            logits, value, hidden = policy(depth[t], goal[t], prev[t], masks[t], hidden)
            torch.testing.assert_close(logits_seq[t], logits, atol=1e-4, rtol=1e-4)
            torch.testing.assert_close(value_seq[t], value, atol=1e-4, rtol=1e-4)
    torch.testing.assert_close(hidden_seq, hidden, atol=1e-4, rtol=1e-4)
    assert logits_seq.shape == (steps, n, 4) and value_seq.shape == (steps, n) and hidden_seq.shape == (n, 4, 512)


def test_single_step_cell_equals_nn_lstm() -> None:
    # Acting runs the LSTM cell as plain matrix products (LSTMStateEncoder._step); it must be nn.LSTM's step,
    # biases included (they start at zero in a fresh policy, so randomise everything here).
    torch.manual_seed(0)
    enc = LSTMStateEncoder(576, 512, 2)
    with torch.no_grad():
        for p in enc.parameters():
            p.normal_(0, 0.05)
        x, hidden = torch.randn(1, 5, 576), torch.randn(5, 4, 512) * 0.5
        out, new_hidden = enc(x, hidden, torch.ones(1, 5, dtype=torch.bool))
        h, c = hidden.transpose(0, 1).chunk(2, dim=0)
        ref_out, (ref_h, ref_c) = enc.rnn(x, (h.contiguous(), c.contiguous()))
    torch.testing.assert_close(out, ref_out, atol=1e-5, rtol=1e-5)
    torch.testing.assert_close(new_hidden, torch.cat([ref_h, ref_c]).transpose(0, 1), atol=1e-5, rtol=1e-5)


def test_mask_zero_resets_state_and_previous_action(policy: PointNavResNetPolicy) -> None:
    rng = np.random.default_rng(3)
    depth, goal = _obs(rng, 2)
    stale = torch.randn(2, 4, 512)
    off = torch.zeros(2, dtype=torch.bool)
    with torch.no_grad():
        reset_out = policy(depth, goal, torch.tensor([3, 1]), off, stale)
        fresh_out = policy(depth, goal, torch.tensor([0, 0]), off, torch.zeros(2, 4, 512))
        kept_out = policy(depth, goal, torch.tensor([3, 1]), ~off, stale)
    torch.testing.assert_close(reset_out[0], fresh_out[0])
    torch.testing.assert_close(reset_out[2], fresh_out[2])
    assert not torch.allclose(kept_out[2], fresh_out[2], atol=1e-3)


def test_hidden_state_packs_h_before_c(policy: PointNavResNetPolicy) -> None:
    rng = np.random.default_rng(4)
    depth, goal = _obs(rng, 1)
    with torch.no_grad():
        _, _, hidden = policy(depth, goal, torch.zeros(1), torch.zeros(1), policy.initial_hidden(1))
    # The LSTM's output h of the last layer is bounded by tanh; c is not, and after one step from
    # zero state c = i * g, so |h| = |o * tanh(c)| <= |tanh(c)| <= |c| holds row by row.
    h, c = hidden[0, :2], hidden[0, 2:]
    assert torch.all(h.abs() <= c.abs().tanh() + 1e-6)
    assert not torch.allclose(h, c)


def _agent(policy: PointNavResNetPolicy, n: int = 1) -> PointNavAgentPolicy:
    return PointNavAgentPolicy(policy, n, InferenceConfig(channels_last=False))


def test_agent_returns_int_actions_and_resizes_depth(policy: PointNavResNetPolicy) -> None:
    rng = np.random.default_rng(5)
    agent = _agent(policy, 2)
    actions = agent.act(rng.random((2, 256, 320, 1), dtype=np.float32), np.array([[2.0, 0.3], [1.0, -1.0]]))
    assert actions.dtype == np.int64 and actions.shape == (2,)
    assert set(actions.tolist()) <= {0, 1, 2, 3}
    assert agent.masks.all() and torch.equal(agent.prev_actions, torch.from_numpy(actions))


def _run(agent: PointNavAgentPolicy, obs: list, goals: list) -> None:
    for (depth, goal), g in zip(obs, goals):
        agent.act(depth, goal, goal_world=g)


@pytest.mark.parametrize("shift, expect_reset", [(0.15, True), (0.05, False)])
def test_goal_move_resets_hidden_only_beyond_threshold(
    policy: PointNavResNetPolicy, shift: float, expect_reset: bool
) -> None:
    rng = np.random.default_rng(6)
    obs = [tuple(x.numpy() for x in _obs(rng, 1)) for _ in range(4)]
    goal = np.array([[1.0, 0.0, -2.0]])
    agent = _agent(policy)
    _run(agent, obs[:3], [goal] * 3)
    agent.act(*obs[3], goal_world=goal + np.array([[shift, 0.0, 0.0]]))
    fresh = _agent(policy)
    fresh.act(*obs[3])  # first step of an episode: zero state, start token
    assert torch.allclose(agent.hidden, fresh.hidden, atol=1e-5) == expect_reset


def test_reset_of_one_env_leaves_the_other(policy: PointNavResNetPolicy) -> None:
    rng = np.random.default_rng(7)
    agent = _agent(policy, 2)
    depth, goal = (x.numpy() for x in _obs(rng, 2))
    agent.act(depth, goal, goal_world=np.zeros((2, 3)))
    before = agent.hidden.clone()
    agent.reset(1)
    assert torch.equal(agent.hidden[0], before[0])
    assert not agent.hidden[1].any() and not agent.masks[1] and agent.masks[0]
    assert np.isnan(agent.goal_world[1]).all() and not np.isnan(agent.goal_world[0]).any()
    agent.reset_hidden(0)
    assert not agent.hidden.any() and agent.goal_world[0].tolist() == [0.0, 0.0, 0.0]


def test_channels_last_gives_the_same_actions(policy: PointNavResNetPolicy) -> None:
    base, other = policy, copy.deepcopy(policy)  # the wrapper converts its policy in place
    rng = np.random.default_rng(8)
    depth, goal = (x.numpy() for x in _obs(rng, 8))
    a = PointNavAgentPolicy(base, 8, InferenceConfig(channels_last=False)).act(depth, goal)
    b = PointNavAgentPolicy(other, 8, InferenceConfig(channels_last=True)).act(depth, goal)
    np.testing.assert_array_equal(a, b)


def test_prepare_depth_area_averages() -> None:
    block = np.arange(4, dtype=np.float32).reshape(2, 2) / 4.0
    big = np.kron(block, np.ones((224, 224), dtype=np.float32))  # 448 x 448, four constant quadrants
    big[0, 0] = 1.0  # one bright pixel: area averaging spreads it over its 2x2 cell
    out = prepare_depth(big)
    assert out.shape == (1, 224, 224, 1)
    assert out[0, 0, 0, 0].item() == pytest.approx(0.25)
    assert out[0, 200, 200, 0].item() == pytest.approx(0.75)
    with pytest.raises(ValueError, match="depth must be"):
        prepare_depth(np.zeros((1, 4, 4, 3)))


def test_encode_depth_reads_each_pixel_where_the_encoder_expects_it(policy: PointNavResNetPolicy) -> None:
    # encode_depth builds its NCHW view without a permute (speed); the result must be the encoder's on
    # the frame itself, and a non-square frame shows that height and width were not swapped.
    depth = torch.rand(3, 64, 96, 1, generator=torch.Generator().manual_seed(0))
    with torch.inference_mode():
        expected = policy.net.visual_encoder(depth.permute(0, 3, 1, 2).contiguous()).flatten(1)
        got = policy.net.encode_depth(depth)
    assert got.shape == expected.shape and torch.allclose(got, expected, atol=1e-5)
    with pytest.raises(RuntimeError), torch.inference_mode():  # a 3-channel frame is refused, not cut to one
        policy.net.encode_depth(torch.rand(3, 64, 96, 3))


def _fixed_logits(agent: PointNavAgentPolicy, probs: list[float]) -> None:
    """Make ``agent``'s policy output the same distribution for every env, without running the network."""
    logits = torch.log(torch.tensor(probs))
    agent.policy.net.encode_depth = lambda x: torch.zeros(x.shape[0], 1)
    agent.policy.forward_features = lambda feat, goal, prev, masks, hidden: (
        logits.expand(1, feat.shape[1], 4).clone(), torch.zeros(1, feat.shape[1], 1), hidden)


def test_sampled_actions_follow_the_policys_distribution(policy: PointNavResNetPolicy) -> None:
    n, calls = 200, 20  # 4,000 draws
    probs = [0.1, 0.2, 0.3, 0.4]
    depth, goal = np.zeros((n, 224, 224, 1), np.float32), np.ones((n, 2), np.float32)
    sampled = PointNavAgentPolicy(copy.deepcopy(policy), n, InferenceConfig(channels_last=False, decoding="sample"))
    _fixed_logits(sampled, probs)
    draws = np.concatenate([sampled.act(depth, goal) for _ in range(calls)])
    np.testing.assert_allclose(np.bincount(draws, minlength=4) / draws.size, probs, atol=0.03)
    greedy = PointNavAgentPolicy(copy.deepcopy(policy), n, InferenceConfig(channels_last=False))
    _fixed_logits(greedy, probs)
    assert (greedy.act(depth, goal) == 3).all()


def test_temperature_sharpens_the_sampled_distribution(policy: PointNavResNetPolicy) -> None:
    n, calls, probs = 200, 20, np.array([0.1, 0.2, 0.3, 0.4])
    depth, goal = np.zeros((n, 224, 224, 1), np.float32), np.ones((n, 2), np.float32)
    for t in (0.5, 2.0):
        agent = PointNavAgentPolicy(copy.deepcopy(policy), n,
                                    InferenceConfig(channels_last=False, decoding="sample", temperature=t))
        _fixed_logits(agent, list(probs))
        draws = np.concatenate([agent.act(depth, goal) for _ in range(calls)])
        expected = probs ** (1 / t) / (probs ** (1 / t)).sum()  # softmax(log p / t)
        np.testing.assert_allclose(np.bincount(draws, minlength=4) / draws.size, expected, atol=0.03)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="temperature"):
            InferenceConfig(decoding="sample", temperature=bad)


def test_sampled_actions_depend_on_each_envs_seed_not_on_the_batch(policy: PointNavResNetPolicy) -> None:
    rng = np.random.default_rng(9)
    steps = [tuple(x.numpy() for x in _obs(rng, 2)) for _ in range(12)]
    cfg = InferenceConfig(channels_last=False, decoding="sample")

    def actions(n: int, envs: list[int], seeds: list[int]) -> np.ndarray:
        agent = PointNavAgentPolicy(policy, n, cfg)
        for i, s in enumerate(seeds):
            agent.reset(i, seed=s)
        return np.stack([agent.act(d[envs], g[envs]) for d, g in steps])

    both = actions(2, [0, 1], [7, 8])
    np.testing.assert_array_equal(both[:, 0], actions(1, [0], [7])[:, 0])
    np.testing.assert_array_equal(both[:, 1], actions(1, [1], [8])[:, 0])
    np.testing.assert_array_equal(both, actions(2, [0, 1], [7, 8]))  # reproducible
    assert not np.array_equal(both[:, 0], actions(1, [0], [9])[:, 0])  # another seed, other draws


def test_least_tried_takes_the_argmax_except_where_the_pose_repeats(policy: PointNavResNetPolicy) -> None:
    n, probs = 400, [0.5, 0.2, 0.2, 0.1]  # argmax is STOP (0); draws are often something else
    depth = np.zeros((n, 224, 224, 1), np.float32)
    agent = PointNavAgentPolicy(copy.deepcopy(policy), n,
                                InferenceConfig(channels_last=False, decoding="least-tried"))
    _fixed_logits(agent, probs)
    for i in range(n):
        agent.reset(i, seed=i)
    goal = np.tile(np.float32([3.0, 0.5]), (n, 1))
    assert (agent.act(depth, goal) == 0).all()  # a first visit: argmax
    moved = goal + np.float32([0.25, 0.0])
    assert (agent.act(depth, moved) == 0).all()  # a new pose: argmax
    # back at the first pose (to within float noise, as after a turn there and back): draws
    drawn = agent.act(depth, goal + np.float32([0.003, 0.004]))
    np.testing.assert_allclose(np.bincount(drawn, minlength=4) / n, probs, atol=0.08)
    agent.reset_hidden()  # a new episode or a moved goal forgets the poses
    assert (agent.act(depth, goal) == 0).all()


def test_least_tried_draws_among_the_movements_taken_least_often_at_that_pose(policy: PointNavResNetPolicy) -> None:
    n, probs = 400, [0.05, 0.6, 0.2, 0.15]  # argmax is FORWARD
    depth = np.zeros((n, 224, 224, 1), np.float32)
    agent = PointNavAgentPolicy(copy.deepcopy(policy), n, InferenceConfig(channels_last=False, decoding="least-tried"))
    _fixed_logits(agent, probs)
    for i in range(n):
        agent.reset(i, seed=i)
    goal = np.tile(np.float32([3.0, 0.5]), (n, 1))
    assert (agent.act(depth, goal) == 1).all()  # a first visit: the argmax
    # back at the pose: FORWARD was taken here, the two turns were not; STOP keeps its 0.05
    second = agent.act(depth, goal)
    np.testing.assert_allclose(np.bincount(second, minlength=4) / n, [0.05, 0, 0.95 * 0.2 / 0.35, 0.95 * 0.15 / 0.35],
                               atol=0.05)
    third = agent.act(depth, goal)
    turned = second >= 2
    assert ((third[turned] == 0) | (third[turned] == 5 - second[turned])).all()  # STOP or the other turn
    # every movement taken once at this pose: the policy's own distribution again
    both = turned & (third >= 2)
    fourth = agent.act(depth, goal)[both]
    np.testing.assert_allclose(np.bincount(fourth, minlength=4) / len(fourth), probs, atol=0.08)


def test_decoding_is_one_of_three_and_temperature_belongs_to_sample() -> None:
    assert InferenceConfig().decoding == "argmax"
    with pytest.raises(ValueError, match="unknown decoding 'greedy'"):
        InferenceConfig(decoding="greedy")
    with pytest.raises(ValueError, match="temperature"):
        InferenceConfig(decoding="least-tried", temperature=0.5)
    assert InferenceConfig(decoding="sample", temperature=0.5).temperature == 0.5

def test_a_frozen_policy_encodes_a_repeated_frame_once_with_the_same_actions(policy: PointNavResNetPolicy) -> None:
    # an agent pressed against a wall, or turning back and forth, sees the same depth again: the encoding is
    # reused, the actions and the recurrent state unchanged
    rng = np.random.default_rng(3)
    frames = rng.random((3, 2, 224, 224, 1), dtype=np.float32)
    goals = rng.uniform(0.5, 3.0, (6, 2, 2)).astype(np.float32)
    order = [0, 0, 1, 1, 0, 2]  # frame per step: repeats, and a frame again after another
    fresh = PointNavAgentPolicy(copy.deepcopy(policy), 2)
    frozen = PointNavAgentPolicy(copy.deepcopy(policy), 2, frozen=True)
    encode = frozen.policy.net.encode_depth
    calls = []
    frozen.policy.net.encode_depth = lambda x: calls.append(1) or encode(x)
    for k, g in zip(order, goals):
        depth = frames[k].copy()
        np.testing.assert_array_equal(frozen.act(depth, g), fresh.act(frames[k], g))
        depth[:] = 0.0  # the caller's buffer, overwritten after the call: not what the next call compares with
        torch.testing.assert_close(frozen.hidden, fresh.hidden, rtol=0, atol=0)
    assert len(calls) == 3
    frozen.act(frames[2][:1], goals[0][:1], rows=[1])  # another set of envs: encoded afresh
    assert len(calls) == 4
