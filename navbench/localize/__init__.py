"""Map-free object localisation: retrieve keyframes, re-rank them with a VLM, segment, backproject,
group into instances and fuse each instance across views (the "memory over maps" pipeline).

Perception backends live in :mod:`navbench.localize.backends` (real models and the oracle); the
GOAT-style benchmark in :mod:`navbench.localize.goat` (split) and :mod:`navbench.localize.benchmark`
(``run_localize``), which are not imported here because they load the renderer.
"""

from navbench.localize.fusion import (
    FusionConfig,
    GoalCandidate,
    confirm_views,
    fuse,
    largest_cluster,
    neighbour_keyframes,
)
from navbench.localize.geometry import (
    GeometryConfig,
    backproject,
    keep_view,
    median_masked_depth,
    project,
    world_to_camera,
)
from navbench.localize.grouping import Cluster, GroupingConfig, ViewCloud, group_views, overlap_fraction
from navbench.localize.pipeline import (
    QUERY_TYPES,
    LocalizationTrace,
    LocalizeError,
    Localizer,
    LocalizerConfig,
    Perception,
    Query,
)
from navbench.localize.vlm import PROMPT_TEMPLATE, ScoredView, format_prompt, parse_reply, rerank

__all__ = [
    "PROMPT_TEMPLATE",
    "QUERY_TYPES",
    "Cluster",
    "FusionConfig",
    "GeometryConfig",
    "GoalCandidate",
    "GroupingConfig",
    "LocalizationTrace",
    "LocalizeError",
    "Localizer",
    "LocalizerConfig",
    "Perception",
    "Query",
    "ScoredView",
    "ViewCloud",
    "backproject",
    "confirm_views",
    "format_prompt",
    "fuse",
    "group_views",
    "keep_view",
    "largest_cluster",
    "median_masked_depth",
    "neighbour_keyframes",
    "overlap_fraction",
    "parse_reply",
    "project",
    "rerank",
    "world_to_camera",
]
