"""Files written the way Habitat's tools write them (benchmarks/habitat_formats.py, made from the upstream
sources): a GOOGLE_texture_basis scan, HM3D-OVON episodes with string object ids, GOAT-Bench episodes and
an HSSD-style scene instance load, render their textures and score 100% with oracle perception."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from navbench.eval.runner import RunConfig, read_records, run
from navbench.scene.asset import SceneError, load_scene

ROOT = Path(__file__).resolve().parents[2]


def _formats():
    spec = importlib.util.spec_from_file_location("habitat_formats", ROOT / "benchmarks" / "habitat_formats.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


H = _formats()


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    return H.write_all(tmp_path_factory.mktemp("habitat_formats"))


def _run(files, episodes: str, agent: str, out: Path, limit: int | None = None):
    from navbench.agents.registry import make_memory, make_oracle, prebuild_memories
    from navbench.api import resolve_episodes
    from navbench.eval.runner import run_dataset, select_episodes

    task, _, path, sd = resolve_episodes(None, None, files[episodes])
    cfg = RunConfig(task=task, split=None, agent=agent, episodes=str(path), scene_dir=str(files["scene_datasets"]),
                    success_distance=sd, limit=limit)
    if agent == "memory":
        prebuild_memories(cfg, select_episodes(run_dataset(path), cfg.limit, cfg.per_scene))
    summary = run(cfg, make_memory if agent == "memory" else make_oracle, out)
    return summary, read_records(out / "episodes.jsonl"), json.loads((out / "config.json").read_text())


def test_google_basis_scan_decodes_to_its_atlas_in_row_order(files):
    if H.basis_file(np.zeros((4, 4, 3), np.uint8)) is None:
        pytest.skip("alktx2 (the UASTC encoder the fixture needs) is not installed")
    asset = load_scene(files["hm3d_scene"])
    assert asset.is_textured
    decoded = asset.textures[0][..., :3].astype(int)
    err = np.abs(decoded - H.atlas().astype(int))
    assert err.mean() < 3.0 and np.percentile(err, 99) < 20  # a flipped atlas would be off by ~50 levels
    assert {o.category for o in asset.objects.values()} == {"chair", "tv_monitor"}


def test_ovon_file_runs_at_ovons_success_distance_with_oracle_sr_100(files, tmp_path):
    summary, records, config = _run(files, "ovon", "oracle", tmp_path / "oracle")
    assert config["success_distance"] == 0.25
    assert len(records) == 4 and all(r["success"] == 1.0 for r in records)


def test_memory_agent_finds_an_open_vocabulary_ovon_goal_with_oracle_perception(files, tmp_path):
    # Episode 1 asks for "tv", which navbench's fixed label map does not know; the oracle learns its
    # instance from the episode's goals.
    summary, records, _ = _run(files, "ovon", "memory", tmp_path / "memory", limit=2)
    assert [r["object_category"] for r in records] == ["armchair", "tv"]
    assert all(r["success"] == 1.0 for r in records), [r.get("log") for r in records]


def test_goat_bench_file_localises_every_subtask_type_at_sr5_100(files, tmp_path):
    from navbench.localize.benchmark import run_localize
    from navbench.localize.goatbench import load_goatbench

    subtasks = load_goatbench(files["goat_bench"])
    assert [s.type for s in subtasks] == ["object", "language", "image", "object", "language"]
    assert subtasks[2].image_goal.height == 224 and subtasks[1].query.startswith("The television")
    s = run_localize(episodes=files["goat_bench"], scene_dir=files["scene_datasets"], out=tmp_path / "loc",
                     memory_root=tmp_path / "mem")
    assert s["sr_by_type"] == {"object": 1.0, "image": 1.0, "language": 1.0}
    assert s["n_by_type"] == {"object": 2, "image": 1, "language": 2}


def test_malformed_goat_bench_file_exits_2_naming_it(files, tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"episodes": [{"scene_id": "x.glb", "tasks": [["chair", "smell", "c_0"]]}],
                               "goals": {}}))
    proc = subprocess.run([sys.executable, "-m", "navbench.cli", "localize", "--episodes", str(bad), "--scene-dir",
                           str(files["scene_datasets"])], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2 and "bad.json" in proc.stderr and "smell" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


def test_scene_instance_composes_stage_and_objects_as_habitat_sim_places_them(files):
    asset = load_scene(files["hssd_scene"])
    chair, cabinet = asset.objects[0], asset.objects[1]
    assert (chair.category, cabinet.category) == ("chair", "cabinet")  # semantic ids named by the lexicon
    # The chair: a 0.5 x 0.9 x 0.5 box with its origin at its base centre, turned 45 degrees about y
    # ([w, x, y, z] = [cos 22.5, 0, sin 22.5, 0]), asset-local origin at (1, 0, -1).
    r = 0.25 * np.sqrt(2)
    np.testing.assert_allclose(chair.aabb_min, [1 - r, 0, -1 - r], atol=1e-4)
    np.testing.assert_allclose(chair.aabb_max, [1 + r, 0.9, -1 + r], atol=1e-4)
    # The cabinet: a 1 x 0.5 x 0.4 box, scaled 1.2 and then 1.5 in z, its centre (COM) at (-1.5, 0.3, 1).
    np.testing.assert_allclose(cabinet.aabb_min, [-2.1, 0.0, 1 - 0.36], atol=1e-4)
    np.testing.assert_allclose(cabinet.aabb_max, [-0.9, 0.6, 1 + 0.36], atol=1e-4)
    assert set(np.unique(asset.face_ids)) == {-1, 0, 1}


def test_scene_instance_objectnav_scores_oracle_sr_100(files, tmp_path):
    summary, records, config = _run(files, "objectnav_hssd", "oracle", tmp_path / "hssd")
    assert config["success_distance"] == 0.1 and len(records) == 2
    assert all(r["success"] == 1.0 for r in records)


def test_scene_instance_with_an_unknown_template_is_refused_naming_it(files, tmp_path):
    doc = json.loads(files["hssd_scene"].read_text())
    doc["object_instances"][0]["template_name"] = "no_such_object"
    bad = files["hssd_scene"].with_name("bad.scene_instance.json")
    bad.write_text(json.dumps(doc))
    try:
        with pytest.raises(SceneError, match=r"bad\.scene_instance\.json: template 'no_such_object'"):
            load_scene(bad)
    finally:
        bad.unlink()


def test_a_bare_scene_handle_resolves_to_its_scene_instance(files):
    from navbench.scene.datasets import resolve_scene

    assert resolve_scene("room", files["scene_datasets"]) == files["hssd_scene"]
    with pytest.raises(SceneError, match=r"nosuch: scene file not found .*nosuch\.scene_instance\.json"):
        resolve_scene("nosuch", files["scene_datasets"])


def test_goat_bench_descriptions_over_55_words_are_dropped_as_the_reader_drops_them(files, tmp_path):
    import gzip

    from navbench.localize.goatbench import load_goatbench

    doc = json.loads(gzip.decompress(files["goat_bench"].read_bytes()))
    base = Path(H.HM3D_SCENE_ID).name
    doc["goals"][f"{base}_tv"][0]["lang_desc"] = " ".join(["word"] * 56)
    path = tmp_path / "long.json"
    path.write_text(json.dumps(doc))
    assert [s.type for s in load_goatbench(path)] == ["object", "image", "object", "language"]


def test_invisible_scene_instance_is_left_out(files):
    doc = json.loads(files["hssd_scene"].read_text())
    doc["object_instances"][1]["is_instance_visible"] = False
    path = files["hssd_scene"].with_name("hidden.scene_instance.json")
    path.write_text(json.dumps(doc))
    try:
        assert set(load_scene(path).objects) == {0}
    finally:
        path.unlink()


def test_instance_imagenav_file_reads_and_renders_its_goal_images(files):
    from navbench.episodes.instance_imagenav import instance_imagegoal_observations, load_instance_imagenav
    from navbench.scene.datasets import resolve_scene

    ds = load_instance_imagenav(files["instance_imagenav"])
    assert [(e.goal_key, e.goal_image_id) for e in ds.episodes] == [(f"{H.SCAN}_3", 1), (f"{H.SCAN}_4", 0),
                                                                     (f"{H.SCAN}_3", 0)]
    ep = ds.episodes[0]
    assert len(ep.goal_positions()) > 10  # measured to the view points
    asset = load_scene(resolve_scene(ep.scene_id, files["scene_datasets"]))
    for ep in ds.episodes[:2]:
        obs = instance_imagegoal_observations(asset, ep)
        g = ep.image_goal
        assert obs["instance_imagegoal"].shape == (g.height, g.width, 3)
        assert obs["instance_imagegoal_hfov"].tolist() == [g.hfov_deg]
    # the armchair's view (rolled 10 degrees, pitched down 20) shows it: its green fills part of the image
    img = instance_imagegoal_observations(asset, ds.episodes[0])["instance_imagegoal"].astype(int)
    green = (img[..., 1] > img[..., 0] + 40) & (img[..., 1] > img[..., 2] + 40)
    assert 0.05 < green.mean() < 0.95


def test_goat_bench_file_reads_for_navigation(files):
    from navbench.episodes.goat import load_goat

    (ep,) = load_goat(files["goat_bench"]).episodes
    assert [t.type for t in ep.tasks] == ["object", "description", "image", "object", "description"]
    assert ep.num_goals == 5 and ep.descriptions[1].startswith("The television")
    assert ep.image_goals[2].height == 224 and ep.image_goals[2].hfov_deg == 79.0
    assert [[g.object_id for g in gs] for gs in ep.subtask_goals] == [["armchair_0"], ["tv_0"], ["armchair_0"],
                                                                      ["tv_0"], ["armchair_0"]]


@pytest.mark.parametrize("name,task,sd", [("instance_imagenav", "instance_imagenav", 0.1),
                                          ("goat_bench", "goat", 0.25)])
def test_image_and_goat_files_run_with_the_oracle_at_sr_100(files, tmp_path, name, task, sd):
    summary, records, config = _run(files, name, "oracle", tmp_path / name)
    assert config["task"] == task and config["success_distance"] == sd  # told from the file's fields
    assert summary["success"] == 1.0 and all(r["success"] == 1.0 for r in records)
    if task == "goat":
        (r,) = records
        assert r["subtask_success"] == [1.0] * 5 and r["task_success"] == 0.0 and r["composite_success"] == 1.0
        assert r["trace"]["actions"].count("6") == 5
        assert summary["partial_success"] == summary["composite_success"] == 1.0 and summary["task_success"] == 0.0
        assert "subtask_success" not in summary  # per-subtask lists stay in the records


@pytest.mark.parametrize("name,break_it,needle", [
    ("instance_imagenav", lambda d: d["episodes"][1].update(goal_object_id="99"), "goals has no key 'abcDEFghiJK_99'"),
    ("instance_imagenav", lambda d: d["episodes"][0].update(goal_image_id=5), "goal_image_id 5 is out of range"),
    ("goat_bench", lambda d: d["episodes"][0]["tasks"][2].__setitem__(3, 4), "tasks[2]: image index 4 is out of range"),
    ("goat_bench", lambda d: d["episodes"][0]["tasks"][1].__setitem__(2, "tv_9"), "no instance with object_id 'tv_9'"),
])
def test_a_broken_image_or_goat_file_exits_2_in_one_line_naming_file_and_field(files, tmp_path, capsys, name,
                                                                                break_it, needle):
    import gzip
    import shutil

    from navbench.cli import main

    src = files[name]
    if name == "instance_imagenav":  # the episodes are in content/ beside the split file
        root = tmp_path / "val"
        shutil.copytree(src.parent, root)
        bad, episodes = root / "content" / f"{H.SCAN}.json.gz", root / src.name
    else:
        bad = episodes = tmp_path / src.name
        shutil.copy(src, bad)
    doc = json.loads(gzip.decompress(bad.read_bytes()))
    break_it(doc)
    bad.write_bytes(gzip.compress(json.dumps(doc).encode()))
    code = main(["run", "--episodes", str(episodes), "--scene-dir", str(files["scene_datasets"]), "--agent", "oracle",
                 "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and str(bad) in err[0] and needle in err[0], err
