"""Where the bundled data lives: ``envs/`` (scenes), ``episodes/``, ``policies/`` beside the package.

``NAVBENCH_DATA`` overrides the root (for a non-editable install, point it at a checkout);
``NAVBENCH_CACHE`` moves the cache (navigability grids, keyframe memories; default ~/.cache/navbench).
"""

from __future__ import annotations

import os
from pathlib import Path

ROOT = Path(os.environ.get("NAVBENCH_DATA", Path(__file__).resolve().parents[1]))
SCENES_DIR = ROOT / "envs"
EPISODES_DIR = ROOT / "episodes"
POLICIES_DIR = ROOT / "policies"
RESULTS_DIR = ROOT / "results"


def cache_dir(*parts: str) -> Path:
    base = Path(os.environ.get("NAVBENCH_CACHE", Path.home() / ".cache" / "navbench"))
    d = base.joinpath(*parts)
    d.mkdir(parents=True, exist_ok=True)
    return d


def split_file(task: str, split: str) -> Path:
    """Bundled split file, Habitat's layout: ``episodes/{task}/{split}/{split}.json.gz``."""
    return EPISODES_DIR / task / split / f"{split}.json.gz"
