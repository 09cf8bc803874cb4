"""Train the PointNav policy on CPU by imitating a shortest-path expert with DAgger.

The expert is the geodesic follower (plans on the true map and keeps ``expert_margin`` of clearance;
``--expert geodesic``, the default) or the optimistic follower (plans on what the agent has seen;
``--expert optimistic``).

    make train-pointnav        # the shipped checkpoint's four-stage recipe (policies/README.md)
    navbench train pointnav --init runs/pointnav/encoder.pth --out runs/pointnav/policy.pth  # add --resume

Each iteration rolls out ``num_envs`` PointNav envs (depth only, the sensor the policy reads) on the
PointNav split ``train_split`` (the 8 bundled train houses, or ``train_large`` with 40 more). The
executed action is the oracle's with probability beta (1 in the first iteration, decaying) and the
learner's otherwise, plus occasional random turns/moves so the data covers recovery from off-path
states; every step is labelled with the oracle's action from the state actually reached (DAgger).
Frames join an aggregated buffer and the network is trained with cross-entropy and inflection
weighting (steps where the oracle changes its action, including STOP, weigh more) on whole episodes
from their first step (default) or on short chunks that start from a zero recurrent state
(``--truncated``). After every iteration it evaluates on bundled PointNav ``val`` episodes, logs to
CSV and writes a resumable checkpoint.

With ``--workers 2`` the envs are split between two rollout processes (:mod:`navbench.policy.workers`),
each with its own copy of the policy, refreshed with the trainer's weights before every collection; on 2
cores that collects ~1.4x faster than one process, whose renderer and expert leave a core idle.

By default (``freeze_visual``) the visual encoder is not trained: the buffer keeps the encoder output
the rollout's own forward pass computed for each frame (fp16), and the rest of the network trains on
those, ~50x cheaper per update on 2 cores. With a trainable encoder the buffer keeps the frames
(depth 2x2-pooled as uint8: the network average-pools 2x2 first, so this loses only quantisation). Start
from a checkpoint whose encoder was trained (``--init PATH``, e.g. ``navbench train encoder``'s output,
see :mod:`navbench.policy.pretrain`). ``--train-encoder`` trains the whole network on short chunks,
with an auxiliary free-space regression on the encoder output.
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

from navbench.env.config import EnvConfig, STOP
from navbench.env.pointnav import PointNavEnv
from navbench.episodes.io import load_dataset
from navbench.paths import split_file
from navbench.policy.checkpoint import load_checkpoint, save_checkpoint, save_train_state
from navbench.policy.net import InferenceConfig, PointNavAgentPolicy, PointNavResNetPolicy, PolicyNetConfig
from navbench.policy.pretrain import free_distances
from navbench.policy.progress import log_row
from navbench.policy.workers import WorkerPool
from navbench.scene.follower import GreedyFollower
from navbench.scene.optimistic import OptimisticFollower
from navbench.scene.pose import quat_from_yaw


@dataclass(frozen=True)
class TrainConfig:
    # "geodesic": the true shortest path (with expert_margin of clearance), the shipped policy's expert;
    # "optimistic": the shortest path on the map seen so far (unseen cells free), whose labels follow
    # from the observation history (navbench.scene.optimistic explains); slower to label.
    expert: str = "geodesic"
    # PointNav split the envs roll out in: "train" (the 8 bundled train houses) or "train_large" (those
    # plus the 40 extra houses of `navbench generate policy-train`: more scenes, a smaller train-val gap).
    train_split: str = "train"
    iterations: int = 14
    frames_per_iteration: int = 6_000
    num_envs: int = 8
    beta0: float = 1.0  # oracle share of executed actions in iteration 0 ...
    beta_decay: float = 0.7  # ... multiplied by this every iteration
    beta_min: float = 0.1
    random_action_prob: float = 0.08  # perturbation (never STOP) for recovery data
    max_episode_steps: int = 250  # long stuck learner rollouts add little; cut them
    buffer_frames: int = 250_000
    # Train on whole episodes from their first step (the LSTM then learns on the recurrent states it
    # meets when deployed). Chunks of chunk_len steps that start from a zero state (truncated BPTT,
    # full_episodes=False) are cheaper with a trainable encoder, but the policy never sees a state
    # after more than chunk_len steps, and its deterministic rollouts drifted into states it was never
    # trained on (pushing into walls for hundreds of steps).
    full_episodes: bool = True
    chunk_len: int = 32  # truncated BPTT length when not full_episodes
    batch_chunks: int = 16  # sequences (episodes or chunks) per update
    epochs_per_iteration: float = 16.0  # gradient steps = this x new frames / frames per update
    lr: float = 5e-4
    # "constant", or "cosine": the rate of iteration i falls from lr to lr_min along half a cosine over the
    # run's iterations. The staged recipe lowered the rate by hand from stage to stage (5e-4 ... 1.56e-5,
    # each drop paid on val: policies/README.md), restarting the buffer and optimizer each time; a
    # schedule gets the same descent in one run, whose aggregated buffer keeps every iteration's data.
    lr_schedule: str = "constant"
    lr_min: float = 1e-5
    weight_decay: float = 0.0
    inflection_weight: float = 3.0
    # Loss weight of steps right after a blocked FORWARD. The shipped stage-5 policy's commonest val
    # failure (17 of 28) is pressing FORWARD into an obstacle beside the camera's view (a plant at the
    # agent's flank) for the rest of the episode: without sliding the frame does not change, so only
    # the unchanged point goal after a FORWARD tells the LSTM it is blocked. These steps are a small
    # share of the buffer; weighting them makes the turn the expert labels there count. 1 = off.
    # Tried at 3 from stage 5 (policies/README.md): pinned val failures 17 -> 10, early STOPs 5 -> 10.
    collision_weight: float = 1.0
    # Loss weight of steps within endgame_radius of the goal, where the STOP is decided. Stages 6 and 7
    # (policies/README.md) freed pinned episodes but lost as many to STOPs 0.2-0.5 m short of the goal;
    # these steps are a few percent of the buffer. 1 = off.
    endgame_weight: float = 1.0
    endgame_radius: float = 0.75
    # Loss weight of steps where the expert's plan still needs turnaround_turns or more turns (>= 90
    # degrees at 30-degree turns). Session 15 traced the shipped file's pinned val failures: at a wall
    # between it and the goal the expert turns one way for several steps (in 12 of 14 such episodes a
    # history-only planner, the optimistic follower, takes the expert's action on 88-100% of the steps),
    # while the policy turns back towards the goal after one or two turns and bumps into the wall
    # again. 1 = off.
    turnaround_weight: float = 1.0
    turnaround_turns: int = 3
    # Feed the previous action to the LSTM (habitat's prev_action_embedding). Cloned policies that see
    # their previous action can learn to repeat it (expert actions come in long runs: the "copycat"
    # failure of behaviour cloning), but without it a policy cannot tell that its last FORWARD was
    # blocked (no sliding: the frame does not change), and DAgger labels exactly those states. Off
    # (--no-prev-action), the embedding table is zeroed and frozen; the state_dict keeps its layout.
    prev_action: bool = True
    # Extra room (m) the geodesic expert keeps from obstacles where it can (GreedyFollower's
    # clearance_margin): shortest paths graze corners, and a learner that follows them a few
    # centimetres off clips the corner with its body and, without sliding, does not move at all.
    expert_margin: float = 0.15
    # Where the expert says STOP (None: success_distance). A cloned STOP is imprecise by a few
    # centimetres; an expert that stops at 0.1 m puts the learner's stops inside the 0.2 m success
    # radius instead of just outside it (most failed STOPs of the 0.2 m expert's policy were at 0.2-0.35 m).
    expert_success_distance: float | None = None
    grad_clip: float = 1.0
    val_episodes: int = 16
    # Monitoring only (the shipped figures come from `navbench run` with the full 500): an untrained
    # policy that never stops would otherwise spend most of an iteration in evaluation.
    val_max_steps: int = 250
    success_distance: float = 0.2
    # Probability that a rollout episode starts from a random cell beside an obstacle instead of its own
    # start (reset_maybe_tight). 0 = off.
    tight_starts: float = 0.0
    seed: int = 0
    threads: int = 2
    # Rollout processes (navbench.policy.workers): with 2, each steps half of the envs with its own copy of
    # the policy, one llvmpipe and one torch thread, and collection runs ~1.4x faster on 2 cores (session 31).
    # 1 = in this process, as every committed run before session 31 was collected. Results depend on the
    # number of workers (each has its own random stream), not on timing.
    workers: int = 1
    # torch.autocast(cpu, bfloat16) around each update's forward pass (the optimizer keeps fp32 weights).
    # With the encoder frozen an update is the LSTM and the fully connected layers on cached features;
    # on session 29's AVX-512-BF16 CPU (family 25) that runs ~1.6x faster under bf16 (T=80 x 16
    # sequences: 0.25 -> 0.16 s). Off by default: the committed recipes and logs were trained in fp32.
    bf16: bool = False
    # bfloat16 autocast while the learner acts in collection. The encoder's forward pass is about half of a
    # rollout worker's time, and at one thread and batch 4 it runs 356 frames/s in bf16 against 262 in fp32
    # (session 32, family-25 EPYC). The stored features are then bf16-rounded (~2% relative difference)
    # while evaluation encodes in fp32. Off by default: every committed recipe collected in fp32.
    act_bf16: bool = False
    # Train everything after the visual encoder on cached encoder outputs (the encoder stays as it is,
    # e.g. as initialised or as loaded with --init). On 2 cores the ResNet's backward pass is ~90% of a
    # full update; without it an update is ~50x cheaper, which is what makes CPU training converge.
    freeze_visual: bool = True
    # Auxiliary loss while the encoder trains: regress, from the encoder output alone, how far the
    # agent could walk straight along a few headings inside the field of view (from the navigable
    # grid, capped at free_space_range). The action label says little about geometry (one of four
    # classes, often ambiguous); this dense target teaches the encoder where obstacles are.
    aux_free_space_weight: float = 1.0
    free_space_headings_deg: tuple[float, ...] = (-30.0, -15.0, 0.0, 15.0, 30.0)
    free_space_range: float = 2.5


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

    def sample(self, rng: np.random.Generator, n: int, T: int | None) -> dict[str, torch.Tensor]:
        """``n`` chunks of up to T steps; the chunk's first step starts fresh (mask 0), padding weighs 0.

        ``T=None``: whole episodes from their first step, drawn uniformly, padded to the longest.
        """
        lens = np.array([len(e["label"]) for e in self.episodes])
        whole = T is None
        if whole:
            # n episodes of similar length (a random window of the length-sorted list): padding to the
            # longest then wastes little of the LSTM's time, the cost of a whole-episode update.
            by_len = np.argsort(lens, kind="stable")
            start = int(rng.integers(max(1, len(by_len) - n + 1)))
            eps = by_len[start:start + n] if len(by_len) >= n else rng.choice(len(self.episodes), size=n)
            T = int(lens[eps].max())
        else:
            eps = rng.choice(len(self.episodes), size=n, p=lens / lens.sum())
        key = "feat" if "feat" in self.episodes[0] else "depth"
        obs_shape, obs_dtype = self.episodes[0][key].shape[1:], self.episodes[0][key].dtype
        depth = np.zeros((T, n, *obs_shape), obs_dtype)
        goal = np.zeros((T, n, 2), np.float32)
        prev = np.zeros((T, n), np.int64)
        mask = np.zeros((T, n), bool)
        label = np.zeros((T, n), np.int64)
        weight = np.zeros((T, n), np.float32)
        has_free = "free" in self.episodes[0]
        free = np.zeros((T, n, self.episodes[0]["free"].shape[1] if has_free else 0), np.float32)
        for j, e in enumerate(eps):
            ep = self.episodes[e]
            L = len(ep["label"])
            s = 0 if whole else int(rng.integers(L))
            k = min(T, L - s)
            depth[:k, j] = ep[key][s:s + k]
            goal[:k, j] = ep["goal"][s:s + k]
            prev[:k, j] = ep["prev"][s:s + k]
            mask[:k, j] = ep["mask"][s:s + k]
            mask[0, j] = False  # no history before the chunk: start it like an episode
            label[:k, j] = ep["label"][s:s + k]
            weight[:k, j] = ep["weight"][s:s + k]
            if has_free:
                free[:k, j] = ep["free"][s:s + k]
        batch = {key: torch.from_numpy(depth), "goal": torch.from_numpy(goal), "prev": torch.from_numpy(prev),
                 "mask": torch.from_numpy(mask), "label": torch.from_numpy(label), "weight": torch.from_numpy(weight)}
        if has_free:
            batch["free"] = torch.from_numpy(free)
        return batch


def pooled_uint8(depth: np.ndarray) -> np.ndarray:
    """(H, W, 1) depth in [0,1] -> (H/2, W/2) uint8, the network's own 2x2 average pool, quantised."""
    d = depth[..., 0]
    d = d.reshape(d.shape[0] // 2, 2, d.shape[1] // 2, 2).mean(axis=(1, 3))
    return np.round(d * 255).astype(np.uint8)


def unpool(depth_u8: torch.Tensor) -> torch.Tensor:
    """(..., h, w) uint8 -> (..., 2h, 2w, 1) float: nearest upsampling that the net's 2x2 pool inverts exactly."""
    d = depth_u8.float() / 255.0
    d = d.repeat_interleave(2, dim=-1).repeat_interleave(2, dim=-2)
    return d.unsqueeze(-1)


def silence_prev_action(policy: PointNavResNetPolicy) -> None:
    """Zero and freeze the previous-action embedding (TrainConfig.prev_action explains why)."""
    emb = policy.net.prev_action_embedding
    with torch.no_grad():
        emb.weight.zero_()
    emb.requires_grad_(False)


def cosine_rate(lr: float, lr_min: float, frac: float) -> float:
    """The rate ``frac`` (0..1, clipped) of the way along half a cosine from ``lr`` down to ``lr_min``."""
    return lr_min + 0.5 * (lr - lr_min) * (1.0 + np.cos(np.pi * min(1.0, max(0.0, frac))))


def iteration_lr(cfg: TrainConfig, it: int) -> float:
    """Learning rate of iteration ``it`` (0-based) under ``cfg.lr_schedule``."""
    if cfg.lr_schedule == "constant":
        return cfg.lr
    if cfg.lr_schedule == "cosine":
        return cosine_rate(cfg.lr, cfg.lr_min, it / max(1, cfg.iterations - 1))
    raise ValueError(f"unknown lr_schedule {cfg.lr_schedule!r}: choose constant or cosine")


def inflection_weights(labels: np.ndarray, w: float) -> np.ndarray:
    out = np.ones(len(labels), np.float32)
    out[0] = w
    out[1:][labels[1:] != labels[:-1]] = w
    return out


# ------------------------------------------------------------------------------------------ rollouts
def make_envs(n: int, split: str, seed: int, first: int = 0) -> list[PointNavEnv]:
    """Envs ``first .. first + n - 1`` of a training run: env ``i`` is seeded with ``seed * 1000 + i``, so a
    run split over workers draws the same episode streams as one process with all the envs."""
    ds = load_dataset(split_file("pointnav", split))
    cfg = EnvConfig(rgb=False, depth=True, success_distance=TrainConfig.success_distance)
    envs = [PointNavEnv(ds, config=cfg) for _ in range(n)]
    for i, env in enumerate(envs):
        env.reset(seed=seed * 1000 + first + i)
    return envs


def worker_shares(num_envs: int, workers: int) -> list[tuple[int, int]]:
    """(first env, env count) of each rollout worker: ``num_envs`` split as evenly as it goes."""
    if workers < 1 or workers > num_envs:
        raise ValueError(f"workers must be between 1 and num_envs ({num_envs}), got {workers}")
    counts = [num_envs // workers + (w < num_envs % workers) for w in range(workers)]
    return [(sum(counts[:w]), counts[w]) for w in range(workers)]


# Tight starts (``tight_starts``): a start on a navigable cell this close to the grid's edge leaves at most
# this much room between the body and an obstacle (the grid is already eroded by the 0.18 m radius).
TIGHT_CLEARANCE = 0.1
TIGHT_MIN_DISTANCE = 1.0  # metres of geodesic distance to the goal, so the episode is not over at once


def reset_maybe_tight(env: PointNavEnv, rng: np.random.Generator, p: float) -> dict:
    """``env.reset()`` (the env's own seeded draw), and with probability ``p`` the same episode again from a
    tight start: a random navigable cell within ``TIGHT_CLEARANCE`` of an obstacle, at least
    ``TIGHT_MIN_DISTANCE`` from the goal on its island, facing a random heading. Returns the first observation.

    The shipped policy fails 17.6% of the PointNav val episodes that start that close to an obstacle and
    5.4% of the others (policies/README.md): wedged in a slit beside furniture, it presses FORWARD
    against what it cannot see (depth reads 0 nearer than 0.5 m). Uniform starts put ~1 in 6 episodes
    there; this raises the share of training rollouts that begin in that state. It pays in DAgger, where
    the expert labels every step of the way out (session 25's stage 25: tight val starts failed 3 of 34,
    6 before), not in PPO, which leaves them by a lucky draw (stage 24: still 6).
    """
    obs, _ = env.reset()
    if p <= 0 or rng.random() >= p:
        return obs
    field = env.navgrid.distance_field(env.goal_points)
    for _ in range(20):
        start = env.navgrid.sample_tight_point(rng, TIGHT_CLEARANCE)
        if start is None:
            break
        if TIGHT_MIN_DISTANCE <= field.distance(start) < np.inf:
            ep = dataclasses.replace(env.episode, episode_id=f"{env.episode.episode_id}-tight",
                                     start_position=[float(v) for v in start],
                                     start_rotation=[float(v) for v in quat_from_yaw(rng.uniform(-np.pi, np.pi))])
            return env.reset(options={"episode": ep})[0]
    return obs  # no tight cell reaches the goal: keep the episode as drawn


def make_expert(env: PointNavEnv, cfg: TrainConfig) -> GreedyFollower:
    stop = cfg.expert_success_distance or cfg.success_distance
    if cfg.expert == "geodesic":
        return GreedyFollower(env.navgrid, env.goal_points, stop, clearance_margin=cfg.expert_margin)
    if cfg.expert == "optimistic":
        c = env.config
        return OptimisticFollower(env.navgrid, env.goal_points, stop, c.hfov_deg, c.min_depth, c.max_depth)
    raise ValueError(f"unknown expert {cfg.expert!r}: choose geodesic or optimistic")


class Collector:
    """Rolls out ``envs`` with a beta-mixture of oracle and learner, labelling every step with the oracle.

    Episodes continue across ``collect`` calls. With ``full_episodes`` an episode is handed over when
    it ends, so every stored episode starts at its first step; otherwise one still running at the end
    of a call is handed over as a segment (chunks start without history anyway).
    """

    def __init__(self, envs: list[PointNavEnv], cfg: TrainConfig, rng: np.random.Generator):
        self.envs, self.cfg, self.rng = envs, cfg, rng
        # The free-space target is only read by the auxiliary loss, which needs a trainable encoder.
        self.free_space = not cfg.freeze_visual and cfg.aux_free_space_weight > 0
        # A frozen encoder's outputs ("feat", fp16) are stored as the rollout computed them; a trainable
        # encoder needs the frames themselves ("depth", 2x2-pooled uint8).
        self.frame_key = "feat" if cfg.freeze_visual else "depth"
        self.state: list[dict] = [self._start(env) for env in envs]
        self.successes: list[float] = []  # success of each episode the last collect() finished

    def _start(self, env: PointNavEnv) -> dict:
        obs = reset_maybe_tight(env, self.rng, self.cfg.tight_starts)  # seeded draw from the env's own generator
        # hit: the last FORWARD was blocked; coll: the env's collision count so far
        return {"obs": obs, "follower": make_expert(env, self.cfg), "steps": 0, "last": 0, "new": True,
                "hit": False, "coll": 0, **self._empty()}

    def _empty(self) -> dict:
        lists = {self.frame_key: [], "goal": [], "prev": [], "mask": [], "label": [], "blocked": [], "turns": []}
        return {**lists, "free": []} if self.free_space else lists

    def _segment(self, s: dict) -> dict[str, np.ndarray]:
        labels = np.array(s["label"], np.int64)
        goal = np.stack(s["goal"]).astype(np.float32)
        seg = {self.frame_key: np.stack(s[self.frame_key]), "goal": goal,
               "prev": np.array(s["prev"], np.int64), "mask": np.array(s["mask"], bool), "label": labels,
               "weight": inflection_weights(labels, self.cfg.inflection_weight)
               * np.where(s["blocked"], np.float32(self.cfg.collision_weight), np.float32(1.0))
               * np.where(goal[:, 0] < self.cfg.endgame_radius, np.float32(self.cfg.endgame_weight),
                          np.float32(1.0))
               * np.where(np.array(s["turns"]) >= self.cfg.turnaround_turns, np.float32(self.cfg.turnaround_weight),
                          np.float32(1.0))}
        if self.free_space:
            seg["free"] = np.stack(s["free"])
        s.update(self._empty())
        return seg

    def collect(self, learner: PointNavAgentPolicy, frames: int, beta: float) -> tuple[list[dict], dict]:
        cfg, rng, n = self.cfg, self.rng, len(self.envs)
        out: list[dict[str, np.ndarray]] = []
        successes: list[float] = []
        for i, s in enumerate(self.state):
            if s["new"]:
                learner.reset(i)
        count = 0
        # The learner runs when it acts (beta < 1) or when its encoder output is what gets stored: then
        # the frame is encoded once, here, instead of again after collection.
        run_learner = beta < 1.0 or cfg.freeze_visual
        while count < frames:
            obs = [s["obs"] for s in self.state]
            if run_learner:
                learner_actions, visual = learner.act_and_encode(
                    np.stack([o["depth"] for o in obs]), np.stack([o["pointgoal_with_gps_compass"] for o in obs]))
                visual = visual.to(torch.float16).numpy()
            else:
                learner_actions = np.zeros(n, np.int64)
            for i, env in enumerate(self.envs):
                s = self.state[i]
                s["follower"].observe(s["obs"]["depth"], env.agent_position, env.agent_yaw)
                label = int(s["follower"].next_action(env.agent_position, env.agent_rotation))
                if cfg.freeze_visual:
                    s["feat"].append(visual[i])
                else:
                    s["depth"].append(pooled_uint8(s["obs"]["depth"]))
                s["goal"].append(s["obs"]["pointgoal_with_gps_compass"].copy())
                s["prev"].append(s["last"])
                s["mask"].append(s["steps"] > 0)
                s["label"].append(label)
                s["blocked"].append(s["hit"])
                s["turns"].append(s["follower"].turns_ahead)
                if self.free_space:
                    s["free"].append(free_distances(env.navgrid, env.agent_position, env.agent_yaw,
                                                     cfg.free_space_headings_deg, cfg.free_space_range))
                action = label if rng.random() < beta else int(learner_actions[i])
                if action != STOP and rng.random() < cfg.random_action_prob:
                    action = int(rng.integers(1, 4))
                if run_learner:
                    learner.prev_actions[i] = action  # the learner's memory must see the action taken
                s["obs"], _, term, trunc, info = env.step(action)
                s["hit"] = info["collisions"] > s["coll"]  # this FORWARD was blocked
                s["coll"] = info["collisions"]
                s["last"], s["steps"], s["new"] = action, s["steps"] + 1, False
                count += 1
                if term or trunc or s["steps"] >= cfg.max_episode_steps:
                    out.append(self._segment(s))
                    successes.append(info["success"] if term else 0.0)
                    self.state[i] = self._start(env)
                    learner.reset(i)
        if not cfg.full_episodes:
            for s in self.state:  # hand over running episodes as segments; they continue next call
                if s["label"]:
                    out.append(self._segment(s))
        self.successes = successes
        return out, {"rollout_success": float(np.mean(successes)) if successes else float("nan")}


def acting_config(cfg: TrainConfig) -> InferenceConfig:
    """How the learner acts in collection: as trained (build_learner already made it channels_last), in bf16
    with ``cfg.act_bf16``."""
    return InferenceConfig(channels_last=False, bf16=cfg.act_bf16)


class CollectorWorker:
    """One rollout worker's share of the envs (``TrainConfig.workers``): its envs, its :class:`Collector` with
    its own random stream, and a copy of the policy that ``collect`` refreshes with the trainer's weights."""

    def __init__(self, cfg: TrainConfig, first: int, num_envs: int, env_seed: int, rng_seed: list[int]):
        self.collector = Collector(make_envs(num_envs, cfg.train_split, env_seed, first), cfg,
                                   np.random.default_rng(rng_seed))
        self.policy, _ = build_learner(cfg)

    def collect(self, weights: dict[str, torch.Tensor], frames: int, beta: float) -> tuple[list[dict], list[float]]:
        self.policy.load_state_dict(weights)
        learner = PointNavAgentPolicy(self.policy.eval(), num_envs=len(self.collector.envs),
                                      config=acting_config(self.collector.cfg))
        eps, _ = self.collector.collect(learner, frames, beta)
        return eps, self.collector.successes


def collect_in_workers(pool: WorkerPool, policy: PointNavResNetPolicy, frames: int, beta: float
                       ) -> tuple[list[dict], dict]:
    """``Collector.collect`` over every worker of ``pool`` (each collects its share of ``frames``); episodes in
    worker order."""
    weights = policy.state_dict()
    share = -(-frames // len(pool))
    results = pool.call("collect", [(weights, share, beta)] * len(pool))
    eps = [e for r in results for e in r[0]]
    successes = [x for r in results for x in r[1]]
    return eps, {"rollout_success": float(np.mean(successes)) if successes else float("nan")}


def evaluate(policy: PointNavResNetPolicy, episodes: int, success_distance: float,
             max_steps: int = 500) -> dict[str, float]:
    """Deterministic SR/SPL on the first ``episodes`` episodes of bundled PointNav val (batched over 8 envs)."""
    ds = load_dataset(split_file("pointnav", "val"))
    eps = ds.episodes[:episodes]
    cfg = EnvConfig(rgb=False, depth=True, success_distance=success_distance, max_steps=max_steps)
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
    return {"val_sr": float(np.mean([r[0] for r in results])), "val_spl": float(np.mean([r[1] for r in results]))}


# -------------------------------------------------------------------------------------------- train
def make_aux_head(policy: PointNavResNetPolicy, cfg: TrainConfig) -> torch.nn.Module:
    """Training-only head on the encoder output (not part of the shipped state_dict)."""
    dim = policy.net.visual_fc[1].in_features
    return torch.nn.Sequential(torch.nn.Linear(dim, 256), torch.nn.ReLU(),
                               torch.nn.Linear(256, len(cfg.free_space_headings_deg)))


def build_learner(cfg: TrainConfig) -> tuple[PointNavResNetPolicy, torch.nn.Module | None]:
    """The policy to train (what is frozen set by ``cfg``) and the auxiliary head, if it trains one."""
    # channels_last: oneDNN's NHWC convolution kernels train ~1.7x faster on this CPU class
    policy = PointNavResNetPolicy(PolicyNetConfig()).to(memory_format=torch.channels_last)
    aux_head = None
    if cfg.freeze_visual:
        policy.net.visual_encoder.requires_grad_(False)
    elif cfg.aux_free_space_weight > 0:
        aux_head = make_aux_head(policy, cfg)
    if not cfg.prev_action:
        silence_prev_action(policy)
    return policy, aux_head


def train_step(policy, opt, batch, cfg: TrainConfig, aux_head: torch.nn.Module | None = None
               ) -> tuple[float, float]:
    T, n = batch["label"].shape
    hidden = policy.initial_hidden(n)
    with torch.autocast("cpu", dtype=torch.bfloat16, enabled=cfg.bf16):
        if "feat" in batch:
            feats = batch["feat"].float()
        else:
            depth = unpool(batch["depth"].reshape(T * n, *batch["depth"].shape[2:]))
            feats = policy.net.encode_depth(depth).reshape(T, n, -1)
        logits, _, _ = policy.forward_features(feats, batch["goal"], batch["prev"], batch["mask"], hidden)
    logits = logits.float()
    w = batch["weight"]
    loss = (F.cross_entropy(logits.reshape(T * n, -1), batch["label"].reshape(-1), reduction="none")
            * w.reshape(-1)).sum() / w.sum()
    if aux_head is not None:
        valid = (w > 0).reshape(-1)
        pred = aux_head(feats.reshape(T * n, -1)[valid].float())
        loss = loss + cfg.aux_free_space_weight * F.mse_loss(pred, batch["free"].reshape(T * n, -1)[valid])
    opt.zero_grad(set_to_none=True)
    loss.backward()
    params = [p for p in policy.parameters() if p.requires_grad]
    if aux_head is not None:
        params += list(aux_head.parameters())
    torch.nn.utils.clip_grad_norm_(params, cfg.grad_clip)
    opt.step()
    valid = w > 0
    acc = (logits.argmax(-1)[valid] == batch["label"][valid]).float().mean()
    return loss.item(), acc.item()


def train(cfg: TrainConfig, out: Path, resume: bool = False, state_dir: Path = Path("runs/train_pointnav"),
          init: Path | None = None, log_every=print) -> dict[str, float]:
    torch.set_num_threads(cfg.threads)
    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    state_dir = Path(state_dir)
    state_dir.mkdir(parents=True, exist_ok=True)
    state_path = state_dir / "train_state.pt"  # weights + optimizer (100 MB): resumable, not shipped
    log_path = out.with_suffix(".log.csv")

    policy, aux_head = build_learner(cfg)
    params = [p for p in policy.parameters() if p.requires_grad]
    opt = torch.optim.Adam(params + (list(aux_head.parameters()) if aux_head is not None else []), lr=cfg.lr,
                           weight_decay=cfg.weight_decay)
    start_it, frames_total, wall0 = 0, 0, 0.0
    if resume and state_path.is_file():
        st = torch.load(state_path, weights_only=False)
        policy.load_state_dict(st["policy"])
        if aux_head is not None and st.get("aux_head") is not None:
            aux_head.load_state_dict(st["aux_head"])
        opt.load_state_dict(st["optimizer"])
        start_it, frames_total, wall0 = st["iteration"], st["frames"], st["wall_s"]
        rng = np.random.default_rng([cfg.seed, start_it])
        log_every(f"resumed at iteration {start_it} ({frames_total} frames, {wall0:.0f} s)")
    else:
        if init is not None:  # warm start: weights only, fresh optimizer
            policy.load_state_dict(load_checkpoint(init).state_dict())
            if not cfg.prev_action:
                silence_prev_action(policy)
            log_every(f"initialised from {init}")
        if log_path.exists():
            log_path.unlink()

    envs: list[PointNavEnv] = []
    pool: WorkerPool | None = None
    shares = worker_shares(cfg.num_envs, cfg.workers)
    if cfg.workers > 1:
        pool = source = WorkerPool(CollectorWorker, [(cfg, first, n, cfg.seed + start_it, [cfg.seed, start_it, w])
                                                     for w, (first, n) in enumerate(shares)],
                                   threads=max(1, cfg.threads // cfg.workers))
    else:
        envs = make_envs(cfg.num_envs, cfg.train_split, cfg.seed + start_it)
        source = Collector(envs, cfg, rng)
    try:
        return _train_loop(cfg, policy, aux_head, opt, rng, source, start_it,
                           frames_total, wall0, out, log_path, state_path, log_every)
    finally:
        if pool is not None:
            pool.close()
        for e in envs:
            e.close()


def _train_loop(cfg, policy, aux_head, opt, rng, source: Collector | WorkerPool, start_it, frames_total, wall0,
                out, log_path, state_path, log_every) -> dict[str, float]:
    """The iterations of :func:`train`: collect (in this process, or in a WorkerPool), aggregate, update, log."""
    buffer = EpisodeBuffer(cfg.buffer_frames)
    t_start = time.time() - wall0
    last: dict[str, float] = {}
    for it in range(start_it, cfg.iterations):
        beta = max(cfg.beta_min, cfg.beta0 * cfg.beta_decay ** it)
        lr = iteration_lr(cfg, it)
        for group in opt.param_groups:
            group["lr"] = lr
        policy.eval()
        t0 = time.time()
        if isinstance(source, WorkerPool):
            eps, stats = collect_in_workers(source, policy, cfg.frames_per_iteration, beta)
        else:
            learner = PointNavAgentPolicy(policy, num_envs=cfg.num_envs, config=acting_config(cfg))
            eps, stats = source.collect(learner, cfg.frames_per_iteration, beta)
        for e in eps:
            buffer.add(e)
        new_frames = sum(len(e["label"]) for e in eps)
        frames_total += new_frames
        t_collect = time.time() - t0
        policy.train()
        if not buffer.episodes:  # whole episodes, none ended yet: they carry over into the next collection
            n_updates = 0
        else:
            seq_len = buffer.frames / len(buffer.episodes) if cfg.full_episodes else cfg.chunk_len
            n_updates = max(1, round(new_frames * cfg.epochs_per_iteration / (seq_len * cfg.batch_chunks)))
        losses, accs = [], []
        t0 = time.time()
        for u in range(n_updates):
            batch = buffer.sample(rng, cfg.batch_chunks, None if cfg.full_episodes else cfg.chunk_len)
            loss, acc = train_step(policy, opt, batch, cfg, aux_head)
            losses.append(loss)
            accs.append(acc)
        t_train = time.time() - t0
        policy.eval()
        val = (evaluate(policy, cfg.val_episodes, cfg.success_distance, cfg.val_max_steps) if cfg.val_episodes > 0
               else {"val_sr": float("nan"), "val_spl": float("nan")})
        last = {"iteration": it + 1, "frames": frames_total, "beta": beta, "lr": f"{lr:.4g}",
                "loss": float(np.mean(losses)) if losses else float("nan"),
                "acc": float(np.mean(accs)) if accs else float("nan"), **stats, **val,
                "collect_s": t_collect, "train_s": t_train, "updates": n_updates, "buffer_frames": buffer.frames,
                "wall_s": time.time() - t_start}
        log_every(log_row(log_path, last, digits=3))
        meta = {"train_config": dataclasses.asdict(cfg), "frames": frames_total, "wall_s": last["wall_s"],
                "iteration": it + 1, "val_sr": val["val_sr"], "val_spl": val["val_spl"]}
        save_checkpoint(out, policy, meta)
        save_train_state(state_path, {"policy": policy.state_dict(), "optimizer": opt.state_dict(),
                                      "iteration": it + 1,
                                      "aux_head": aux_head.state_dict() if aux_head is not None else None,
                                      "frames": frames_total, "wall_s": last["wall_s"]})
    return last


def config_from_args(args) -> TrainConfig:
    """The CLI's options over TrainConfig's defaults (an option left unset keeps the default)."""
    fields = TrainConfig.__dataclass_fields__
    return TrainConfig(**{k: v for k, v in vars(args).items() if k in fields and v is not None})


def main_args(args) -> int:
    cfg = config_from_args(args)
    result = train(cfg, Path(args.out), resume=args.resume, state_dir=Path(args.state_dir),
                   init=Path(args.init) if args.init else None)
    print(json.dumps(result))
    return 0
