"""Memory over maps: the scene as a bank of posed RGB-D keyframes plus an embedding index over them."""

from navbench.memory.index import EmbeddingIndex, EmbeddingIndexError, l2_normalize
from navbench.memory.keyframes import KeyframeSelector, PoseError, rotation_angle_deg, select_keyframes
from navbench.memory.prescan import (
    Memory,
    MemoryStats,
    PrescanConfig,
    PrescanError,
    Trajectory,
    build_memory,
    load_or_build_memory,
    plan_trajectory,
)
from navbench.memory.store import (
    Frame,
    Intrinsics,
    KeyframeRecord,
    KeyframeStore,
    StoreConfig,
    StoreError,
    StoreStats,
)

__all__ = [
    "EmbeddingIndex",
    "EmbeddingIndexError",
    "Frame",
    "Intrinsics",
    "KeyframeRecord",
    "KeyframeSelector",
    "KeyframeStore",
    "Memory",
    "MemoryStats",
    "PoseError",
    "PrescanConfig",
    "PrescanError",
    "StoreConfig",
    "StoreError",
    "StoreStats",
    "Trajectory",
    "build_memory",
    "l2_normalize",
    "load_or_build_memory",
    "plan_trajectory",
    "rotation_angle_deg",
    "select_keyframes",
]
