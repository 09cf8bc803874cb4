"""`navbench generate habitat-test-data DIR`: habitat-lab's test scenes and test PointNav dataset, stood in for by
navbench houses and seeded episodes at the paths habitat-lab's tests read."""

import gzip
import json
from pathlib import Path

import pytest

from navbench.cli import main
from navbench.episodes import habitat_test_data as htd
from navbench.paths import SCENES_DIR
from navbench.scene.cache import load_scene_and_navgrid

SMALL = {"train": 3, "val": 2, "test": 2}  # episodes per scene, to keep the test fast


def _write(out, seed=0, **kw):
    return htd.write_habitat_test_data(out, seed=seed, episodes_per_scene=SMALL, objectnav_per_scene=2,
                                       log=lambda *_: None, **kw)


def _split(out, split, path=htd.split_path):
    with gzip.open(path(out, split), "rt") as fh:
        return json.load(fh)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    out = tmp_path_factory.mktemp("htd")
    assert _write(out) == {"pointnav/train": 6, "pointnav/val": 4, "pointnav/test": 4, "objectnav/train": 6,
                           "objectnav/val": 6}
    return out


def test_files_are_where_habitat_labs_tests_read_them(data):
    assert sorted(p.relative_to(data).as_posix() for p in data.rglob("*") if p.is_file()) == sorted(
        p.relative_to(data).as_posix() for p in htd.written_files(data))
    for name in ("skokloster-castle", "van-gogh-room", "apartment_1"):
        assert (data / f"data/scene_datasets/habitat-test-scenes/{name}.glb").read_bytes() == \
            (SCENES_DIR / htd.STAND_INS[name]).read_bytes()
        assert (data / f"data/scene_datasets/habitat-test-scenes/{name}.semantic.json").is_file()
    for split in ("train", "val", "test"):
        assert (data / f"data/datasets/pointnav/habitat-test-scenes/v1/{split}/{split}.json.gz").is_file()
    for split in ("train", "val"):
        assert (data / f"data/datasets/objectnav/mp3d/v1/{split}/{split}.json.gz").is_file()
    assert (data / "data/scene_datasets/mp3d/house_008/house_008.glb").read_bytes() == \
        (SCENES_DIR / "houses/val/house_008.glb").read_bytes()


def test_episodes_are_pointnav_v1_on_the_stand_in_scenes(data):
    grids = {}
    for split in ("train", "val", "test"):
        doc = _split(data, split)
        assert list(doc) == ["episodes"]
        scenes = set()
        for ep in doc["episodes"]:
            # the fields habitat-lab's NavigationEpisode(**episode) and NavigationGoal(**goal) take
            assert set(ep) == {"episode_id", "scene_id", "start_position", "start_rotation", "info", "goals"}
            assert [set(g) for g in ep["goals"]] == [{"position", "radius"}]
            assert ep["scene_id"].startswith("data/scene_datasets/habitat-test-scenes/")
            scenes.add(ep["scene_id"])
            if ep["scene_id"] not in grids:
                grids[ep["scene_id"]] = load_scene_and_navgrid(data / ep["scene_id"], htd.TEST_AGENT)[1]
            grid = grids[ep["scene_id"]]
            assert grid.is_navigable(ep["start_position"]) and grid.is_navigable(ep["goals"][0]["position"])
            # d0 is measured with the body of habitat-lab's test agent (radius 0.1 m), as its simulator does
            d0 = grid.geodesic_distance(ep["start_position"], ep["goals"][0]["position"])
            assert ep["info"]["geodesic_distance"] == pytest.approx(d0, abs=1e-3)
        assert scenes == {f"data/scene_datasets/habitat-test-scenes/{n}.glb" for n in htd.POINTNAV_SCENES}
        assert [ep["episode_id"] for ep in doc["episodes"]] == [str(i) for i in range(len(doc["episodes"]))]


def test_objectnav_episodes_are_objectnav_v1_on_mp3d_paths(data):
    for split, rels in htd.OBJECTNAV_STAND_INS.items():
        doc = _split(data, split, htd.objectnav_split_path)
        assert set(doc) == {"episodes", "goals_by_category", "category_to_task_category_id",
                            "category_to_scene_annotation_category_id"}
        cats = set(doc["category_to_task_category_id"])
        assert cats and cats <= set(htd.MP3D_CATEGORIES)
        assert {e["scene_id"] for e in doc["episodes"]} == {
            f"data/scene_datasets/mp3d/{Path(r).stem}/{Path(r).stem}.glb" for r in rels}
        for ep in doc["episodes"]:
            assert ep["goals"] == [] and ep["object_category"] in cats
            goals = doc["goals_by_category"][f"{Path(ep['scene_id']).name}_{ep['object_category']}"]
            assert goals and all(g["view_points"] for g in goals)


