"""``Simulator.semantic_scene`` in habitat-sim's order and ids (``SemanticScene::buildHM3DHouse`` and
``buildMp3dHouse``) on the HM3D and MP3D layouts of tests/scene/scanfix.py, and on navbench's own scenes; the
SEMANTIC sensor draws the ids it lists.

Needs numpy-quaternion (habitat-sim's rotation type): installed with the ``habitat`` extra."""

import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("quaternion", reason="numpy-quaternion (the habitat extra) is not installed")

import navbench.habitat_sim as hs  # noqa: E402
from navbench.habitat_sim.utils.common import quat_from_angle_axis  # noqa: E402

sys.path.insert(0, str(Path(__file__).parents[1] / "scene"))
import scanfix as F  # noqa: E402


def _sim(scene):
    sim_cfg = hs.SimulatorConfiguration()
    sim_cfg.scene_id = str(scene)
    agent = hs.AgentConfiguration()
    spec = hs.CameraSensorSpec()
    spec.uuid, spec.sensor_type, spec.resolution = "semantic", hs.SensorType.SEMANTIC, [48, 64]
    spec.position = [0.0, 1.0, 0.0]
    agent.sensor_specifications = [spec]
    return hs.Simulator(hs.Configuration(sim_cfg, [agent]))


def _ids_towards_the_wall(sim):
    """The SEMANTIC image from the room's centre facing the wall (the tv on it, the armchair before it)."""
    state = sim.get_agent(0).get_state()
    state.position, state.rotation = np.zeros(3, np.float32), quat_from_angle_axis(0.0, [0, 1, 0])
    sim.get_agent(0).set_state(state)
    return sim.get_sensor_observations()["semantic"]


def _box_is(aabb, lo_hi):
    return np.allclose(np.concatenate([np.asarray(aabb.min), np.asarray(aabb.max)]), lo_hi, atol=1e-5)


def test_hm3d_semantic_scene_is_habitat_sims(tmp_path):
    with _sim(F.write_hm3d_scene(tmp_path / "scene_datasets" / "hm3d")) as sim:
        sem = sim.semantic_scene
        ids = _ids_towards_the_wall(sim)
    # object 0 "Unknown", then every semantic.txt row by instance id, named "{raw name}_{id}"
    assert [o.id for o in sem.objects] == ["Unknown_0", "floor_1", "wall_2", "armchair_3", "tv_4"]
    assert [o.semantic_id for o in sem.objects] == [0, 1, 2, 3, 4]
    assert [(c.index(), c.name()) for c in sem.categories] == [
        (0, "Unknown"), (1, "floor"), (2, "wall"), (3, "armchair"), (4, "tv")]
    assert sem.objects[3].category is sem.categories[3]
    # regions are the region ids, -1 (object 0's) first, with no level and no category
    assert [r.id for r in sem.regions] == ["_-1", "_0", "_1"] and sem.levels == []
    assert [o.semantic_id for o in sem.regions[1].objects] == [1, 2, 3] and sem.objects[4].region is sem.regions[2]
    assert sem.regions[1].category is None
    assert _box_is(sem.objects[3].aabb, [0.5, 0.0, -1.5, 1.0, 0.9, -1.0])
    assert np.allclose(np.asarray(sem.objects[3].obb.center), [0.75, 0.45, -1.25])
    # the sensor draws every listed object (the wall and the floor too), each an index into objects
    assert {1, 2, 3, 4} <= set(np.unique(ids).tolist()) <= {0, 1, 2, 3, 4}
    for k in np.unique(ids[ids > 0]):
        assert sem.objects[k].semantic_id == k and sem.objects[k].id.endswith(f"_{k}")


