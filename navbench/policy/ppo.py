"""Fine-tune a trained PointNav policy with PPO on habitat-lab's PointNav reward.

    navbench train ppo --init policies/pointnav_navbench.pth --train-split train_large \
        --out runs/pointnav/policy_ppo.pth --state-dir runs/pointnav/ppo_state    # add --resume

DAgger (:mod:`navbench.policy.train`) imitates the expert one step at a time, and its policies fail
closed-loop: pinned against a wall between them and the goal, they turn, turn back towards the goal and
bump again (policies/README.md, session 15). PPO optimises the return of whole rollouts, where such a
loop costs reward every step. The reward is habitat-lab's PointNav default: the decrease of the
geodesic distance to the goal, minus 0.01 a step, plus 2.5 on a successful STOP. Actions are sampled
from the policy (habitat-baselines does the same in training); evaluation stays argmax. With
``--bc-weight`` the geodesic expert labels every step of the rollouts and a cross-entropy term to its
actions joins the PPO loss (as Kickstarting keeps a teacher's term during RL).

The visual encoder stays frozen (as in DAgger): the rollout keeps each frame's encoder output, and the
updates train the LSTM, the goal and action embeddings and the two heads on those, which is what makes
updates cheap on 2 cores. Each update collects ``rollout_steps`` steps in each of ``num_envs`` envs,
then runs ``ppo_epochs`` epochs of clipped PPO over ``num_minibatches`` groups of envs, each a whole
``rollout_steps`` sequence from the recurrent state it started with (habitat-baselines' recurrent
generator). Imitation trains no critic, so the first ``critic_warmup`` updates train only the value
head, with the actor fixed (the warm-up PIRLNav uses for RL fine-tuning of a cloned policy): an
untrained critic's advantages would otherwise push the policy at random.
"""

from __future__ import annotations

import dataclasses
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from navbench.policy.checkpoint import load_checkpoint, save_checkpoint, save_train_state
from navbench.policy.net import PointNavResNetPolicy, PolicyNetConfig, prepare_depth
from navbench.policy.precision import native_bf16
from navbench.policy.progress import log_row
from navbench.policy.train import cosine_rate, make_envs, reset_maybe_tight, worker_shares
from navbench.policy.workers import WorkerPool
from navbench.scene.follower import GreedyFollower


