"""Train the PointNav policy on CPU by DAgger imitation of the geodesic shortest-path expert.

    navbench train --config configs/pointnav/2h.toml          # the recipes run this as their `dagger` stages
    navbench train dagger --init runs/pointnav/encoder.pth --out runs/pointnav/dagger.pth   # add --resume

The expert (:func:`navbench.policy.rollout.make_expert`) follows the true shortest path, keeping
``expert_margin`` of clearance where it can, and says STOP within ``expert_success_distance`` of the goal.

Each iteration rolls out ``num_envs`` PointNav envs (depth only, the sensor the policy reads) on the PointNav
split ``train_split``. The executed action is the expert's with probability beta (``beta0``, times
``beta_decay`` every iteration, floored at ``beta_min``) and the learner's otherwise, plus occasional random
turns/moves so the data covers recovery from off-path states; every step is labelled with the expert's action
from the state actually reached (DAgger). Whole episodes join an aggregated buffer, and the network is trained
with cross-entropy on whole episodes from their first step (the LSTM then learns on the recurrent states it
meets when deployed), steps where the expert changes its action weighing more. After every iteration it scores
the bundled PointNav ``select`` episodes (never ``val``), logs to CSV and writes a resumable checkpoint.

The visual encoder is not trained: start from a checkpoint whose encoder was (``--init``, e.g.
``navbench train encoder``'s output, see :mod:`navbench.policy.pretrain`). The buffer keeps the encoder output
the rollout's own forward pass computed for each frame (fp16), and the rest of the network trains on those, which
is what makes updates cheap on 2 cores.

With ``--workers 2`` the envs are split between two rollout processes (:mod:`navbench.policy.rollout`), each
with its own copy of the policy, refreshed with the trainer's weights before every collection.
"""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

from navbench.env.config import STOP, EnvConfig
from navbench.env.pointnav import PointNavEnv
from navbench.episodes.io import load_dataset
from navbench.loop_progress import progress
from navbench.paths import split_file
from navbench.policy import distributed as ddp
from navbench.policy.checkpoint import (
    load_checkpoint,
    load_train_state,
    read_train_state,
    save_checkpoint,
    save_train_state,
)
from navbench.policy.config import TrainConfig
from navbench.policy.csv_log import keep_rows_through, log_row
from navbench.policy.net import InferenceConfig, PointNavAgentPolicy, PointNavResNetPolicy, PolicyNetConfig
from navbench.policy.rollout import Collection, EnvSlots, make_envs

__all__ = ["TrainConfig", "Collector", "EpisodeBuffer", "build_learner", "evaluate", "train", "train_step"]


# ------------------------------------------------------------------------------------------- buffer
class EpisodeBuffer:
    """Aggregated DAgger data as whole episodes, capped at ``max_frames`` (oldest episodes dropped)."""

    def __init__(self, max_frames: int):
        self.max_frames = max_frames
        self.episodes: list[dict[str, np.ndarray]] = []
        self.frames = 0

    def add(self, ep: dict[str, np.ndarray]) -> None:
        self.episodes.append(ep)
        self.frames += len(ep["label"])
        while self.frames > self.max_frames and len(self.episodes) > 1:
            self.frames -= len(self.episodes.pop(0)["label"])

    def sample(self, rng: np.random.Generator, n: int) -> dict[str, torch.Tensor]:
        """``n`` whole episodes from their first step, padded to the longest (padding weighs 0).

        The episodes are a random window of the length-sorted list, so they have similar lengths: padding then
        wastes little of the LSTM's time, the cost of a whole-episode update.
        """
        lens = np.array([len(e["label"]) for e in self.episodes])
        by_len = np.argsort(lens, kind="stable")
        start = int(rng.integers(max(1, len(by_len) - n + 1)))
        eps = by_len[start:start + n] if len(by_len) >= n else rng.choice(len(self.episodes), size=n)
        T = int(lens[eps].max())
        feat_dim = self.episodes[0]["feat"].shape[1:]
        feat = np.zeros((T, n, *feat_dim), self.episodes[0]["feat"].dtype)
        goal = np.zeros((T, n, 2), np.float32)
        prev = np.zeros((T, n), np.int64)
        mask = np.zeros((T, n), bool)
        label = np.zeros((T, n), np.int64)
        weight = np.zeros((T, n), np.float32)
        for j, e in enumerate(eps):
            ep = self.episodes[e]
            k = len(ep["label"])
            feat[:k, j] = ep["feat"]
            goal[:k, j] = ep["goal"]
            prev[:k, j] = ep["prev"]
            mask[:k, j] = ep["mask"]
            label[:k, j] = ep["label"]
            weight[:k, j] = ep["weight"]
        return {"feat": torch.from_numpy(feat), "goal": torch.from_numpy(goal), "prev": torch.from_numpy(prev),
                "mask": torch.from_numpy(mask), "label": torch.from_numpy(label), "weight": torch.from_numpy(weight)}


