"""The three PointNav trainers' configurations, one frozen dataclass each, light enough to import for the CLI.

Every field is one ``navbench train encoder|dagger|ppo`` option (``--iterations 14`` sets ``iterations``) and one
key of a recipe stage (``configs/pointnav/*.toml``); its ``help`` metadata is the option's help line.

    navbench train dagger --help
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


def option(default: Any, help: str, choices: tuple[str, ...] | None = None) -> Any:
    """A config field with its one-line help (and, for a text option, its valid values)."""
    return field(default=default, metadata={"help": help, "choices": choices})


TRAIN_SPLITS = ("train", "train_large")
SPLIT_HELP = "PointNav split to roll out in: train (8 houses) or train_large (those plus 40 more)"


@dataclass(frozen=True)
class PretrainConfig:
    """``navbench train encoder``: the depth encoder's geometry pre-training (navbench.policy.pretrain)."""

    frames_per_scene: int = option(6_000, "frames rendered per bundled train house")
    heldout_frames: int = option(1_500, "frames held out of training to report the held-out loss")
    updates: int = option(2_500, "gradient updates")
    batch_size: int = option(64, "frames per update")
    lr: float = option(1e-3, "peak learning rate (AdamW, warm-up then cosine)")
    min_lr: float = option(1e-5, "the cosine schedule's last rate")
    warmup: int = option(100, "updates of linear warm-up")
    weight_decay: float = option(1e-4, "AdamW weight decay")
    patch_weight: float = option(1.0, "weight of the top-down navigability patch loss against the free-space rays")
    ray_headings_deg: tuple[float, ...] = option(tuple(float(a) for a in range(-36, 37, 6)),
                                                 "headings (degrees) of the free-space rays")
    ray_range: float = option(4.0, "metres at which a free-space ray is capped")
    patch_cells: int = option(16, "cells per side of the navigability patch")
    patch_cell_size: float = option(0.25, "metres per patch cell")
    log_every: int = option(100, "updates between log rows (each also scores the held-out frames)")
    save_every: int = option(250, "updates between checkpoints")
    seed: int = option(0, "seed of the rendered poses and of the updates")
    threads: int = option(2, "torch threads")
    bf16: bool = option(False, "bfloat16 autocast in the updates (faster only where the CPU has AVX512-BF16 or AMX)")


@dataclass(frozen=True)
class TrainConfig:
    """``navbench train dagger``: DAgger imitation of the geodesic expert (navbench.policy.train)."""

    train_split: str = option("train", SPLIT_HELP, TRAIN_SPLITS)
    iterations: int = option(14, "collect-then-train iterations")
    frames_per_iteration: int = option(6_000, "frames collected per iteration")
    num_envs: int = option(8, "envs stepped side by side")
    beta0: float = option(1.0, "expert share of the executed actions in the first iteration")
    beta_decay: float = option(0.7, "factor on the expert share after every iteration")
    beta_min: float = option(0.1, "floor of the expert share")
    random_action_prob: float = option(0.08, "share of random non-STOP actions, so the data covers recoveries")
    max_episode_steps: int = option(250, "steps after which a rollout episode is cut")
    buffer_frames: int = option(250_000, "aggregated buffer cap in frames, oldest episodes dropped first")
    batch_episodes: int = option(16, "whole episodes per update")
    epochs_per_iteration: float = option(16.0, "gradient steps = this x new frames / frames per update")
    lr: float = option(5e-4, "learning rate (Adam)")
    lr_schedule: str = option("constant", "learning rate over the iterations: constant, or cosine or linear from "
                              "--lr to --lr-min", ("constant", "cosine", "linear"))
    lr_min: float = option(1e-5, "the cosine or linear schedule's last rate")
    weight_decay: float = option(0.0, "Adam's L2 weight decay")
    inflection_weight: float = option(3.0, "loss weight of steps where the expert changes its action")
    collision_weight: float = option(1.0, "loss weight of steps right after a refused FORWARD")
    endgame_weight: float = option(1.0, "loss weight of steps within --endgame-radius of the goal")
    endgame_radius: float = option(0.75, "metres from the goal within which --endgame-weight applies")
    expert_margin: float = option(0.15, "extra clearance (m) the expert keeps from obstacles where it can")
    expert_success_distance: float = option(0.2, "distance (m) to the goal at which the expert says STOP")
    grad_clip: float = option(1.0, "gradient norm clip")
    monitor_episodes: int = option(16, "bundled `select` episodes scored after every iteration (0: none)")
    monitor_max_steps: int = option(250, "step limit of a monitor episode")
    tight_starts: float = option(0.0, "probability that a rollout episode starts beside an obstacle")
    seed: int = option(0, "seed of the rollouts and the updates")
    threads: int = option(2, "torch threads (split between the workers)")
    workers: int = option(1, "rollout processes sharing the envs (results depend on it, not on timing)")
    preempt_fraction: float = option(0.6, "distributed runs: a rank ends its rollout early once this share of the "
                                     "ranks finished theirs (1: never)")
    preempt_min_share: float = option(0.25, "distributed runs: the share of its rollout a rank collects before it "
                                      "may end early")
    bf16: bool = option(False, "bfloat16 autocast in the updates (faster only where the CPU has AVX512-BF16 or AMX)")
    act_bf16: bool = option(False, "bfloat16 autocast for the acting policy's encoder in rollouts")