@dataclass(frozen=True)
class PPOConfig:
    train_split: str = "train_large"
    num_envs: int = 8
    rollout_steps: int = 128  # per env and update (habitat-baselines' num_steps)
    updates: int = 300
    lr: float = 2.5e-5  # fine-tuning: a tenth of habitat-baselines' from-scratch 2.5e-4
    # "constant", or "cosine": after the critic warm-up the actor's rate falls from lr to lr_min along half
    # a cosine over the remaining updates (habitat-baselines decays it linearly to 0). At a constant rate the
    # last update's weights are one draw from a random walk: three 250-update continuations of stage 16 at
    # 2.5e-5 scored 88.5-91.0 SR on val against its 92.5. A decayed rate ends the run on settled weights
    # (tried in stage 22, 800 updates: val stayed where stage 16 is; policies/README.md).
    lr_schedule: str = "constant"
    lr_min: float = 0.0
    # The value head starts untrained and must fit returns of up to ~10 within the warm-up: at the
    # actor's rate 80 Adam steps would move it by ~0.002 a weight.
    critic_lr: float = 1e-3
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip: float = 0.2
    ppo_epochs: int = 2
    num_minibatches: int = 2  # groups of envs per epoch
    value_coef: float = 0.5
    entropy_coef: float = 1e-3  # the cloned policy already explores by sampling; keep it from flattening
    max_grad_norm: float = 0.2
    critic_warmup: int = 30  # first updates train the value head only
    slack_reward: float = -0.01
    success_reward: float = 2.5
    # Penalty per metre walked that did not bring the agent closer to the goal (0 = habitat's reward).
    # Habitat's reward counts steps, SPL counts metres: 250 updates with it raised val SR 86.5 -> 94.5
    # but left SPL at 74.9, the successful paths 1.49x the geodesic distance instead of 1.21x (fewer
    # turns in place, more metres on curves). Summed over an episode this term is -weight x (path
    # length - geodesic distance), SPL's own loss.
    waste_weight: float = 0.0
    # Penalty per refused MOVE_FORWARD (the env counts it as a collision; 0 = habitat's reward). PPO samples
    # its actions, so a policy that presses into an obstacle leaves it by chance after a few draws and the
    # presses cost it little; evaluated by argmax the same policy presses for the rest of the episode (most
    # of stage 16's val failures: 69-239 refused FORWARDs). The penalty prices each press directly.
    collision_penalty: float = 0.0
    # Scale the success bonus by the episode's SPL (geodesic / max(path, geodesic)): the bonus then pays
    # what SPL pays, so a shorter successful path earns more, while a failure still forfeits all of it.
    success_spl: bool = False
    # Weight of an imitation term on PPO's own rollouts: cross-entropy to the geodesic expert's action at
    # every step the learner visited (DAgger's labels, kept during RL as Kickstarting keeps its teacher's).
    # PPO alone learns to leave the pinned spots DAgger cannot, but on habitat's step-counting reward it
    # also trades turns in place for longer curves; the expert's labels pull the rest towards its paths.
    bc_weight: float = 0.0
    # Probability that an episode ending in a rollout is followed by a replay of an earlier failed one
    # (drawn at random from the last ``replay_buffer`` failures; a replay leaves the buffer and comes back
    # only if it fails again) instead of a fresh draw: the cloned policy already succeeds on ~92% of train
    # episodes, so most rollout steps teach it little, while its failures (wedged in a slit between
    # furniture and a wall, turning in place at a dead end) recur on val. Prioritised level replay (Jiang
    # et al., 2021) in its simplest form. 0 = off. The buffer restarts empty on --resume.
    replay_failures: float = 0.0
    replay_buffer: int = 64
    # Probability that a fresh episode starts beside an obstacle (navbench.policy.train.reset_maybe_tight),
    # where the shipped file's val failures begin three times as often. 0 = off. Tried alone in PPO (stage 24):
    # no fewer tight failures on val; it pays in DAgger instead (policies/README.md, stages 24-27).
    tight_starts: float = 0.0
    # Fine-tune the visual encoder too (at encoder_lr_scale x the actor's rate). It was trained on geometry
    # targets only (navbench.policy.pretrain) and has been frozen since; the shipped file's failures are
    # pressing into an obstacle at the edge of the view, which frozen features may not tell from free space
    # (tried in stage 23: no better on val; policies/README.md).
    # The rollout then keeps each frame's depth (fp16, ~100 MB an update) instead of its features, and the
    # update re-encodes them, under bf16 autocast with ``bf16`` (1.2 s against 2.7 s forward+backward
    # for 512 frames on session 24's AVX-512-BF16 CPU; slower than fp32 where the CPU lacks BF16).
    train_encoder: bool = False
    # The encoder's rate as a fraction of the actor's. At the full rate its 3.1M weights moved the policy
    # by an approximate KL of 0.02-0.03 per update (clip fraction ~0.09) where the frozen-encoder updates
    # move it by ~5e-4: too far for fine-tuning a policy that already succeeds on ~94% of its rollouts.
    encoder_lr_scale: float = 0.1
    # bfloat16 autocast around the encoder's pass in the update, which exists only with train_encoder: with the
    # encoder frozen (the default; every PPO stage of both recipes) the update reads the rollout's stored features
    # and this changes nothing. On where the CPU has AVX512-BF16 or AMX, off elsewhere, where bf16 is emulated
    # (an encoder-stage update took 7.0 s against 0.66 s in fp32 on session 33's AVX2-only EPYC;
    # navbench.policy.precision). --bf16 turns it on anywhere.
    bf16: bool = dataclasses.field(default_factory=native_bf16)
    # bfloat16 autocast around the rollout's encoder pass (TrainConfig.act_bf16 says why); the LSTM, the logits
    # that become the PPO ratio's old log-probabilities and the value stay fp32. Off by default.
    act_bf16: bool = False
    expert_success_distance: float = 0.1  # the shipped policy's DAgger expert (policies/README.md)
    expert_margin: float = 0.15
    seed: int = 0
    threads: int = 2
    # Rollout processes (navbench.policy.workers; TrainConfig.workers explains): 2 collect ~1.4x faster on 2
    # cores. 1 = in this process, as every committed PPO run before session 31 was collected.
    workers: int = 1
    save_every: int = 5  # updates between checkpoints (each writes ~120 MB of resumable state)