def cosine_rate(lr: float, lr_min: float, frac: float) -> float:
    """The rate ``frac`` (0..1, clipped) of the way along half a cosine from ``lr`` down to ``lr_min``."""
    return lr_min + 0.5 * (lr - lr_min) * (1.0 + np.cos(np.pi * min(1.0, max(0.0, frac))))


def iteration_lr(cfg: TrainConfig, it: int) -> float:
    """Learning rate of iteration ``it`` (0-based) under ``cfg.lr_schedule``."""
    if cfg.lr_schedule == "constant":
        return cfg.lr
    if cfg.lr_schedule == "cosine":
        return cosine_rate(cfg.lr, cfg.lr_min, it / max(1, cfg.iterations - 1))
    if cfg.lr_schedule == "linear":
        return cfg.lr + (cfg.lr_min - cfg.lr) * min(1.0, it / max(1, cfg.iterations - 1))
    raise ValueError(f"unknown lr_schedule {cfg.lr_schedule!r}: choose constant, cosine or linear")


def inflection_weights(labels: np.ndarray, w: float) -> np.ndarray:
    """``w`` at the first step and wherever the label changes, 1 elsewhere."""
    out = np.ones(len(labels), np.float32)
    out[0] = w
    out[1:][labels[1:] != labels[:-1]] = w
    return out


def step_weights(labels: np.ndarray, blocked: np.ndarray, goal: np.ndarray, cfg: TrainConfig) -> np.ndarray:
    """Each step's loss weight: inflections, steps right after a refused FORWARD (where only the unchanged point
    goal tells the LSTM it is blocked) and steps near the goal (where the STOP is decided) weigh more."""
    return (inflection_weights(labels, cfg.inflection_weight)
            * np.where(blocked, np.float32(cfg.collision_weight), np.float32(1.0))
            * np.where(goal[:, 0] < cfg.endgame_radius, np.float32(cfg.endgame_weight), np.float32(1.0)))


