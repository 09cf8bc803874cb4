"""Fine-tune a trained PointNav policy with PPO on habitat-lab's PointNav reward.

    navbench train --config configs/pointnav/full.toml      # the full recipe runs this as its `ppo_*` stages
    navbench train ppo --init runs/pointnav/dagger.pth --bc-weight 0.1 --out runs/pointnav/ppo.pth  # add --resume

DAgger (:mod:`navbench.policy.train`) imitates the expert one step at a time; PPO optimises the return of whole
rollouts, where a closed-loop failure (turning back and forth against a wall between the agent and the goal)
costs reward every step. The reward is habitat-lab's PointNav default: the decrease of the geodesic distance to
the goal, plus ``slack_reward`` a step, plus ``success_reward`` on a successful STOP. Actions are sampled from
the policy (habitat-baselines does the same in training); evaluation stays argmax. With ``--bc-weight`` the
geodesic expert labels every step of the rollouts and a cross-entropy term to its actions joins the PPO loss
(as Kickstarting keeps a teacher's term during RL), which keeps the paths close to the expert's.

The visual encoder stays frozen (as in DAgger): the rollout keeps each frame's encoder output, and the updates
train the LSTM, the goal and action embeddings and the two heads on those, which is what makes updates cheap on 2
cores. Each update collects ``rollout_steps`` steps in each of ``num_envs`` envs (:mod:`navbench.policy.rollout`),
then runs ``ppo_epochs`` epochs of clipped PPO over ``num_minibatches`` groups of envs, each a whole
``rollout_steps`` sequence from the recurrent state it started with (habitat-baselines' recurrent generator).
Imitation trains no critic, so the first ``critic_warmup`` updates train only the value head, with the actor
fixed (the warm-up PIRLNav uses for RL fine-tuning of a cloned policy): an untrained critic's advantages would
otherwise push the policy at random.
"""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from navbench.loop_progress import progress
from navbench.policy import distributed as ddp
from navbench.policy.checkpoint import load_checkpoint, load_train_state, save_checkpoint
from navbench.policy.config import PPOConfig
from navbench.policy.csv_log import keep_rows_through, log_row
from navbench.policy.net import PointNavResNetPolicy, PolicyNetConfig, prepare_depth
from navbench.policy.rollout import Collection, EnvSlots, make_envs

__all__ = ["PPOConfig", "Rollout", "gae", "ppo_update", "step_reward", "train_ppo"]


def step_reward(d_before: float, d_after: float, success: bool, cfg: PPOConfig, spl: float = 1.0) -> float:
    """habitat-lab's PointNav reward for one step: progress in geodesic distance, slack, success bonus (times the
    episode's ``spl`` with ``terminal_reward = "spl"``)."""
    bonus = cfg.success_reward * (spl if cfg.terminal_reward == "spl" else 1.0)
    return d_before - d_after + cfg.slack_reward + (bonus if success else 0.0)


def update_lr_factor(cfg: PPOConfig, u: int) -> float:
    """The share of the configured learning rates that update ``u`` (0-based) uses."""
    if cfg.lr_schedule == "constant":
        return 1.0
    if cfg.lr_schedule == "linear":
        return 1.0 - u / cfg.updates
    raise ValueError(f"unknown lr_schedule {cfg.lr_schedule!r}: choose constant or linear")


def gae(rewards: np.ndarray, values: np.ndarray, dones: np.ndarray, last_value: np.ndarray,
        gamma: float, lam: float) -> np.ndarray:
    """Generalised advantage estimates (T, N); ``dones[t]`` marks that step t ended its episode (no bootstrap)."""
    adv = np.zeros_like(rewards)
    running = np.zeros(rewards.shape[1], np.float32)
    for t in reversed(range(len(rewards))):
        next_value = last_value if t == len(rewards) - 1 else values[t + 1]
        live = 1.0 - dones[t]
        delta = rewards[t] + gamma * next_value * live - values[t]
        running = delta + gamma * lam * live * running
        adv[t] = running
    return adv


