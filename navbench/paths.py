"""Where the bundled data lives: ``envs/`` (scenes), ``episodes/``, ``policies/`` and ``configs/`` (training
recipes).

In a checkout (and an editable install) they are the top-level directories beside the package. An installed
wheel carries them as package data, ``navbench/_data/``, found through :mod:`importlib.resources`.
``NAVBENCH_DATA`` overrides the root (a directory holding ``envs/``, ``episodes/``, ``policies/``,
``configs/``); ``NAVBENCH_CACHE`` moves the cache (navigability grids and layered surfaces, keyframe memories; default
~/.cache/navbench).

    python -c "from navbench.paths import ROOT; print(ROOT)"
"""

from __future__ import annotations

import os
from importlib.resources import files
from pathlib import Path

DATA_DIRS = ("configs", "envs", "episodes", "policies")  # what a wheel carries as navbench/_data/
CHECKOUT = Path(__file__).resolve().parents[1]


def data_root() -> Path:
    """``NAVBENCH_DATA``, else the installed package data, else the checkout the package was imported from."""
    if os.environ.get("NAVBENCH_DATA"):
        return Path(os.environ["NAVBENCH_DATA"])
    packaged = Path(str(files("navbench").joinpath("_data")))
    return packaged if packaged.is_dir() else CHECKOUT


ROOT = data_root()
SCENES_DIR = ROOT / "envs"
EPISODES_DIR = ROOT / "episodes"
POLICIES_DIR = ROOT / "policies"
CONFIGS_DIR = ROOT / "configs"
RESULTS_DIR = ROOT / "results"  # the reference runs and tables: in a checkout only


def cache_dir(*parts: str) -> Path:
    base = Path(os.environ.get("NAVBENCH_CACHE", Path.home() / ".cache" / "navbench"))
    d = base.joinpath(*parts)
    d.mkdir(parents=True, exist_ok=True)
    return d


def split_file(task: str, split: str) -> Path:
    """Bundled split file, Habitat's layout: ``episodes/{task}/{split}/{split}.json.gz``."""
    return EPISODES_DIR / task / split / f"{split}.json.gz"
