"""Stand-ins for habitat-lab's test data, so that habitat-lab's own ``test/`` runs on navbench's habitat_sim::

    navbench generate habitat-test-data DIR     # then run habitat-lab's tests with DIR as the working directory

habitat-lab's tests read the habitat test scenes and the test PointNav dataset by paths relative to the working
directory: ``data/scene_datasets/habitat-test-scenes/{skokloster-castle,van-gogh-room,apartment_1}.glb`` and
``data/datasets/pointnav/habitat-test-scenes/v1/{split}/{split}.json.gz`` (habitat-lab's
``habitat/config/habitat/dataset/pointnav/habitat_test.yaml`` and ``default_structured_configs.py``'s
``SimulatorConfig.scene``), data habitat-lab's repository does not hold. Each scene is one of navbench's bundled val
houses copied under the test scene's file name with its ``.semantic.json`` sidecar; the episodes are drawn on them
by navbench's seeded PointNav generator (:func:`navbench.episodes.generate.pointnav_episodes`) for the agent body of
habitat-lab's PointNav test config (radius 0.1 m, height 1.5 m, climb 0.2 m), and written in habitat-lab's
PointNav-v1 format (``habitat/datasets/pointnav/pointnav_dataset.py``) with the scene path habitat-lab's test files
hold (``data/scene_datasets/habitat-test-scenes/<name>.glb``). Like habitat's test dataset, the episodes lie in two
scenes.

habitat-lab's ObjectNav tests (``test/config/habitat/habitat_mp3d_object_nav_test.yaml``) read
``data/datasets/objectnav/mp3d/v1/{split}/{split}.json.gz`` with scenes under ``data/scene_datasets/``: ``train`` and
``val`` stand-ins hold ObjectNav-v1 episodes from navbench's ObjectNav generator
(:func:`navbench.episodes.generate.objectnav_split`, whose default body is that config's: radius 0.18 m, height
0.88 m) in three bundled houses each (train houses for ``train``, val houses for ``val``), copied to
``data/scene_datasets/mp3d/<house>/<house>.glb``, over the MP3D ObjectNav categories the houses have.

The houses are not Habitat's scenes: positions and numbers that habitat-lab's tests take from those scenes do not
hold on them.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from navbench.episodes.generate import SceneGoals, objectnav_split, pointnav_episodes
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


OBJECTNAV_SUBDIR = "data/datasets/objectnav/mp3d/v1"
# The bundled houses standing in for MP3D scenes in each ObjectNav split.
OBJECTNAV_STAND_INS = {
    "train": ("houses/train/house_000.glb", "houses/train/house_001.glb", "houses/train/house_002.glb"),
    "val": ("houses/val/house_008.glb", "houses/val/house_009.glb", "houses/val/house_010.glb"),
}
OBJECTNAV_EPISODES_PER_SCENE = 5
# MP3D's 21 ObjectNav categories (habitat-lab's objectnav_mp3d dataset); a split uses those its houses have.
MP3D_CATEGORIES = ("chair", "table", "picture", "cabinet", "cushion", "sofa", "bed", "chest_of_drawers", "plant",
                   "sink", "toilet", "stool", "towel", "tv_monitor", "shower", "bathtub", "counter", "fireplace",
                   "gym_equipment", "seating", "clothes")


def scene_path(out: Path, name: str) -> Path:
    return out / SCENES_SUBDIR / f"{name}.glb"


def split_path(out: Path, split: str) -> Path:
    return out / POINTNAV_SUBDIR / split / f"{split}.json.gz"


def mp3d_scene_path(out: Path, rel: str) -> Path:
    """Where the bundled house ``rel`` stands in for an MP3D scene: ``data/scene_datasets/mp3d/<house>/<house>.glb``."""
    stem = Path(rel).stem
    return out / "data/scene_datasets/mp3d" / stem / f"{stem}.glb"


def objectnav_split_path(out: Path, split: str) -> Path:
    return out / OBJECTNAV_SUBDIR / split / f"{split}.json.gz"


def written_files(out: Path) -> list[Path]:
    """Every file :func:`write_habitat_test_data` writes under ``out``."""
    files = []
    for name in STAND_INS:
        files += [scene_path(out, name), semantic_path(scene_path(out, name))]
    for rels in OBJECTNAV_STAND_INS.values():
        files += [f for rel in rels for f in (mp3d_scene_path(out, rel), semantic_path(mp3d_scene_path(out, rel)))]
    return (files + [split_path(out, split) for split in EPISODES_PER_SCENE]
            + [objectnav_split_path(out, split) for split in OBJECTNAV_STAND_INS])


def _copy_scene(src: Path, dst: Path) -> None:
    if not src.is_file():
        raise FileNotFoundError(f"{src}: bundled scene not found (run `navbench generate scenes`)")
    dst.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(src, dst)
    shutil.copyfile(semantic_path(src), semantic_path(dst))


def write_habitat_test_data(out: Path, scene_dir: Path = SCENES_DIR, seed: int = 0, overwrite: bool = False,
                            episodes_per_scene: dict[str, int] = EPISODES_PER_SCENE,
                            objectnav_per_scene: int = OBJECTNAV_EPISODES_PER_SCENE, log=print) -> dict[str, int]:
    """Write the stand-in scenes, PointNav splits and ObjectNav splits under ``out``; returns the episodes in each
    split (``pointnav/<split>``, ``objectnav/<split>``).

    Refuses (ValueError) a ``out`` that exists and holds anything, unless ``overwrite`` (then only the files
    listed by :func:`written_files` are replaced)."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: not a directory")
    if out.is_dir() and any(out.iterdir()) and not overwrite:
        raise ValueError(f"{out}: directory exists and is not empty (pass --overwrite to replace the stand-ins in it)")
    for name, rel in STAND_INS.items():
        _copy_scene(scene_dir / rel, scene_path(out, name))
    for rels in OBJECTNAV_STAND_INS.values():
        for rel in rels:
            _copy_scene(scene_dir / rel, mp3d_scene_path(out, rel))
    counts = write_pointnav_splits(out, seed, episodes_per_scene, log)
    counts.update(write_objectnav_splits(out, seed, objectnav_per_scene, log))
    return counts


