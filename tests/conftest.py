"""Shared fixtures: a bundled scene and small episode files made from it on the fly."""

from pathlib import Path

import numpy as np
import pytest

from navbench.paths import SCENES_DIR

SMOKE_SCENE = SCENES_DIR / "houses" / "val" / "house_008.glb"


@pytest.fixture(scope="session")
def scene_path() -> Path:
    if not SMOKE_SCENE.is_file():
        pytest.fail(f"{SMOKE_SCENE} missing: run `navbench generate scenes`")
    return SMOKE_SCENE


@pytest.fixture(scope="session")
def pointnav_file(tmp_path_factory, scene_path) -> Path:
    """Six short PointNav episodes (1-6 m) in the smoke scene."""
    from navbench.episodes.generate import GeneratorConfig, pointnav_episodes
    from navbench.episodes.io import save_dataset
    from navbench.episodes.types import EpisodeDataset

    eps = pointnav_episodes(scene_path, SCENES_DIR, 6, np.random.default_rng(7),
                            GeneratorConfig(min_geodesic=1.0, max_geodesic=6.0))
    return save_dataset(EpisodeDataset(episodes=eps), tmp_path_factory.mktemp("pn") / "smoke.json.gz")


@pytest.fixture(scope="session")
def objectnav_file(tmp_path_factory, scene_path) -> Path:
    """Six short ObjectNav episodes in the smoke scene, over the categories it has."""
    from navbench.episodes.generate import GeneratorConfig, SceneGoals, objectnav_episodes
    from navbench.episodes.io import save_dataset
    from navbench.episodes.types import EpisodeDataset

    sg = SceneGoals(scene_path, SCENES_DIR)
    cats = sg.available(("chair", "table", "bed", "sofa", "plant", "toilet"))[:3]
    eps, table = objectnav_episodes(sg, cats, 6, np.random.default_rng(7),
                                    cfg=GeneratorConfig(min_geodesic=1.0, max_geodesic=6.0))
    ds = EpisodeDataset(episodes=eps, goals_by_category=table,
                        category_to_task_category_id={c: i for i, c in enumerate(sorted(cats))})
    return save_dataset(ds, tmp_path_factory.mktemp("on") / "smoke.json.gz")
