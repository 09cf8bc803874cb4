"""The bundled InstanceImageNav and GOAT-Bench val splits: upstream layouts read by the upstream readers, goal
images that see their instance, GOAT's mixed 5-10 subtasks, byte-identical regeneration, the oracle at SR 100."""

import filecmp
import gzip
import json
from collections import Counter

import numpy as np
import pytest

import navbench
from navbench.cli import main
from navbench.episodes.goat import load_goat
from navbench.episodes.instance_imagenav import load_instance_imagenav
from navbench.localize.backends.oracle import centre_instance
from navbench.localize.nav_splits import write_goat_split, write_instance_imagenav_split
from navbench.paths import EPISODES_DIR, SCENES_DIR, split_file
from navbench.render.camera import CameraConfig
from navbench.render.renderer import Renderer
from navbench.scene.asset import load_scene


def test_instance_imagenav_val_is_habitats_layout_and_reads():
    path = split_file("instance_imagenav", "val")
    assert json.loads(gzip.decompress(path.read_bytes()))["episodes"] == []
    houses = [f"house_{i:03d}.json.gz" for i in range(8, 12)]
    assert sorted(p.name for p in (path.parent / "content").iterdir()) == houses
    ds = load_instance_imagenav(path)
    assert len(ds.episodes) == 400 and len({e.episode_id for e in ds.episodes}) == 400
    assert len({e.goal_key for e in ds.episodes}) > 80  # many instances, not a few repeated


def test_every_instance_goal_image_sees_its_instance():
    """Rendered with instance ids at the file's camera: the goal covers >= 2 % of the image, in its centre."""
    content = json.loads(gzip.decompress((split_file("instance_imagenav", "val").parent / "content" /
                                          "house_009.json.gz").read_bytes()))
    asset = load_scene(SCENES_DIR / "houses/val/house_009.glb")
    with Renderer(asset, CameraConfig(224, 224, 79.0)) as r:
        for goal in content["goals"].values():
            cam = goal["image_goals"][0]
            assert (cam["hfov"], cam["image_dimensions"]) == (79.0, [224, 224])
            ids = r.render(np.array(cam["position"]), np.array(cam["rotation"]), rgb=False, depth=False, ids=True).ids
            assert (ids == goal["object_id"]).mean() >= 0.02
            assert centre_instance(ids) == goal["object_id"]  # the generator's test of "the object in the centre"


def test_goat_val_mixes_the_three_types_in_5_to_10_subtasks():
    ds = load_goat(split_file("goat", "val"))
    assert len(ds.episodes) == 40
    assert all(5 <= len(e.tasks) <= 10 for e in ds.episodes)
    types = Counter(t.type for e in ds.episodes for t in e.tasks)
    assert set(types) == {"object", "description", "image"} and min(types.values()) > 60
    assert all(e.dropped_descriptions == 0 and e.num_goals == len(e.tasks) for e in ds.episodes)
    for e in ds.episodes:
        for k, t in enumerate(e.tasks):
            if t.type == "description":  # the scene's semantics: colour, category, room, a neighbour
                assert t.category.replace("_", " ") in e.descriptions[k] and " in the " in e.descriptions[k]
        goal = [(t.category,) if t.type == "object" else (t.category, t.instance_id) for t in e.tasks]
        assert all(a != b for a, b in zip(goal, goal[1:]))  # never the goal just closed again


def test_goat_descriptions_name_one_instance_alone():
    from navbench.localize.describe import ground

    asset = load_scene(SCENES_DIR / "houses/val/house_010.glb")
    content = json.loads(gzip.decompress((split_file("goat", "val").parent / "content" /
                                          "house_010.json.gz").read_bytes()))
    described = [g for goals in content["goals"].values() for g in goals if g["lang_desc"]]
    assert described
    for g in described:
        assert ground(g["lang_desc"], asset.objects) == [g["object_id"]]


@pytest.mark.slow
def test_both_splits_regenerate_byte_for_byte(tmp_path):
    write_instance_imagenav_split(tmp_path, SCENES_DIR, seed=0, log=lambda *a: None)
    write_goat_split(tmp_path, SCENES_DIR, seed=0, log=lambda *a: None)
    for task in ("instance_imagenav", "goat"):
        cmp = filecmp.dircmp(tmp_path / task / "val", EPISODES_DIR / task / "val")
        assert not cmp.diff_files and not cmp.left_only and not cmp.right_only
        for name in cmp.common_files + [f"content/{n}" for n in cmp.subdirs["content"].common_files]:
            assert (tmp_path / task / "val" / name).read_bytes() == (EPISODES_DIR / task / "val" / name).read_bytes()


def test_a_house_regenerates_byte_for_byte(tmp_path, monkeypatch):
    """One house, a few episodes, twice: the same bytes (the whole split's check is the slow test above)."""
    import navbench.localize.nav_splits as ns

    monkeypatch.setattr(ns, "_houses", lambda scene_dir: [(SCENES_DIR / "houses/val/house_011.glb", "house_011")])
    plan = ns.NavSplitPlan(goat_per_scene=3)
    for out in ("a", "b"):
        write_goat_split(tmp_path / out, SCENES_DIR, seed=0, plan=plan, log=lambda *a: None)
    a, b = (tmp_path / o / "goat" / "val" / "content" / "house_011.json.gz" for o in ("a", "b"))
    assert a.read_bytes() == b.read_bytes()


@pytest.mark.slow  # an end-to-end run (seconds to tens of seconds): make test-slow
@pytest.mark.parametrize("task,k", [("instance_imagenav", 3), ("goat", 1)])
def test_the_oracle_reaches_every_goal_of_the_bundled_split(tmp_path, task, k):
    summary = navbench.evaluate("oracle", task=task, per_scene=k, out=tmp_path / "run")
    assert summary["num_episodes"] == 4 * k and summary["success"] == 1.0 and summary["num_failed"] == 0


@pytest.mark.slow
@pytest.mark.parametrize("task,n", [("instance_imagenav", 400), ("goat", 40)])
def test_the_oracle_reaches_every_goal_of_the_whole_bundled_split(tmp_path, task, n):
    summary = navbench.evaluate("oracle", task=task, out=tmp_path / "run")
    assert summary["num_episodes"] == n and summary["success"] == 1.0


def test_a_split_missing_an_image_index_exits_2_naming_file_and_field(tmp_path, capsys):
    src = split_file("instance_imagenav", "val").parent
    (tmp_path / "content").mkdir()
    (tmp_path / "val.json.gz").write_bytes((src / "val.json.gz").read_bytes())
    doc = json.loads(gzip.decompress((src / "content" / "house_008.json.gz").read_bytes()))
    doc["episodes"][3]["goal_image_id"] = 1
    bad = tmp_path / "content" / "house_008.json"
    bad.write_text(json.dumps(doc))
    assert main(["run", "--task", "instance_imagenav", "--episodes", str(tmp_path / "val.json.gz"),
                 "--agent", "oracle", "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(bad) in err[0] and "goal_image_id 1 is out of range" in err[0]
