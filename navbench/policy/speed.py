"""Throughput of the PointNav policy on this machine (random weights; speed does not depend on them).

    navbench bench                          # reports measure_policy_speed()
    python benchmarks/policy_speed.py --all

``measure_policy_speed`` is what ``navbench bench`` reports; ``benchmarks/policy_speed.py`` wraps it.
Inference goes through :class:`PointNavAgentPolicy` so the figures include the per-step numpy <->
torch and state bookkeeping an agent pays.
"""

from __future__ import annotations

import time

import numpy as np
import torch
import torch.nn.functional as F

from navbench.policy.net import InferenceConfig, PointNavAgentPolicy, PointNavResNetPolicy, PolicyNetConfig


def _rate(step, items_per_call: int, seconds: float, warmup: int = 3) -> float:
    for _ in range(warmup):
        step()
    calls = 0
    start = time.perf_counter()
    while True:
        step()
        calls += 1
        elapsed = time.perf_counter() - start
        if elapsed >= seconds:
            return calls * items_per_call / elapsed


def inference_rate(policy: PointNavResNetPolicy, n: int, config: InferenceConfig, seconds: float,
                   device: str = "cpu") -> float:
    """Frames/s of :class:`PointNavAgentPolicy` stepping ``n`` envs at once on ``device`` (actions come back
    to the CPU each step, which also waits for the GPU)."""
    rng = np.random.default_rng(0)
    agent = PointNavAgentPolicy(policy, n, config, device=device)
    size = policy.cfg.input_size
    depth = rng.random((n, *size, 1), dtype=np.float32)
    goal = np.stack([rng.uniform(0.5, 5.0, n), rng.uniform(-np.pi, np.pi, n)], axis=1).astype(np.float32)
    return _rate(lambda: agent.act(depth, goal), n, seconds)


def _training_rate(policy: PointNavResNetPolicy, steps: int, envs: int, seconds: float) -> float:
    """Samples/s of forward + backward + Adam on (steps x envs) sequences, PPO-shaped losses."""
    policy.train()
    opt = torch.optim.Adam(policy.parameters(), lr=2.5e-4)
    gen = torch.Generator().manual_seed(0)
    depth = torch.rand(steps, envs, *policy.cfg.input_size, 1, generator=gen)
    goal = torch.rand(steps, envs, 2, generator=gen)
    actions = torch.randint(0, policy.cfg.num_actions, (steps, envs), generator=gen)
    masks = torch.rand(steps, envs, generator=gen) > 0.05
    returns = torch.randn(steps, envs, generator=gen)
    hidden = policy.initial_hidden(envs)

    def step() -> None:
        logits, value, _ = policy(depth, goal, actions, masks, hidden)
        loss = F.cross_entropy(logits.reshape(-1, logits.shape[-1]), actions.reshape(-1)) + F.mse_loss(value, returns)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()

    rate = _rate(step, steps * envs, seconds, warmup=1)
    policy.eval()
    return rate


def measure_policy_speed(
    seconds: float = 3.0, config: InferenceConfig = InferenceConfig(), training: bool = False, device: str = "cpu"
) -> dict[str, float]:
    """Inference steps/s at batch 1 and frames/s at batch 8 (each timed for ``seconds``).

    Keys ``policy_steps_per_s_b1``, ``policy_frames_per_s_b8``; with ``training``, also
    ``policy_train_samples_per_s_b32`` (4-step x 8-env sequences). Runs on torch's current thread
    count; set ``torch.set_num_threads`` before calling to pin it. ``device``: where inference runs (the
    training figure is the CPU's).
    """
    torch.manual_seed(0)
    policy = PointNavResNetPolicy(PolicyNetConfig())
    result = {
        "policy_steps_per_s_b1": inference_rate(policy, 1, config, seconds, device),
        "policy_frames_per_s_b8": inference_rate(policy, 8, config, seconds, device),
    }
    if training:
        result["policy_train_samples_per_s_b32"] = _training_rate(PointNavResNetPolicy(), 4, 8, seconds)
    return result
