"""Stand-ins for habitat-lab's test data, so that habitat-lab's own ``test/`` runs on navbench's habitat_sim::

    navbench generate habitat-test-data DIR     # then run habitat-lab's tests with DIR as the working directory

habitat-lab's tests read the habitat test scenes and the test PointNav dataset by paths relative to the working
directory: ``data/scene_datasets/habitat-test-scenes/{skokloster-castle,van-gogh-room,apartment_1}.glb`` and
``data/datasets/pointnav/habitat-test-scenes/v1/{split}/{split}.json.gz`` (habitat-lab's
``habitat/config/habitat/dataset/pointnav/habitat_test.yaml`` and ``default_structured_configs.py``'s
``SimulatorConfig.scene``). Neither can be downloaded here. Each scene is one of navbench's bundled val houses
copied under the test scene's file name with its ``.semantic.json`` sidecar; the episodes are drawn on them by
navbench's seeded PointNav generator (:func:`navbench.episodes.generate.pointnav_episodes`) for the agent body
of habitat-lab's PointNav test config (radius 0.1 m, height 1.5 m, climb 0.2 m), and written in habitat-lab's
PointNav-v1 format (``habitat/datasets/pointnav/pointnav_dataset.py``) with the scene path habitat-lab's test
files hold (``data/scene_datasets/habitat-test-scenes/<name>.glb``). Like habitat's test dataset, the episodes
lie in two scenes. The houses are not Habitat's scenes: positions and numbers that habitat-lab's tests take from
those scenes do not hold on them.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from navbench.episodes.generate import pointnav_episodes
from navbench.episodes.io import save_dataset
from navbench.episodes.types import EpisodeDataset
from navbench.paths import SCENES_DIR
from navbench.scene.asset import semantic_path
from navbench.scene.navigability import NavGridConfig

SCENES_SUBDIR = "data/scene_datasets/habitat-test-scenes"
POINTNAV_SUBDIR = "data/datasets/pointnav/habitat-test-scenes/v1"

# habitat-lab's test scene -> the bundled navbench house standing in for it (relative to the scenes dir).
STAND_INS = {
    "skokloster-castle": "houses/val/house_008.glb",
    "van-gogh-room": "houses/val/house_009.glb",
    "apartment_1": "houses/val/house_010.glb",
}
# The scenes the PointNav test dataset's episodes lie in (habitat-lab's test_pointnav_dataset expects two).
POINTNAV_SCENES = ("skokloster-castle", "van-gogh-room")
# Episodes per scene in each split; each split draws from a generator stream of its own.
EPISODES_PER_SCENE = {"train": 50, "val": 25, "test": 25}
# habitat-lab's default agent (``AgentConfig``: radius 0.1, height 1.5, max_climb 0.2) on habitat-sim's default
# navmesh cell size (``NavMeshSettings.cell_size`` 0.05): what the simulator's path finder measures on.
TEST_AGENT = NavGridConfig(agent_radius=0.1, agent_height=1.5, max_climb=0.2, cell_size=0.05)


def scene_path(out: Path, name: str) -> Path:
    return out / SCENES_SUBDIR / f"{name}.glb"


def split_path(out: Path, split: str) -> Path:
    return out / POINTNAV_SUBDIR / split / f"{split}.json.gz"


def written_files(out: Path) -> list[Path]:
    """Every file :func:`write_habitat_test_data` writes under ``out``."""
    files = []
    for name in STAND_INS:
        files += [scene_path(out, name), semantic_path(scene_path(out, name))]
    return files + [split_path(out, split) for split in EPISODES_PER_SCENE]


def write_habitat_test_data(out: Path, scene_dir: Path = SCENES_DIR, seed: int = 0, overwrite: bool = False,
                            episodes_per_scene: dict[str, int] = EPISODES_PER_SCENE, log=print) -> dict[str, int]:
    """Write the stand-in scenes and PointNav splits under ``out``; returns the episodes in each split.

    Refuses (ValueError) a ``out`` that exists and holds anything, unless ``overwrite`` (then only the files
    listed by :func:`written_files` are replaced)."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: not a directory")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise ValueError(f"{out}: directory exists and is not empty (pass --overwrite to replace the stand-ins in it)")
    for name, rel in STAND_INS.items():
        src = scene_dir / rel
        if not src.is_file():
            raise FileNotFoundError(f"{src}: bundled scene not found (run `navbench generate scenes`)")
        dst = scene_path(out, name)
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(src, dst)
        shutil.copyfile(semantic_path(src), semantic_path(dst))
    counts = {}
    for k, (split, per_scene) in enumerate(episodes_per_scene.items()):
        rng = np.random.default_rng([seed, k])
        episodes = []
        for name in POINTNAV_SCENES:
            # scene ids relative to ``out``: data/scene_datasets/habitat-test-scenes/<name>.glb
            episodes += pointnav_episodes(scene_path(out, name), out, per_scene, rng, id_offset=len(episodes),
                                          grid_config=TEST_AGENT)
        save_dataset(EpisodeDataset(episodes=episodes), split_path(out, split))
        counts[split] = len(episodes)
        log(f"{split_path(out, split)}: {len(episodes)} episodes")
    return counts
