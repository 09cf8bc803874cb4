"""The DD-PPO PointNav policy (habitat-baselines ``PointNavResNetPolicy`` layout) and its checkpoints.

The names below load on first use, so importing a submodule that needs no torch (the training
configs the CLI's parser is built from) does not import torch.
"""

from importlib import import_module
from typing import Any

_HOME = {
    "CheckpointData": "checkpoint", "CheckpointError": "checkpoint", "infer_net_config": "checkpoint",
    "load_checkpoint": "checkpoint", "read_checkpoint": "checkpoint", "save_checkpoint": "checkpoint",
    "POINTNAV_ACTIONS": "net", "InferenceConfig": "net", "PointNavAgentPolicy": "net",
    "PointNavResNetPolicy": "net", "PolicyNetConfig": "net", "prepare_depth": "net",
    "measure_policy_speed": "speed",
}
__all__ = sorted(_HOME)


def __getattr__(name: str) -> Any:
    if name not in _HOME:
        raise AttributeError(f"module 'navbench.policy' has no attribute {name!r}")
    return getattr(import_module(f"navbench.policy.{_HOME[name]}"), name)