# ------------------------------------------------------------------------------------------ rollouts
class Collector:
    """Rolls out ``envs`` with a beta-mixture of expert and learner (``policy``), labelling every step with the
    expert. Episodes continue across ``collect`` calls and are handed over whole when they end."""

    def __init__(self, envs: list[PointNavEnv], cfg: TrainConfig, rng: np.random.Generator,
                 policy: PointNavResNetPolicy):
        self.cfg, self.rng, self.policy = cfg, rng, policy
        self.slots = EnvSlots(envs, rng, cfg.tight_starts, expert=(cfg.expert_success_distance, cfg.expert_margin))
        self.state = [self._fresh() for _ in envs]

    @property
    def envs(self) -> list[PointNavEnv]:
        return self.slots.envs

    @classmethod
    def for_worker(cls, cfg: TrainConfig, envs: list[PointNavEnv], rng_seed: list[int]) -> Collector:
        return cls(envs, cfg, np.random.default_rng(rng_seed), build_learner(cfg))

    @staticmethod
    def worker_args(args: tuple, workers: int) -> tuple:
        frames, beta = args
        return -(-frames // workers), beta  # each worker collects its share of the frames

    @staticmethod
    def merge(results: list) -> tuple[list[dict], list[float]]:
        return [e for r in results for e in r[0]], [x for r in results for x in r[1]]

    def learner(self) -> PointNavAgentPolicy:
        """The acting policy: as trained, in bf16 with ``act_bf16`` (build_learner made it channels_last)."""
        return PointNavAgentPolicy(self.policy, num_envs=len(self.envs),
                                   config=InferenceConfig(channels_last=False, bf16=self.cfg.act_bf16))

    @staticmethod
    def _fresh() -> dict:
        # steps: taken this episode; last: the previous action; new: the learner's memory needs a reset;
        # hit: the last FORWARD was refused
        return {"steps": 0, "last": 0, "new": True, "hit": False,
                "feat": [], "goal": [], "prev": [], "mask": [], "label": [], "blocked": []}

    def _episode(self, s: dict) -> dict[str, np.ndarray]:
        labels = np.array(s["label"], np.int64)
        goal = np.stack(s["goal"]).astype(np.float32)
        return {"feat": np.stack(s["feat"]), "goal": goal, "prev": np.array(s["prev"], np.int64),
                "mask": np.array(s["mask"], bool), "label": labels,
                "weight": step_weights(labels, np.array(s["blocked"]), goal, self.cfg)}

    def snapshot(self) -> dict:
        """The envs and the episodes in flight (their recorded steps), for an exact resume."""
        state = []
        for s in self.state:
            state.append({"steps": s["steps"], "last": s["last"], "new": s["new"], "hit": bool(s["hit"]),
                          "feat": torch.from_numpy(np.stack(s["feat"])) if s["feat"] else None,
                          "goal": torch.from_numpy(np.stack(s["goal"])) if s["goal"] else None,
                          "prev": [int(v) for v in s["prev"]], "mask": [bool(v) for v in s["mask"]],
                          "label": [int(v) for v in s["label"]], "blocked": [bool(v) for v in s["blocked"]]})
        return {"slots": self.slots.snapshot(), "state": state}

    def restore(self, snap: dict) -> None:
        self.slots.restore(snap["slots"])
        self.state = []
        for s in snap["state"]:
            self.state.append({**s, "feat": [] if s["feat"] is None else list(s["feat"].numpy()),
                               "goal": [] if s["goal"] is None else list(s["goal"].numpy()),
                               "prev": list(s["prev"]), "mask": list(s["mask"]), "label": list(s["label"]),
                               "blocked": list(s["blocked"])})

    def collect(self, frames: int, beta: float, preempt: ddp.Preemption | None = None
                ) -> tuple[list[dict], list[float]]:
        """At least ``frames`` steps over the envs (fewer when ``preempt`` ends the collection early): (episodes
        that ended, their successes)."""
        cfg, rng, slots = self.cfg, self.rng, self.slots
        learner = self.learner()
        out: list[dict[str, np.ndarray]] = []
        successes: list[float] = []
        for i, s in enumerate(self.state):
            if s["new"]:
                learner.reset(i)
        count = 0
        while count < frames:
            if preempt is not None and preempt.should_stop(count, frames):
                break
            # the learner's forward pass also gives the encoder output that the buffer stores
            actions, visual = learner.act_and_encode(np.stack([o["depth"] for o in slots.obs]),
                                                     np.stack([o["pointgoal_with_gps_compass"] for o in slots.obs]))
            visual = visual.to(torch.float16).numpy()
            for i in range(len(slots)):
                s = self.state[i]
                label = slots.label(i)
                s["feat"].append(visual[i])
                s["goal"].append(slots.obs[i]["pointgoal_with_gps_compass"].copy())
                s["prev"].append(s["last"])
                s["mask"].append(s["steps"] > 0)
                s["label"].append(label)
                s["blocked"].append(s["hit"])
                action = label if rng.random() < beta else int(actions[i])
                if action != STOP and rng.random() < cfg.random_action_prob:
                    action = int(rng.integers(1, 4))
                learner.prev_actions[i] = action  # the learner's memory must see the action taken
                term, trunc, info, s["hit"] = slots.step(i, action)
                s["last"], s["steps"], s["new"] = action, s["steps"] + 1, False
                count += 1
                if term or trunc or s["steps"] >= cfg.max_episode_steps:
                    out.append(self._episode(s))
                    successes.append(info["success"] if term else 0.0)
                    slots.restart(i)
                    self.state[i] = self._fresh()
                    learner.reset(i)
        if preempt is not None:
            preempt.finished()
        return out, successes


def evaluate(policy: PointNavResNetPolicy, episodes: int, max_steps: int = 500) -> dict[str, float]:
    """Deterministic SR/SPL on the first ``episodes`` episodes of the bundled PointNav ``select`` split (batched
    over 8 envs): the split for watching and choosing among trained policies, so ``val`` stays unseen."""
    ds = load_dataset(split_file("pointnav", "select"))
    eps = ds.episodes[:episodes]
    cfg = EnvConfig(rgb=False, depth=True, max_steps=max_steps)
    n = min(8, len(eps))
    envs = [PointNavEnv(ds, config=cfg) for _ in range(n)]
    agent = PointNavAgentPolicy(policy, num_envs=n, config=InferenceConfig(channels_last=False))
    queue = list(eps)
    obs: list = [None] * n
    active = [False] * n
    results = []

    def start(i):
        if queue:
            obs[i], _ = envs[i].reset(options={"episode": queue.pop(0)})
            agent.reset(i)
            active[i] = True
        else:
            active[i] = False

    for i in range(n):
        start(i)
    while any(active):
        depth = np.stack([o["depth"] for o in obs])
        goal = np.stack([o["pointgoal_with_gps_compass"] for o in obs])
        actions = agent.act(depth, goal)
        for i in range(n):
            if not active[i]:
                continue
            obs[i], _, term, trunc, info = envs[i].step(int(actions[i]))
            if term or trunc:
                results.append((info["success"], info["spl"]))
                start(i)
    for e in envs:
        e.close()
    policy.train()
    return {"select_sr": float(np.mean([r[0] for r in results])),
            "select_spl": float(np.mean([r[1] for r in results]))}


# -------------------------------------------------------------------------------------------- train
def build_learner(cfg: TrainConfig) -> PointNavResNetPolicy:
    """The policy to train: the visual encoder frozen, channels_last (oneDNN's NHWC convolutions act faster)."""
    policy = PointNavResNetPolicy(PolicyNetConfig()).to(memory_format=torch.channels_last)
    policy.net.visual_encoder.requires_grad_(False)
    return policy


def train_step(policy: PointNavResNetPolicy, opt: torch.optim.Optimizer, batch: dict[str, torch.Tensor],
               cfg: TrainConfig, forward=None) -> tuple[float, float]:
    """One update on a batch of stored episodes: weighted cross-entropy to the expert's labels. (loss, accuracy)

    ``forward`` is the training forward (``policy.forward_features``, or its DDP wrapper in a distributed run,
    where the loss is normalised by every rank's total weight: the averaged gradient is then the gradient of
    one process on the union of the ranks' batches)."""
    forward = policy.forward_features if forward is None else forward
    T, n = batch["label"].shape
    dev = next(policy.parameters()).device
    batch = {k: v.to(dev) for k, v in batch.items()}
    hidden = policy.initial_hidden(n, dev)
    with torch.autocast(dev.type, dtype=torch.bfloat16, enabled=cfg.bf16):
        logits, _, _ = forward(batch["feat"].float(), batch["goal"], batch["prev"], batch["mask"], hidden)
    logits = logits.float()
    w = batch["weight"]
    dist = ddp.info()
    norm = w.sum() if not dist.distributed else ddp.all_sum([float(w.sum())])[0] / dist.world_size
    loss = (F.cross_entropy(logits.reshape(T * n, -1), batch["label"].reshape(-1), reduction="none")
            * w.reshape(-1)).sum() / norm
    opt.zero_grad(set_to_none=True)
    loss.backward()
    torch.nn.utils.clip_grad_norm_([p for p in policy.parameters() if p.requires_grad], cfg.grad_clip)
    opt.step()
    valid = w > 0
    acc = (logits.argmax(-1)[valid] == batch["label"][valid]).float().mean()
    return loss.item(), acc.item()


def train(cfg: TrainConfig, out: Path, resume: bool = False, state_dir: Path = Path("runs/pointnav/dagger_state"),
          init: Path | None = None, log_every=print, device: str = "cpu") -> dict[str, float]:
    """Run ``cfg`` from ``init``'s weights (or resume from ``state_dir``); writes ``out`` and its ``.log.csv``.
    The learner's updates (and, with one worker, its rollouts) run on ``device`` (resolved); rollout workers
    act on the CPU. Under torchrun or SLURM every rank runs this (:mod:`navbench.policy.distributed`) with its
    own envs and buffer; rank 0 writes the checkpoint and the log."""
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    dist = ddp.init(device)
    device = ddp.rank_device(device)
    resume = resume or ddp.restarted()
    rng = np.random.default_rng(ddp.rank_seeds(cfg.seed))
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    state_dir = Path(state_dir)
    state_dir.mkdir(parents=True, exist_ok=True)
    state_path = state_dir / "train_state.pt"  # weights + optimizer: resumable, not shipped
    log_path = out.with_suffix(".log.csv")
    if not dist.is_main:
        log_every = _quiet

    policy = build_learner(cfg).to(device)
    opt = torch.optim.Adam([p for p in policy.parameters() if p.requires_grad], lr=cfg.lr,
                           weight_decay=cfg.weight_decay)
    start_it, frames_total, wall0 = 0, 0, 0.0
    if resume and state_path.is_file():
        start_it, frames_total, wall0 = load_train_state(state_path, policy, opt, "iteration")
        rng = np.random.default_rng(ddp.rank_seeds([cfg.seed, start_it]))
        log_every(f"resumed at iteration {start_it} ({frames_total} frames, {wall0:.0f} s)")
        if dist.is_main:
            keep_rows_through(log_path, "iteration", start_it)
    else:
        if init is not None:  # warm start: weights only, fresh optimizer
            policy.load_state_dict(load_checkpoint(init).state_dict())
            log_every(f"initialised from {init}")
        if dist.is_main and log_path.exists():
            log_path.unlink()
    if dist.distributed:
        log_every(f"world size {dist.world_size} ({dist.backend}): {cfg.num_envs} envs per rank")
    ddp.barrier()

    first = dist.rank * cfg.num_envs  # env i of rank r is seeded base + r * num_envs + i
    if cfg.workers > 1:
        source = Collection.in_workers(Collector, cfg, cfg.seed + start_it,
                                       [ddp.rank_seeds([cfg.seed, start_it, w]) for w in range(cfg.workers)],
                                       first_env=first)
    else:
        source = Collection(Collector(make_envs(cfg.num_envs, cfg.train_split, cfg.seed + start_it, first), cfg, rng,
                                      policy))
    buffer = ShardedBuffer(cfg.buffer_frames, ddp.rank_state_path(state_dir / "buffer"))
    if start_it == 0:  # a fresh run: shards an earlier run left are not this run's
        for stale in buffer.directory.glob("iteration_*.pt"):
            stale.unlink()
    local = ddp.load_local(state_path, "iteration", start_it) if start_it > 0 else None
    if local is not None and len(local["collect"]) != max(1, cfg.workers):  # saved with another --workers
        local = None
    if local is not None:  # continue the envs, the episodes in flight, the buffer and the random streams exactly
        source.restore(local["collect"])
        ddp.set_rng_state(rng, local["rng"])
        torch.set_rng_state(local["torch_rng"])
        buffer.load(local["shards"])
    elif start_it > 0:
        log_every("the resume state holds no rollout state for this world size: envs and buffer start afresh")
    try:
        return _train_loop(cfg, policy, opt, rng, source, buffer, start_it, frames_total, wall0, out, log_path,
                           state_path, log_every)
    finally:
        source.close()


def _quiet(*_args) -> None:
    """The log of a rank other than 0: its rows are rank 0's."""


class ShardedBuffer(EpisodeBuffer):
    """The aggregated buffer, each iteration's new episodes also written to ``directory`` as one shard, so a
    resumed run rebuilds the same buffer; shards wholly dropped from the buffer are deleted."""

    def __init__(self, max_frames: int, directory: Path):
        super().__init__(max_frames)
        self.directory = Path(directory)
        self.shards: list[list[int]] = []  # [iteration, episodes] of the shards on disk, oldest first
        self.added = 0  # episodes added so far (those before added - len(episodes) were dropped)

    def _path(self, it: int) -> Path:
        return self.directory / f"iteration_{it:06d}.pt"

    def add_iteration(self, it: int, eps: list[dict[str, np.ndarray]], save: bool = True) -> None:
        for e in eps:
            self.add(e)
        self.added += len(eps)
        if save:
            self.directory.mkdir(parents=True, exist_ok=True)
            save_train_state(self._path(it), {"episodes": [{k: torch.from_numpy(np.ascontiguousarray(v))
                                                            for k, v in e.items()} for e in eps]})
            self.shards.append([it, len(eps)])
        oldest, first = self.added - len(self.episodes), self.added - sum(n for _, n in self.shards)
        while self.shards and first + self.shards[0][1] <= oldest:
            first += self.shards[0][1]
            self._path(self.shards.pop(0)[0]).unlink(missing_ok=True)

    def load(self, shards: list[list[int]]) -> None:
        """Rebuild the buffer from the shards a saved state lists (adding them in order drops the same episodes)."""
        for it, _ in shards:
            eps = read_train_state(self._path(it))["episodes"]
            self.add_iteration(it, [{k: v.numpy() for k, v in e.items()} for e in eps], save=False)
        self.shards = [list(x) for x in shards]


def _train_loop(cfg, policy, opt, rng, source: Collection, buffer: ShardedBuffer, start_it, frames_total, wall0,
                out, log_path, state_path, log_every) -> dict[str, float]:
    """The iterations of :func:`train`: collect, aggregate, update, monitor, log, save (also when SIGTERM or
    SIGUSR1 asks)."""
    dist = ddp.info()
    t_start = time.time() - wall0
    last: dict[str, float] = {}
    forward = ddp.training_forward(policy)
    iterations = range(start_it, cfg.iterations)
    with ddp.StopSignals() as signals:
        for it in (progress(iterations, desc="dagger iterations") if dist.is_main else iterations):
            beta = max(cfg.beta_min, cfg.beta0 * cfg.beta_decay ** it)
            lr = iteration_lr(cfg, it)
            for group in opt.param_groups:
                group["lr"] = lr
            policy.eval()
            t0 = time.time()
            preempt = ddp.Preemption(cfg.preempt_fraction, cfg.preempt_min_share, f"{Path(out).name}/{it}")
            eps, successes = source.collect(policy, cfg.frames_per_iteration, beta,
                                            *([preempt] if source.local is not None else []))
            buffer.add_iteration(it + 1, eps)
            new_frames = sum(len(e["label"]) for e in eps)
            t_collect = time.time() - t0
            policy.train()
            n_updates = _updates(cfg, buffer, new_frames)
            new_frames = int(ddp.all_sum([float(new_frames)])[0])
            frames_total += new_frames
            losses, accs = [], []
            t0 = time.time()
            for _ in range(n_updates):
                loss, acc = train_step(policy, opt, buffer.sample(rng, cfg.batch_episodes), cfg, forward)
                losses.append(loss)
                accs.append(acc)
            t_train = time.time() - t0
            policy.eval()
            monitor = (evaluate(policy, cfg.monitor_episodes, cfg.monitor_max_steps)
                       if cfg.monitor_episodes > 0 and dist.is_main
                       else {"select_sr": float("nan"), "select_spl": float("nan")})
            means = ddp.all_mean({"loss": float(np.mean(losses)) if losses else float("nan"),
                                  "acc": float(np.mean(accs)) if accs else float("nan"),
                                  "rollout_success": float(np.mean(successes)) if successes else float("nan")})
            buffer_frames = int(ddp.all_sum([float(buffer.frames)])[0])
            last = {"iteration": it + 1, "frames": frames_total, "beta": beta, "lr": f"{lr:.4g}",
                    "loss": means["loss"], "acc": means["acc"], "rollout_success": means["rollout_success"],
                    **monitor, "collect_s": t_collect, "train_s": t_train, "updates": n_updates,
                    "buffer_frames": buffer_frames, "wall_s": time.time() - t_start}
            if dist.is_main:
                log_every(log_row(log_path, last, digits=3))
                meta = {"train_config": dataclasses.asdict(cfg), "frames": frames_total, "wall_s": last["wall_s"],
                        "iteration": it + 1, **monitor}
                save_checkpoint(out, policy, meta)
            ddp.save_resume(state_path, {"policy": policy.state_dict(), "optimizer": opt.state_dict(),
                                         "iteration": it + 1, "frames": frames_total, "wall_s": last["wall_s"]},
                            {"iteration": it + 1, "collect": source.snapshot(), "rng": ddp.rng_state(rng),
                             "torch_rng": torch.get_rng_state(), "shards": buffer.shards})
            if signals.requested():
                log_every(f"stopped by signal {signals.signum or 'on another rank'} after iteration {it + 1}; "
                          "resume state saved (continue with --resume)")
                last = {**last, "stopped_by_signal": signals.signum or -1}
                break
    return last


def _updates(cfg: TrainConfig, buffer: EpisodeBuffer, new_frames: int) -> int:
    """Gradient steps of this iteration: ``epochs_per_iteration`` passes over the new frames, in batches of
    ``batch_episodes`` episodes of the buffer's mean length; the same on every rank (from the ranks' totals),
    none while some rank's buffer is empty (the episodes in flight carry over into the next collection)."""
    if not ddp.info().distributed:
        if not buffer.episodes:
            return 0
        seq_len = buffer.frames / len(buffer.episodes)
        return max(1, round(new_frames * cfg.epochs_per_iteration / (seq_len * cfg.batch_episodes)))
    if ddp.all_min([float(len(buffer.episodes))])[0] == 0:
        return 0
    frames, episodes, new = ddp.all_sum([float(buffer.frames), float(len(buffer.episodes)), float(new_frames)])
    return max(1, round(new * cfg.epochs_per_iteration / (frames / episodes * cfg.batch_episodes)))


def main(cfg: TrainConfig, out: Path, state_dir: Path, init: Path | None, resume: bool,
         device: str = "cpu") -> dict[str, float]:
    """``navbench train dagger``: train, print the last log row as JSON."""
    result = train(cfg, out, resume=resume, state_dir=state_dir, init=init, device=device)
    if ddp.info().is_main:
        print(json.dumps(result))
    return result
