"""`navbench generate habitat-test-data DIR`: habitat-lab's test scenes and test PointNav dataset, stood in for by
navbench houses and seeded episodes at the paths habitat-lab's tests read."""

import gzip
import json
import subprocess
import sys

import pytest

from navbench.episodes import habitat_test_data as htd
from navbench.paths import SCENES_DIR
from navbench.scene.cache import load_scene_and_navgrid

SMALL = {"train": 3, "val": 2, "test": 2}  # episodes per scene, to keep the test fast


def _write(out, seed=0, **kw):
    return htd.write_habitat_test_data(out, seed=seed, episodes_per_scene=SMALL, log=lambda *_: None, **kw)


def _split(out, split):
    with gzip.open(htd.split_path(out, split), "rt") as fh:
        return json.load(fh)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    out = tmp_path_factory.mktemp("htd")
    assert _write(out) == {"train": 6, "val": 4, "test": 4}
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


def test_same_seed_same_files_other_seed_other_episodes(data, tmp_path):
    _write(tmp_path / "a")
    _write(tmp_path / "b", seed=1)
    for split in ("train", "val", "test"):
        assert htd.split_path(tmp_path / "a", split).read_bytes() == htd.split_path(data, split).read_bytes()
        assert _split(tmp_path / "b", split) != _split(data, split)
    # the splits draw from streams of their own: no episode repeats across them
    starts = [tuple(e["start_position"]) for s in ("train", "val", "test") for e in _split(data, s)["episodes"]]
    assert len(set(starts)) == len(starts)


def test_a_non_empty_directory_is_refused_unless_overwrite(tmp_path):
    (tmp_path / "keep.txt").write_text("mine")
    with pytest.raises(ValueError, match="not empty"):
        _write(tmp_path)
    assert not (tmp_path / "data").exists()
    _write(tmp_path, overwrite=True)
    assert (tmp_path / "keep.txt").read_text() == "mine"
    assert htd.split_path(tmp_path, "val").is_file()
    (tmp_path / "file").write_text("")
    with pytest.raises(ValueError, match="not a directory"):
        _write(tmp_path / "file")


def test_cli_refuses_a_non_empty_directory_in_one_line(tmp_path):
    (tmp_path / "x").write_text("")
    r = subprocess.run([sys.executable, "-m", "navbench", "generate", "habitat-test-data", str(tmp_path)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and str(tmp_path) in r.stderr and "--overwrite" in r.stderr
    assert not (tmp_path / "data").exists()


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