def test_hm3d_id_missing_from_semantic_txt_keeps_objects_indexed_by_id(tmp_path):
    mesh = F.write_hm3d_scene(tmp_path / "scene_datasets" / "hm3d")
    txt = mesh.parent / "abcDEFghiJK.semantic.txt"
    txt.write_text("".join(line for line in txt.read_text().splitlines(True) if not line.startswith("2,")))
    with _sim(mesh) as sim:
        sem = sim.semantic_scene
        ids = _ids_towards_the_wall(sim)
    # habitat-sim would list 4 objects with tv_4 at index 3; habitat-lab's ObjectNav looks goals up by index
    assert [o.id for o in sem.objects] == ["Unknown_0", "floor_1", "Unknown_2", "armchair_3", "tv_4"]
    assert 2 not in ids and {1, 3, 4} <= set(np.unique(ids).tolist())  # the wall's colour is no longer listed


def test_mp3d_semantic_scene_is_habitat_sims(tmp_path):
    with _sim(F.write_mp3d_scene(tmp_path / "scene_datasets" / "mp3d")) as sim:
        sem = sim.semantic_scene
        ids = _ids_towards_the_wall(sim)
    # objects in .house order, id "{level}_{region}_{index}"
    assert [o.id for o in sem.objects] == ["0_0_0", "0_0_1", "0_1_2"]
    assert [o.semantic_id for o in sem.objects] == [0, 1, 2]
    chair = sem.objects[1].category
    assert (chair.index(), chair.name(), chair.index("raw"), chair.name("raw")) == (3, "chair", 3, "sofa chair")
    assert chair.name("other") == "" and chair.index("other") == -1
    assert [(c.index(), c.name()) for c in sem.categories] == [(2, "floor"), (3, "chair"), (22, "tv_monitor")]
    # levels and regions: ids "{level}" and "{level}_{region}"; region categories from the one-letter label
    assert [lv.id for lv in sem.levels] == ["0"] and [r.id for r in sem.levels[0].regions] == ["0_0", "0_1"]
    assert [(r.category.index(), r.category.name()) for r in sem.regions] == [(16, "living room"), (15, "kitchen")]
    assert sem.objects[2].region is sem.regions[1] and sem.regions[0].objects == sem.objects[:2]
    # the records' boxes turned from Matterport's z-up frame into Habitat's: the armchair's OBB and its AABB
    obb = sem.objects[1].obb
    assert np.allclose(np.asarray(obb.center), [0.75, 0.45, -1.25]) and np.allclose(np.asarray(obb.sizes),
                                                                                     [0.5, 0.5, 0.9])
    assert _box_is(sem.objects[1].aabb, [0.5, 0.0, -1.5, 1.0, 0.9, -1.0])
    assert _box_is(sem.aabb, [-3.0, -0.1, -3.0, 3.0, 2.5, 3.0])
    assert obb.contains([0.75, 0.1, -1.1]) and not obb.contains([0.75, 1.0, -1.25])
    # the sensor draws each face's object index: the armchair 1, the tv 2, 0 for the floor (object 0) and the
    # unannotated wall
    assert set(np.unique(ids).tolist()) == {0, 1, 2}
    for k in (1, 2):
        assert sem.objects[k].semantic_id == k and sem.objects[k].id.endswith(f"_{k}")


def test_navbench_scene_objects_are_indexed_by_instance_id_with_rooms_as_regions(scene_path):
    from navbench.scene.asset import load_scene

    asset = load_scene(scene_path)
    with _sim(scene_path) as sim:
        sem = sim.semantic_scene
    assert len(sem.objects) == max(asset.objects) + 1
    for i, obj in enumerate(sem.objects):
        assert obj.semantic_id == i and obj.id.endswith(f"_{i}")
        ann = asset.objects.get(i)
        assert obj.category.name() == (ann.category if ann else "Unknown")
        if ann is not None and ann.room:
            assert obj.region.id == ann.room and obj in obj.region.objects
    assert sem.categories[0].name() == "Unknown" and [c.index() for c in sem.categories] == list(
        range(len(sem.categories)))
    assert {r.id for r in sem.regions} == {r.name for r in asset.rooms}