def test_a_non_empty_directory_is_refused_unless_overwrite_and_the_same_seed_writes_the_same_files(data, tmp_path):
    (tmp_path / "keep.txt").write_text("mine")
    with pytest.raises(ValueError, match="not empty"):
        _write(tmp_path)
    assert not (tmp_path / "data").exists()
    _write(tmp_path, overwrite=True)
    assert (tmp_path / "keep.txt").read_text() == "mine"
    for path in htd.written_files(data):
        assert (tmp_path / path.relative_to(data)).read_bytes() == path.read_bytes()
    (tmp_path / "file").write_text("")
    with pytest.raises(ValueError, match="not a directory"):
        _write(tmp_path / "file")


def test_another_seed_draws_other_episodes_and_splits_do_not_share_episodes(data, tmp_path):
    for name in htd.POINTNAV_SCENES:
        htd._copy_scene(SCENES_DIR / htd.STAND_INS[name], htd.scene_path(tmp_path, name))
    htd.write_pointnav_splits(tmp_path, seed=1, episodes_per_scene=SMALL, log=lambda *_: None)
    for split in ("train", "val", "test"):
        assert _split(tmp_path, split) != _split(data, split)
    starts = [tuple(e["start_position"]) for s in ("train", "val", "test") for e in _split(data, s)["episodes"]]
    assert len(set(starts)) == len(starts)


def test_cli_refuses_a_non_empty_directory_in_one_line(tmp_path, capsys):
    (tmp_path / "x").write_text("")
    assert main(["generate", "habitat-test-data", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.strip().count("\n") == 0 and str(tmp_path) in err and "--overwrite" in err
    assert not (tmp_path / "data").exists()
    assert main(["generate", "scenes", str(tmp_path)]) == 2  # DIR belongs to habitat-test-data alone
    assert "--out" in capsys.readouterr().err


def test_habitat_labs_reader_loads_the_test_dataset(data, monkeypatch):
    pytest.importorskip("habitat", reason="habitat-lab (the habitat extra) not installed")
    from habitat.config.default import get_config
    from habitat.datasets.pointnav.pointnav_dataset import PointNavDatasetV1

    monkeypatch.chdir(data)  # habitat-lab's test config holds paths relative to the working directory
    for split in ("train", "val", "test"):
        cfg = get_config("benchmark/nav/pointnav/pointnav_habitat_test.yaml",
                         overrides=[f"habitat.dataset.split={split}"]).habitat.dataset
        assert PointNavDatasetV1.check_config_paths_exist(cfg)
        ds = PointNavDatasetV1(cfg)
        assert len(ds.episodes) == 2 * SMALL[split]
        assert sorted(ds.scene_ids) == sorted(f"data/scene_datasets/habitat-test-scenes/{n}.glb"
                                              for n in htd.POINTNAV_SCENES)
        assert all((data / s).is_file() for s in ds.scene_ids)


def test_habitat_labs_reader_loads_the_objectnav_stand_in(data, monkeypatch):
    pytest.importorskip("habitat", reason="habitat-lab (the habitat extra) not installed")
    from habitat.config.default import get_config
    from habitat.datasets.object_nav.object_nav_dataset import ObjectNavDatasetV1

    monkeypatch.chdir(data)
    for split in ("train", "val"):
        cfg = get_config("benchmark/nav/objectnav/objectnav_mp3d.yaml",
                         overrides=[f"habitat.dataset.split={split}"]).habitat.dataset
        assert ObjectNavDatasetV1.check_config_paths_exist(cfg)
        ds = ObjectNavDatasetV1(cfg)
        assert len(ds.episodes) == 6 and all((data / s).is_file() for s in ds.scene_ids)
        assert all(ep.goals for ep in ds.episodes)


def test_habitat_labs_distance_to_goal_at_reset_is_the_episodes_geodesic(data, monkeypatch):
    """The episodes are drawn for the body habitat-lab's PointNav test config gives its path finder."""
    pytest.importorskip("habitat", reason="habitat-lab (the habitat extra) not installed")
    pytest.importorskip("habitat_sim", reason="navbench-habitat-sim (compat/habitat-sim) not installed")
    import habitat
    from habitat.config.default import get_config

    monkeypatch.chdir(data)
    cfg = get_config("benchmark/nav/pointnav/pointnav_habitat_test.yaml", overrides=[
        "habitat.dataset.split=val", "habitat.environment.iterator_options.shuffle=False",
        "habitat.simulator.agents.main_agent.sim_sensors={}"])
    with habitat.Env(config=cfg) as env:
        for _ in range(len(env.episodes)):
            env.reset()
            d0 = env.current_episode.info["geodesic_distance"]
            assert env.get_metrics()["distance_to_goal"] == pytest.approx(d0, abs=1e-3)