def write_pointnav_splits(out: Path, seed: int = 0, episodes_per_scene: dict[str, int] = EPISODES_PER_SCENE,
                          log=print) -> dict[str, int]:
    """The PointNav-v1 test splits on the stand-in test scenes already under ``out``; split ``k`` draws from the
    stream ``[seed, k]`` (ObjectNav's splits from the streams after these)."""
    counts = {}
    for k, (split, per_scene) in enumerate(episodes_per_scene.items()):
        rng = np.random.default_rng([seed, k])
        episodes = []
        for name in POINTNAV_SCENES:
            # scene ids relative to ``out``: data/scene_datasets/habitat-test-scenes/<name>.glb
            episodes += pointnav_episodes(scene_path(out, name), out, per_scene, rng, id_offset=len(episodes),
                                          grid_config=TEST_AGENT)
        save_dataset(EpisodeDataset(episodes=episodes), split_path(out, split))
        counts[f"pointnav/{split}"] = len(episodes)
        log(f"{split_path(out, split)}: {len(episodes)} episodes")
    return counts


def write_objectnav_splits(out: Path, seed: int = 0, per_scene: int = OBJECTNAV_EPISODES_PER_SCENE,
                           log=print) -> dict[str, int]:
    """The ObjectNav-v1 ``train`` and ``val`` stand-ins on the MP3D-path houses already under ``out``, from the
    streams ``[seed, 3]`` and ``[seed, 4]``. (A stream's seed list must differ by more than trailing zeros:
    numpy's SeedSequence gives ``[s, 1, 0]`` the stream of ``[s, 1]``.)"""
    counts = {}
    for k, (split, rels) in enumerate(OBJECTNAV_STAND_INS.items()):
        rng = np.random.default_rng([seed, len(EPISODES_PER_SCENE) + k])
        scenes = [(SceneGoals(mp3d_scene_path(out, rel), out), per_scene) for rel in rels]
        ds = objectnav_split(scenes, MP3D_CATEGORIES, False, rng, split, f"objectnav/{split}: scenes")
        ds.extra.pop("split_version", None)  # navbench's bundled-split version: not one of these files
        save_dataset(ds, objectnav_split_path(out, split))
        counts[f"objectnav/{split}"] = len(ds.episodes)
        log(f"{objectnav_split_path(out, split)}: {len(ds.episodes)} episodes")
    return counts