def step_reward(d_before: float, d_after: float, moved: float, success: bool, cfg: PPOConfig,
                spl: float = 1.0, collided: bool = False) -> float:
    """habitat-lab's PointNav reward for one step (progress in geodesic distance, slack, success
    bonus, times the episode's ``spl`` with ``success_spl``), less ``waste_weight`` x the metres
    ``moved`` beyond that progress and ``collision_penalty`` if the step was a refused FORWARD."""
    progress = d_before - d_after
    bonus = cfg.success_reward * (spl if cfg.success_spl else 1.0) if success else 0.0
    return (progress + cfg.slack_reward + bonus - cfg.waste_weight * max(0.0, moved - progress)
            - (cfg.collision_penalty if collided else 0.0))


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
    """Steps ``envs`` with actions sampled from the policy and keeps what a PPO update needs."""

    def __init__(self, envs, cfg: PPOConfig, policy: PointNavResNetPolicy, generator: torch.Generator,
                 rng: np.random.Generator | None = None):
        self.envs, self.cfg, self.policy, self.gen = envs, cfg, policy, generator
        if cfg.act_bf16:  # oneDNN's bf16 convolutions are ~15% faster in NHWC (the layout changes no value)
            policy.to(memory_format=torch.channels_last)
        self.rng = rng if rng is not None else np.random.default_rng(cfg.seed)
        self.failed: list = []  # episodes that ended without success, oldest first (replay_failures)
        self.replaying = [False] * len(envs)  # whether each env's current episode is a replay
        n = len(envs)
        self.obs = [reset_maybe_tight(env, self.rng, cfg.tight_starts) for env in envs]
        self.dist = np.array([env.distance_to_goal() for env in envs])
        self.walked = np.zeros(n)  # path length so far
        self.collisions = np.zeros(n, np.int64)  # the env's collision count so far this episode
        self.hidden = policy.initial_hidden(n)
        self.prev = torch.zeros(n, dtype=torch.long)
        self.mask = torch.zeros(n, dtype=torch.bool)
        self.finished: list[dict] = []  # per-episode success / spl since the last read
        self.experts = [self._expert(env) for env in envs] if cfg.bc_weight > 0 else None

    def _expert(self, env) -> GreedyFollower:
        return GreedyFollower(env.navgrid, env.goal_points, self.cfg.expert_success_distance,
                              clearance_margin=self.cfg.expert_margin)

    def _next_episode(self, env, success: bool) -> tuple[dict, bool]:
        """Reset ``env`` after an episode: (first observation, whether it is a replay). A replay of an
        earlier failure with probability ``replay_failures`` (config comment), else the env's own draw
        (from a tight start with probability ``tight_starts``)."""
        cfg = self.cfg
        if cfg.replay_failures > 0:
            if not success:
                self.failed = (self.failed + [env.episode])[-cfg.replay_buffer:]
            if self.failed and self.rng.random() < cfg.replay_failures:
                episode = self.failed.pop(int(self.rng.integers(len(self.failed))))
                return env.reset(options={"episode": episode})[0], True
        return reset_maybe_tight(env, self.rng, cfg.tight_starts), False

    def _step_policy(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """Encoder output, point goal, logits, value and next recurrent state for the current observations."""
        depth = prepare_depth(np.stack([o["depth"] for o in self.obs]), self.policy.cfg.input_size)
        goal = torch.as_tensor(np.stack([o["pointgoal_with_gps_compass"] for o in self.obs]), dtype=torch.float32)
        with torch.inference_mode():
            with torch.autocast("cpu", dtype=torch.bfloat16, enabled=self.cfg.act_bf16):
                feat = self.policy.net.encode_depth(depth).float()
            logits, value, hidden = self.policy.forward_features(feat[None], goal[None], self.prev[None],
                                                                 self.mask[None], self.hidden)
        # with train_encoder the update re-encodes the frame, so the rollout keeps the depth instead
        seen = depth.to(torch.float16) if self.cfg.train_encoder else feat.clone()
        return seen, goal, logits[0].clone(), value[0].clone(), hidden.clone()

    def collect(self) -> dict[str, torch.Tensor]:
        T, n = self.cfg.rollout_steps, len(self.envs)
        keys = ("depth" if self.cfg.train_encoder else "feat", "goal", "prev", "mask", "action", "logp", "value")
        buf: dict[str, list] = {k: [] for k in keys}
        rewards, dones = np.zeros((T, n), np.float32), np.zeros((T, n), np.float32)
        hidden0 = self.hidden.clone()
        for t in range(T):
            feat, goal, logits, value, hidden = self._step_policy()
            dist = torch.distributions.Categorical(logits=logits)
            action = torch.multinomial(dist.probs, 1, generator=self.gen)[:, 0]
            step = (feat, goal, self.prev.clone(), self.mask.clone(), action, dist.log_prob(action), value)
            for k, v in zip(keys, step):
                buf[k].append(v)
            if self.experts is not None:  # labelled where the learner is, before it moves
                labels = [ex.next_action(env.agent_position, env.agent_rotation)
                          for ex, env in zip(self.experts, self.envs)]
                buf.setdefault("label", []).append(torch.tensor(labels))
            self.hidden, self.prev, self.mask = hidden, action.clone(), torch.ones(n, dtype=torch.bool)
            for i, env in enumerate(self.envs):
                self.obs[i], _, term, trunc, info = env.step(int(action[i]))
                d, walked = info["distance_to_goal"], info["path_length"]
                rewards[t, i] = step_reward(self.dist[i], d, walked - self.walked[i], bool(term and info["success"]),
                                            self.cfg, info["spl"], collided=info["collisions"] > self.collisions[i])
                self.dist[i], self.walked[i], self.collisions[i] = d, walked, info["collisions"]
                if term or trunc:
                    dones[t, i] = 1.0
                    self.finished.append({"success": info["success"], "spl": info["spl"],
                                          "replay": self.replaying[i]})
                    self.obs[i], self.replaying[i] = self._next_episode(env, bool(info["success"]))
                    self.dist[i], self.walked[i], self.collisions[i] = env.distance_to_goal(), 0.0, 0
                    self.hidden[i] = 0.0
                    self.prev[i] = 0
                    self.mask[i] = False
                    if self.experts is not None:
                        self.experts[i] = self._expert(env)
        last_value = self._step_policy()[3].numpy()
        out = {k: torch.stack(v) for k, v in buf.items()}
        adv = gae(rewards, out["value"].numpy(), dones, last_value, self.cfg.gamma, self.cfg.gae_lambda)
        out["adv"] = torch.from_numpy(adv)
        out["ret"] = out["adv"] + out["value"]
        out["hidden0"] = hidden0
        out["reward"] = torch.from_numpy(rewards)
        return out


class RolloutWorker:
    """One rollout worker's share of the envs (``PPOConfig.workers``): a :class:`Rollout` over its envs with its
    own random streams, driven by a copy of the policy that ``collect`` refreshes with the trainer's weights."""

    def __init__(self, cfg: PPOConfig, first: int, num_envs: int, env_seed: int, rng_seed: list[int]):
        self.policy = PointNavResNetPolicy(PolicyNetConfig()).eval()
        seeds = np.random.default_rng(rng_seed)
        gen = torch.Generator().manual_seed(int(seeds.integers(2**62)))
        self.rollout = Rollout(make_envs(num_envs, cfg.train_split, env_seed, first), cfg, self.policy, gen,
                               np.random.default_rng(seeds.integers(2**62)))

    def collect(self, weights: dict[str, torch.Tensor]) -> tuple[dict[str, torch.Tensor], list[dict]]:
        # a frozen encoder's weights are sent once; every later call brings only what trains
        self.policy.load_state_dict({**self.policy.state_dict(), **weights})
        data = self.rollout.collect()
        finished, self.rollout.finished = self.rollout.finished, []
        return data, finished


class PooledRollout:
    """:class:`Rollout`'s ``collect``/``finished`` over a :class:`WorkerPool` of :class:`RolloutWorker`: each
    worker steps its envs, and the updates see the workers' envs side by side, in worker order."""

    def __init__(self, pool: WorkerPool, policy: PointNavResNetPolicy, cfg: PPOConfig):
        self.pool, self.policy, self.cfg = pool, policy, cfg
        self.finished: list[dict] = []
        self._encoder_sent = False

    def collect(self) -> dict[str, torch.Tensor]:
        weights = {k: v for k, v in self.policy.state_dict().items()
                   if self.cfg.train_encoder or not self._encoder_sent or not k.startswith("net.visual_encoder.")}
        self._encoder_sent = True
        results = self.pool.call("collect", [(weights,)] * len(self.pool))
        for _, finished in results:
            self.finished.extend(finished)
        # every tensor is (steps, envs, ...) but the recurrent state the rollout started from, (envs, ...)
        return {k: torch.cat([data[k] for data, _ in results], dim=0 if k == "hidden0" else 1)
                for k in results[0][0]}


def actor_lr(cfg: PPOConfig, u: int) -> float:
    """The actor's learning rate at update ``u`` (0-based) under ``cfg.lr_schedule`` (the critic keeps
    ``cfg.critic_lr``)."""
    if cfg.lr_schedule == "constant":
        return cfg.lr
    if cfg.lr_schedule == "cosine":
        return cosine_rate(cfg.lr, cfg.lr_min, (u - cfg.critic_warmup) / max(1, cfg.updates - cfg.critic_warmup - 1))
    raise ValueError(f"unknown lr_schedule {cfg.lr_schedule!r}: choose constant or cosine")


def _encode(policy: PointNavResNetPolicy, depth: torch.Tensor, cfg: PPOConfig, grad: bool) -> torch.Tensor:
    """(T, N, H, W, 1) stored depth -> (T, N, F) encoder output, with gradients only when the actor trains."""
    steps, n = depth.shape[:2]
    with torch.set_grad_enabled(grad), torch.autocast("cpu", dtype=torch.bfloat16, enabled=cfg.bf16):
        feat = policy.net.encode_depth(depth.reshape(steps * n, *depth.shape[2:]).float())
    return feat.float().view(steps, n, -1)


def ppo_update(policy: PointNavResNetPolicy, opt: torch.optim.Optimizer, data: dict[str, torch.Tensor],
               cfg: PPOConfig, actor: bool, rng: np.random.Generator) -> dict[str, float]:
    """Clipped PPO epochs over env groups; with ``actor`` False only the value loss is applied."""
    n = data["action"].shape[1]
    adv = data["adv"]
    adv = (adv - adv.mean()) / (adv.std() + 1e-5)
    stats: dict[str, list[float]] = {k: [] for k in ("policy_loss", "value_loss", "entropy", "approx_kl", "clip_frac")}
    if cfg.bc_weight > 0:
        stats["bc_loss"] = []
    params = [p for p in policy.parameters() if p.requires_grad]
    for _ in range(cfg.ppo_epochs):
        for idx in np.array_split(rng.permutation(n), cfg.num_minibatches):
            idx = torch.as_tensor(idx)
            feat = (data["feat"][:, idx] if "feat" in data
                    else _encode(policy, data["depth"][:, idx], cfg, grad=actor))
            logits, value, _ = policy.forward_features(feat, data["goal"][:, idx],
                                                       data["prev"][:, idx], data["mask"][:, idx], data["hidden0"][idx])
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
              state_dir: Path = Path("runs/pointnav/ppo_state"), log_every=print) -> dict[str, float]:
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    out, state_dir = Path(out), Path(state_dir)
    out.parent.mkdir(parents=True, exist_ok=True)
    state_dir.mkdir(parents=True, exist_ok=True)
    state_path = state_dir / "ppo_state.pt"
    log_path = out.with_suffix(".log.csv")

    policy = PointNavResNetPolicy(PolicyNetConfig())
    if not cfg.train_encoder:
        policy.net.visual_encoder.requires_grad_(False)
    # Adam's state must not accumulate on a frozen actor during the warm-up: Adam moves a parameter
    # whose gradient is zero by its momentum, so the actor's gradients are set to None instead.
    critic = list(policy.critic.parameters())
    encoder = list(policy.net.visual_encoder.parameters()) if cfg.train_encoder else []
    rest = [p for n, p in policy.named_parameters()
            if p.requires_grad and not n.startswith(("critic.", "net.visual_encoder."))]
    groups = [{"params": rest, "lr": cfg.lr}, {"params": critic, "lr": cfg.critic_lr}]
    if encoder:  # a third group, so the optimizer state of a frozen-encoder run keeps its two groups
        groups.append({"params": encoder, "lr": cfg.lr * cfg.encoder_lr_scale})
    opt = torch.optim.Adam(groups, eps=1e-5)
    start, frames, wall0 = 0, 0, 0.0
    if resume and state_path.is_file():
        st = torch.load(state_path, weights_only=False)
        policy.load_state_dict(st["policy"])
        opt.load_state_dict(st["optimizer"])
        start, frames, wall0 = st["update"], st["frames"], st["wall_s"]
        log_every(f"resumed at update {start} ({frames} frames, {wall0:.0f} s)")
    elif init is None:
        raise ValueError(f"no resumable state in {state_dir}; --init PATH names the policy to fine-tune")
    else:
        policy.load_state_dict(load_checkpoint(init).state_dict())
        log_every(f"initialised from {init}")
        if log_path.exists():
            log_path.unlink()
    policy.eval()  # no dropout or batch statistics anywhere; eval() only marks inference
    rng = np.random.default_rng([cfg.seed, start])
    gen = torch.Generator().manual_seed(int(rng.integers(2**62)))
    envs: list = []
    pool: WorkerPool | None = None
    shares = worker_shares(cfg.num_envs, cfg.workers)
    if cfg.workers > 1:
        pool = WorkerPool(RolloutWorker, [(cfg, first, n, cfg.seed * 7919 + start, [cfg.seed, start, 2, w])
                                          for w, (first, n) in enumerate(shares)],
                          threads=max(1, cfg.threads // cfg.workers))
        rollout = PooledRollout(pool, policy, cfg)
    else:
        envs = make_envs(cfg.num_envs, cfg.train_split, cfg.seed * 7919 + start)
        rollout = Rollout(envs, cfg, policy, gen, np.random.default_rng([cfg.seed, start, 1]))
    try:
        return _ppo_loop(cfg, policy, opt, rollout, rng, start, frames, wall0, init, out, log_path, state_path,
                         log_every)
    finally:
        if pool is not None:
            pool.close()
        for e in envs:
            e.close()


def _ppo_loop(cfg: PPOConfig, policy, opt, rollout: Rollout | PooledRollout, rng, start, frames, wall0, init, out,
              log_path, state_path, log_every) -> dict[str, float]:
    """The updates of :func:`train_ppo`: collect, update, log, save."""
    t_start = time.time() - wall0
    last: dict[str, float] = {}
    window: list[dict] = []
    replayed = 0  # replayed episodes finished in this process (the count restarts on --resume)
    for u in range(start, cfg.updates):
        t0 = time.time()
        data = rollout.collect()
        t_collect = time.time() - t0
        t0 = time.time()
        rate = actor_lr(cfg, u)  # set every update, so a resumed run follows the schedule
        opt.param_groups[0]["lr"] = rate
        if cfg.train_encoder:
            opt.param_groups[2]["lr"] = rate * cfg.encoder_lr_scale
        stats = ppo_update(policy, opt, data, cfg, actor=u >= cfg.critic_warmup, rng=rng)
        # success figures over fresh draws only: replays are failures picked on purpose
        window = (window + [e for e in rollout.finished if not e["replay"]])[-100:]
        replayed += sum(e["replay"] for e in rollout.finished)
        rollout.finished = []
        frames += int(data["action"].numel())
        last = {"update": u + 1, "frames": frames, "actor": int(u >= cfg.critic_warmup),
                # as text: the log rounds floats to 5 decimals, which would leave ~2e-05 of a 2.5e-5 rate
                **({"lr": f"{opt.param_groups[0]['lr']:.4g}"} if cfg.lr_schedule != "constant" else {}),
                "reward_per_step": float(data["reward"].mean()),
                "rollout_success": float(np.mean([e["success"] for e in window])) if window else float("nan"),
                "rollout_spl": float(np.mean([e["spl"] for e in window])) if window else float("nan"),
                "episodes": len(window), **({"replayed": replayed} if cfg.replay_failures > 0 else {}), **stats,
                "collect_s": t_collect, "train_s": time.time() - t0, "wall_s": time.time() - t_start}
        log_every(log_row(log_path, last, digits=4))
        if (u + 1) % cfg.save_every == 0 or u + 1 == cfg.updates:
            save_checkpoint(out, policy, {"ppo_config": dataclasses.asdict(cfg), "init": str(init), "frames": frames,
                                          "wall_s": last["wall_s"], "update": u + 1})
            save_train_state(state_path, {"policy": policy.state_dict(), "optimizer": opt.state_dict(),
                                          "update": u + 1, "frames": frames, "wall_s": last["wall_s"]})
    return last


def main_args(args) -> int:
    fields = PPOConfig.__dataclass_fields__
    cfg = PPOConfig(**{k: v for k, v in vars(args).items() if k in fields and v is not None},
                    # the shared --train-encoder flag is spelt freeze_visual=False for DAgger's TrainConfig
                    **({"train_encoder": True} if getattr(args, "freeze_visual", None) is False else {}))
    result = train_ppo(cfg, Path(args.out), Path(args.init) if args.init else None, resume=args.resume,
                       state_dir=Path(args.state_dir))
    print(json.dumps(result))
    return 0