class Rollout:
    """Steps ``envs`` with actions sampled from ``policy`` (drawn with ``generator``) and keeps what a PPO update
    needs; ``rng`` draws the tight starts."""

    def __init__(self, envs, cfg: PPOConfig, policy: PointNavResNetPolicy, generator: torch.Generator,
                 rng: np.random.Generator):
        self.cfg, self.policy, self.gen = cfg, policy, generator
        if cfg.act_bf16:  # oneDNN's bf16 convolutions are faster in NHWC (the layout changes no value)
            policy.to(memory_format=torch.channels_last)
        expert = (cfg.expert_success_distance, cfg.expert_margin) if cfg.bc_weight > 0 else None
        self.slots = EnvSlots(envs, rng, cfg.tight_starts, expert=expert)
        n = len(envs)
        self.dist = np.array([env.distance_to_goal() for env in envs])
        self.hidden = policy.initial_hidden(n)
        self.prev = torch.zeros(n, dtype=torch.long)
        self.mask = torch.zeros(n, dtype=torch.bool)

    @property
    def envs(self) -> list:
        return self.slots.envs

    @classmethod
    def for_worker(cls, cfg: PPOConfig, envs: list, rng_seed: list[int]) -> Rollout:
        policy = PointNavResNetPolicy(PolicyNetConfig()).eval()
        seeds = np.random.default_rng(rng_seed)
        gen = torch.Generator().manual_seed(int(seeds.integers(2**62)))
        return cls(envs, cfg, policy, gen, np.random.default_rng(seeds.integers(2**62)))

    @staticmethod
    def worker_args(args: tuple, workers: int) -> tuple:
        return args

    @staticmethod
    def merge(results: list) -> tuple[dict[str, torch.Tensor], list[dict]]:
        # every tensor is (steps, envs, ...) but the recurrent state the rollout started from, (envs, ...)
        data = {k: torch.cat([d[k] for d, _ in results], dim=0 if k == "hidden0" else 1) for k in results[0][0]}
        return data, [e for _, finished in results for e in finished]

    def _step_policy(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """Encoder output, point goal, logits, value and next recurrent state for the current observations."""
        obs = self.slots.obs
        depth = prepare_depth(np.stack([o["depth"] for o in obs]), self.policy.cfg.input_size)
        goal = torch.as_tensor(np.stack([o["pointgoal_with_gps_compass"] for o in obs]), dtype=torch.float32)
        dev = next(self.policy.parameters()).device  # the rollout's own state stays on the CPU
        with torch.inference_mode():
            with torch.autocast(dev.type, dtype=torch.bfloat16, enabled=self.cfg.act_bf16):
                feat = self.policy.net.encode_depth(depth.to(dev)).float()
            logits, value, hidden = self.policy.forward_features(
                feat[None], goal.to(dev)[None], self.prev.to(dev)[None], self.mask.to(dev)[None], self.hidden.to(dev))
        return feat.cpu().clone(), goal, logits[0].cpu().clone(), value[0].cpu().clone(), hidden.cpu().clone()

    def snapshot(self) -> dict:
        """Everything the next rollout continues from: envs, recurrent state, random streams."""
        return {"slots": self.slots.snapshot(), "dist": [float(d) for d in self.dist], "hidden": self.hidden.clone(),
                "prev": self.prev.clone(), "mask": self.mask.clone(), "gen": self.gen.get_state()}

    def restore(self, snap: dict) -> None:
        self.slots.restore(snap["slots"])
        self.dist = np.array(snap["dist"], np.float64)
        self.hidden, self.prev, self.mask = snap["hidden"].clone(), snap["prev"].clone(), snap["mask"].clone()
        self.gen.set_state(snap["gen"])

    def collect(self, preempt: ddp.Preemption | None = None) -> tuple[dict[str, torch.Tensor], list[dict]]:
        """``rollout_steps`` steps of every env (fewer when ``preempt`` ends the rollout early): (the update's
        tensors, success and SPL of the episodes that ended)."""
        cfg, slots = self.cfg, self.slots
        T, n = cfg.rollout_steps, len(slots)
        keys = ("feat", "goal", "prev", "mask", "action", "logp", "value")
        buf: dict[str, list] = {k: [] for k in keys}
        rewards, dones = np.zeros((T, n), np.float32), np.zeros((T, n), np.float32)
        finished: list[dict] = []
        hidden0 = self.hidden.clone()
        for t in range(T):
            if preempt is not None and preempt.should_stop(t, T):
                rewards, dones = rewards[:t], dones[:t]
                break
            feat, goal, logits, value, hidden = self._step_policy()
            dist = torch.distributions.Categorical(logits=logits)
            action = torch.multinomial(dist.probs, 1, generator=self.gen)[:, 0]
            step = (feat, goal, self.prev.clone(), self.mask.clone(), action, dist.log_prob(action), value)
            for k, v in zip(keys, step):
                buf[k].append(v)
            if slots.expert is not None:  # labelled where the learner is, before it moves
                buf.setdefault("label", []).append(torch.tensor([slots.label(i) for i in range(n)]))
            self.hidden, self.prev, self.mask = hidden, action.clone(), torch.ones(n, dtype=torch.bool)
            for i in range(n):
                term, trunc, info, _ = slots.step(i, int(action[i]))
                d = info["distance_to_goal"]
                rewards[t, i] = step_reward(self.dist[i], d, bool(term and info["success"]), cfg, info["spl"])
                self.dist[i] = d
                if term or trunc:
                    dones[t, i] = 1.0
                    finished.append({"success": info["success"], "spl": info["spl"]})
                    slots.restart(i)
                    self.dist[i] = slots.envs[i].distance_to_goal()
                    self.hidden[i] = 0.0
                    self.prev[i] = 0
                    self.mask[i] = False
        if preempt is not None:
            preempt.finished()
        last_value = self._step_policy()[3].numpy()
        out = {k: torch.stack(v) for k, v in buf.items()}
        adv = gae(rewards, out["value"].numpy(), dones, last_value, cfg.gamma, cfg.gae_lambda)
        out["adv"] = torch.from_numpy(adv)
        out["ret"] = out["adv"] + out["value"]
        out["hidden0"] = hidden0
        out["reward"] = torch.from_numpy(rewards)
        return out, finished


def normalized_advantages(adv: torch.Tensor) -> torch.Tensor:
    """Advantages less their mean, over their standard deviation, both taken over every rank's rollout."""
    if not ddp.info().distributed:
        return (adv - adv.mean()) / (adv.std() + 1e-5)
    a = adv.double()
    total, total_sq, count = ddp.all_sum([float(a.sum()), float((a * a).sum()), float(a.numel())])
    mean = total / count
    std = max(0.0, (total_sq - count * mean * mean) / max(1.0, count - 1)) ** 0.5
    return ((adv - mean) / (std + 1e-5)).to(adv.dtype)


def ppo_update(policy: PointNavResNetPolicy, opt: torch.optim.Optimizer, data: dict[str, torch.Tensor],
               cfg: PPOConfig, actor: bool, rng: np.random.Generator, forward=None) -> dict[str, float]:
    """Clipped PPO epochs over env groups; with ``actor`` False only the value loss is applied. ``forward`` is
    the training forward (``policy.forward_features``, or its DDP wrapper in a distributed run)."""
    forward = policy.forward_features if forward is None else forward
    n = data["action"].shape[1]
    adv = normalized_advantages(data["adv"])
    stats: dict[str, list[float]] = {k: [] for k in ("policy_loss", "value_loss", "entropy", "approx_kl", "clip_frac")}
    if cfg.bc_weight > 0:
        stats["bc_loss"] = []
    params = [p for p in policy.parameters() if p.requires_grad]
    dev = next(policy.parameters()).device  # the rollout's tensors are on the CPU; each minibatch goes there
    data = {**{k: v.to(dev) for k, v in data.items()}, "adv": adv.to(dev)}
    adv = data["adv"]
    for _ in range(cfg.ppo_epochs):
        for idx in np.array_split(rng.permutation(n), cfg.num_minibatches):
            idx = torch.as_tensor(idx, device=dev)
            logits, value, _ = forward(data["feat"][:, idx], data["goal"][:, idx], data["prev"][:, idx],
                                       data["mask"][:, idx], data["hidden0"][idx])
            logp_all = F.log_softmax(logits, -1)
            logp = logp_all.gather(-1, data["action"][:, idx, None])[..., 0]
            ratio = torch.exp(logp - data["logp"][:, idx])
            a = adv[:, idx]
            policy_loss = -torch.min(ratio * a, ratio.clamp(1 - cfg.clip, 1 + cfg.clip) * a).mean()
            value_loss = 0.5 * (data["ret"][:, idx] - value).pow(2).mean()
            entropy = -(logp_all.exp() * logp_all).sum(-1).mean()
            loss = cfg.value_coef * value_loss
            if actor:
                loss = loss + policy_loss - cfg.entropy_coef * entropy
            if cfg.bc_weight > 0:
                bc_loss = F.cross_entropy(logits.reshape(-1, logits.shape[-1]), data["label"][:, idx].reshape(-1))
                if actor:
                    loss = loss + cfg.bc_weight * bc_loss
            opt.zero_grad(set_to_none=True)
            loss.backward()
            if not actor:  # the warm-up trains the critic alone: nothing else may move
                for name, p in policy.named_parameters():
                    if not name.startswith("critic.") and p.grad is not None:
                        p.grad = None
            torch.nn.utils.clip_grad_norm_(params, cfg.max_grad_norm)
            opt.step()
            with torch.no_grad():
                stats["policy_loss"].append(policy_loss.item())
                stats["value_loss"].append(value_loss.item())
                stats["entropy"].append(entropy.item())
                stats["approx_kl"].append((data["logp"][:, idx] - logp).mean().item())
                stats["clip_frac"].append(((ratio - 1).abs() > cfg.clip).float().mean().item())
                if cfg.bc_weight > 0:
                    stats["bc_loss"].append(bc_loss.item())
    return {k: float(np.mean(v)) for k, v in stats.items()}



def train_ppo(cfg: PPOConfig, out: Path, init: Path | None, resume: bool = False,
              state_dir: Path = Path("runs/pointnav/ppo_state"), log_every=print, device: str = "cpu"
              ) -> dict[str, float]:
    """Fine-tune ``init``'s weights under ``cfg`` (or resume from ``state_dir``); writes ``out`` and its
    ``.log.csv``. The updates (and, with one worker, the rollouts' forward passes) run on ``device``
    (resolved); rollout workers act on the CPU. Under torchrun or SLURM every rank runs this
    (:mod:`navbench.policy.distributed`): rank 0 writes the checkpoint and the log, every rank resumes from the
    state rank 0 saved."""
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    dist = ddp.init(device)
    device = ddp.rank_device(device)
    resume = resume or ddp.restarted()
    out, state_dir = Path(out), Path(state_dir)
    out.parent.mkdir(parents=True, exist_ok=True)
    state_dir.mkdir(parents=True, exist_ok=True)
    state_path = state_dir / "ppo_state.pt"
    log_path = out.with_suffix(".log.csv")
    if not dist.is_main:
        log_every = _quiet

    policy = PointNavResNetPolicy(PolicyNetConfig()).to(device)
    policy.net.visual_encoder.requires_grad_(False)
    # Adam's state must not accumulate on a frozen actor during the warm-up: Adam moves a parameter
    # whose gradient is zero by its momentum, so the actor's gradients are set to None instead.
    critic = list(policy.critic.parameters())
    rest = [p for n, p in policy.named_parameters() if p.requires_grad and not n.startswith("critic.")]
    opt = torch.optim.Adam([{"params": rest, "lr": cfg.lr}, {"params": critic, "lr": cfg.critic_lr}], eps=1e-5)
    start, frames, wall0 = 0, 0, 0.0
    if resume and state_path.is_file():
        start, frames, wall0 = load_train_state(state_path, policy, opt, "update")
        log_every(f"resumed at update {start} ({frames} frames, {wall0:.0f} s)")
        if dist.is_main:
            keep_rows_through(log_path, "update", start)
    elif init is None:
        raise ValueError(f"no resumable state in {state_dir}; --init PATH names the policy to fine-tune")
    else:
        policy.load_state_dict(load_checkpoint(init).state_dict())
        log_every(f"initialised from {init}")
        if dist.is_main and log_path.exists():
            log_path.unlink()
    if dist.distributed:
        log_every(f"world size {dist.world_size} ({dist.backend}): {cfg.num_envs} envs per rank")
    ddp.barrier()  # the log is fresh before any rank writes
    policy.eval()  # no dropout or batch statistics anywhere; eval() only marks inference
    rng = np.random.default_rng(ddp.rank_seeds([cfg.seed, start]))
    gen = torch.Generator().manual_seed(int(rng.integers(2**62)))
    env_seed = cfg.seed * 7919 + start
    first = dist.rank * cfg.num_envs  # env i of rank r is seeded base + r * num_envs + i
    if cfg.workers > 1:
        source = Collection.in_workers(Rollout, cfg, env_seed, [ddp.rank_seeds([cfg.seed, start, 2, w])
                                                                 for w in range(cfg.workers)], first_env=first)
    else:
        source = Collection(Rollout(make_envs(cfg.num_envs, cfg.train_split, env_seed, first), cfg, policy, gen,
                                    np.random.default_rng(ddp.rank_seeds([cfg.seed, start, 1]))))
    window: list[dict] = []  # the last 100 finished rollout episodes of this rank
    local = ddp.load_local(state_path, "update", start) if start > 0 else None
    if local is not None and len(local["collect"]) != max(1, cfg.workers):  # saved with another --workers
        local = None
    if local is not None:  # continue the envs, recurrent states and random streams exactly
        source.restore(local["collect"])
        ddp.set_rng_state(rng, local["rng"])
        torch.set_rng_state(local["torch_rng"])
        window = list(local["window"])
    elif start > 0:
        log_every("the resume state holds no rollout state for this world size: the envs start afresh")
    try:
        return _ppo_loop(cfg, policy, opt, source, rng, start, frames, wall0, init, out, log_path, state_path,
                         log_every, window)
    finally:
        source.close()


def _quiet(*_args) -> None:
    """The log of a rank other than 0: its rows are rank 0's."""


def _ppo_loop(cfg: PPOConfig, policy, opt, source: Collection, rng, start, frames, wall0, init, out,
              log_path, state_path, log_every, window: list[dict]) -> dict[str, float]:
    """The updates of :func:`train_ppo`: collect, update, log, save (also when SIGTERM or SIGUSR1 asks)."""
    dist = ddp.info()
    t_start = time.time() - wall0
    last: dict[str, float] = {}
    forward = ddp.training_forward(policy)
    with ddp.StopSignals() as signals:
        for u in (progress(range(start, cfg.updates), desc="ppo updates") if dist.is_main
                  else range(start, cfg.updates)):
            if cfg.lr_schedule != "constant":
                factor = update_lr_factor(cfg, u)
                opt.param_groups[0]["lr"], opt.param_groups[1]["lr"] = cfg.lr * factor, cfg.critic_lr * factor
            t0 = time.time()
            preempt = ddp.Preemption(cfg.preempt_fraction, cfg.preempt_min_share, f"{Path(out).name}/{u}")
            data, finished = source.collect(policy, *([preempt] if source.local is not None else []))
            t_collect = time.time() - t0
            t0 = time.time()
            stats = ppo_update(policy, opt, data, cfg, actor=u >= cfg.critic_warmup, rng=rng, forward=forward)
            window = (window + finished)[-100:]
            frames += int(ddp.all_sum([float(data["action"].numel())])[0])
            rollout = {"reward_per_step": float(data["reward"].mean()),
                       "rollout_success": float(np.mean([e["success"] for e in window])) if window else float("nan"),
                       "rollout_spl": float(np.mean([e["spl"] for e in window])) if window else float("nan")}
            last = {"update": u + 1, "frames": frames, "actor": int(u >= cfg.critic_warmup), **ddp.all_mean(rollout),
                    "episodes": int(ddp.all_sum([float(len(window))])[0]), **ddp.all_mean(stats),
                    "collect_s": t_collect, "train_s": time.time() - t0, "wall_s": time.time() - t_start}
            if dist.is_main:
                log_every(log_row(log_path, last, digits=4))
            stop = signals.requested()
            if (u + 1) % cfg.save_every == 0 or u + 1 == cfg.updates or stop:
                if dist.is_main:
                    save_checkpoint(out, policy, {"ppo_config": dataclasses.asdict(cfg), "init": str(init),
                                                  "frames": frames, "wall_s": last["wall_s"], "update": u + 1})
                ddp.save_resume(state_path, {"policy": policy.state_dict(), "optimizer": opt.state_dict(),
                                             "update": u + 1, "frames": frames, "wall_s": last["wall_s"]},
                                {"update": u + 1, "collect": source.snapshot(), "rng": ddp.rng_state(rng),
                                 "torch_rng": torch.get_rng_state(), "window": window})
            if stop:
                log_every(f"stopped by signal {signals.signum or 'on another rank'} after update {u + 1}; "
                          "resume state saved (continue with --resume)")
                last = {**last, "stopped_by_signal": signals.signum or -1}
                break
    return last


def main(cfg: PPOConfig, out: Path, state_dir: Path, init: Path | None, resume: bool,
         device: str = "cpu") -> dict[str, float]:
    """``navbench train ppo``: fine-tune, print the last log row as JSON."""
    result = train_ppo(cfg, out, init, resume=resume, state_dir=state_dir, device=device)
    if ddp.info().is_main:
        print(json.dumps(result))
    return result
