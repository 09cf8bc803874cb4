"""Goal grounding of the memory/frontier agents' oracle perception does not depend on where the scene
file lies: a Ray actor runs on a copy of the bundled houses (``$NAVBENCH_CACHE/ray/DIGEST/scenes``), and
must ground a goal name as a local worker reading ``envs/`` does, or it localises other candidates."""

import shutil

import numpy as np

from navbench.agents.perceive import _teach_goals, is_bundled
from navbench.episodes.types import Episode, ObjectGoal
from navbench.localize.backends.oracle import noise_profile
from navbench.localize.benchmark import ModelDirs, oracle_perception
from navbench.paths import SCENES_DIR
from navbench.scene.asset import load_scene

SCENE = "houses/val/house_010.glb"  # three pictures (ids 19, 23, 28)


def _copy(tmp_path, scene_id=SCENE):
    dest = tmp_path / "scenes" / scene_id
    dest.parent.mkdir(parents=True)
    src = SCENES_DIR / scene_id
    for f in src.parent.glob(src.name.split(".")[0] + ".*"):
        shutil.copy2(f, dest.parent / f.name)
    return dest


def _grounding(path, episode):
    """What the oracle stack of the scene at ``path`` makes of the episode's goal name once taught."""
    stack = oracle_perception(load_scene(path), noise_profile("none"), ModelDirs())  # not the process's shared one
    _teach_goals(stack, episode, path)
    name = episode.object_category
    return (stack.encoder.encode_text([name]), stack.reranker._grounding.targets(name),
            stack.segmenter._grounding.targets(name))


def test_a_copy_of_a_bundled_house_grounds_goal_names_as_the_original(tmp_path):
    # Two of the house's three pictures are the episode's goals (as in val_unseen episode 84, whose
    # third picture no navigable view point reaches): the vocabulary still grounds all three.
    goals = [ObjectGoal([0.125275, 1.31769, 5.345315], 19, "picture"),
             ObjectGoal([0.972335, 1.45275, 5.825785], 23, "picture")]
    episode = Episode("84", SCENE, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], goals=goals, object_category="picture")
    copy = _copy(tmp_path)
    assert is_bundled(SCENES_DIR / SCENE, SCENE) and is_bundled(copy, SCENE)
    original, copied = _grounding(SCENES_DIR / SCENE, episode), _grounding(copy, episode)
    assert original[1].tolist() == [19, 23, 28]
    for a, b in zip(original, copied):
        np.testing.assert_array_equal(a, b)


def test_a_changed_copy_is_not_a_bundled_house(tmp_path):
    copy = _copy(tmp_path)
    assert is_bundled(copy, SCENE)
    sidecar = copy.with_name("house_010.semantic.json")
    sidecar.write_text(sidecar.read_text() + " ")
    assert not is_bundled(copy, SCENE)
    assert not is_bundled(copy, str(copy))  # an absolute scene id names no bundled house
