"""The DD-PPO PointNav policy (habitat-baselines ``PointNavResNetPolicy`` layout) and its checkpoints."""

from navbench.policy.checkpoint import (
    CheckpointData,
    CheckpointError,
    infer_net_config,
    load_checkpoint,
    read_checkpoint,
    save_checkpoint,
)
from navbench.policy.net import (
    POINTNAV_ACTIONS,
    InferenceConfig,
    PointNavAgentPolicy,
    PointNavResNetPolicy,
    PolicyNetConfig,
    prepare_depth,
)
from navbench.policy.speed import measure_policy_speed

__all__ = [
    "POINTNAV_ACTIONS",
    "CheckpointData",
    "CheckpointError",
    "InferenceConfig",
    "PointNavAgentPolicy",
    "PointNavResNetPolicy",
    "PolicyNetConfig",
    "infer_net_config",
    "load_checkpoint",
    "measure_policy_speed",
    "prepare_depth",
    "read_checkpoint",
    "save_checkpoint",
]