@dataclass(frozen=True)
class PPOConfig:
    """``navbench train ppo``: PPO fine-tuning on habitat-lab's PointNav reward (navbench.policy.ppo)."""

    train_split: str = option("train_large", SPLIT_HELP, TRAIN_SPLITS)
    num_envs: int = option(8, "envs stepped side by side")
    rollout_steps: int = option(128, "steps per env and update")
    updates: int = option(300, "PPO updates (rollouts)")
    lr: float = option(2.5e-5, "the actor's learning rate (Adam)")
    critic_lr: float = option(1e-3, "the value head's learning rate")
    lr_schedule: str = option("constant", "both learning rates over the updates: constant, or linear down to 0 at "
                              "the last update (habitat-baselines' linear decay)", ("constant", "linear"))
    gamma: float = option(0.99, "discount")
    gae_lambda: float = option(0.95, "GAE lambda")
    clip: float = option(0.2, "PPO ratio clip")
    ppo_epochs: int = option(2, "epochs over each rollout")
    num_minibatches: int = option(2, "groups of envs per epoch")
    value_coef: float = option(0.5, "value loss weight")
    entropy_coef: float = option(1e-3, "entropy bonus")
    max_grad_norm: float = option(0.2, "gradient norm clip")
    critic_warmup: int = option(30, "first updates that train only the value head")
    slack_reward: float = option(-0.01, "reward per step")
    success_reward: float = option(2.5, "reward of a successful STOP")
    terminal_reward: str = option("flat", "the successful STOP's reward: flat --success-reward, or --success-reward "
                                  "x the episode's SPL (a long path earns less)", ("flat", "spl"))
    bc_weight: float = option(0.0, "weight of a cross-entropy term to the geodesic expert's actions (0: off)")
    tight_starts: float = option(0.0, "probability that a rollout episode starts beside an obstacle")
    act_bf16: bool = option(False, "bfloat16 autocast for the acting policy's encoder in rollouts")
    expert_success_distance: float = option(0.1, "distance (m) to the goal at which the --bc-weight expert says STOP")
    expert_margin: float = option(0.15, "extra clearance (m) the --bc-weight expert keeps from obstacles")
    seed: int = option(0, "seed of the rollouts and the updates")
    threads: int = option(2, "torch threads (split between the workers)")
    workers: int = option(1, "rollout processes sharing the envs (results depend on it, not on timing)")
    save_every: int = option(5, "updates between checkpoints")
    preempt_fraction: float = option(0.6, "distributed runs: a rank ends its rollout early once this share of the "
                                     "ranks finished theirs (1: never)")
    preempt_min_share: float = option(0.25, "distributed runs: the share of its rollout a rank collects before it "
                                      "may end early")


CONFIGS = {"encoder": PretrainConfig, "dagger": TrainConfig, "ppo": PPOConfig}
