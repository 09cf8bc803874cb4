import gzip
import json

import pytest

from navbench.episodes.io import load_dataset, save_dataset
from navbench.episodes.types import EpisodeError, ObjectGoal

# A hand-written ObjectNav-v1 file in Habitat's layout (as HM3D's val files are).
HM3D_STYLE = {
    "episodes": [
        {"episode_id": "17", "scene_id": "hm3d/val/00800-TEEsavR23oF/TEEsavR23oF.basis.glb",
         "start_position": [1.0, 0.1, -2.0], "start_rotation": [0.0, 0.38268, 0.0, 0.92388],
         "info": {"geodesic_distance": 5.123456789, "euclidean_distance": 4.0, "closest_goal_object_id": 42},
         "goals": [], "start_room": None, "shortest_paths": None, "object_category": "chair",
         "scene_dataset_config": "./data/scene_datasets/hm3d/hm3d_annotated_basis.scene_dataset_config.json"},
        {"episode_id": "18", "scene_id": "hm3d/val/00800-TEEsavR23oF/TEEsavR23oF.basis.glb",
         "start_position": [0.0, 0.1, 0.0], "start_rotation": [0, 0, 0, 1],
         "info": {"geodesic_distance": 3.0}, "goals": [], "object_category": "bed"},
    ],
    "goals_by_category": {
        "TEEsavR23oF.basis.glb_chair": [
            {"position": [3.0, 0.5, -1.0], "radius": None, "object_id": 42, "object_name": "chair_42",
             "object_category": "chair", "room_id": None, "room_name": None,
             "view_points": [{"agent_state": {"position": [2.5, 0.1, -1.0], "rotation": [0, 0.7071, 0, 0.7071]},
                              "iou": 0.31}]},
            {"position": [5.0, 0.5, 2.0], "radius": None, "object_id": 43, "object_category": "chair",
             "view_points": []},
        ],
        "TEEsavR23oF.basis.glb_bed": [
            {"position": [0.0, 0.5, 4.0], "object_id": 7, "object_category": "bed",
             "view_points": [{"agent_state": {"position": [0.0, 0.1, 3.0], "rotation": [0, 0, 0, 1]}, "iou": 0.5}]},
        ],
    },
    "category_to_task_category_id": {"chair": 0, "bed": 1},
    "category_to_scene_annotation_category_id": {"chair": 3, "bed": 11},
}


def _write(path, data):
    path.write_bytes(gzip.compress(json.dumps(data).encode()))
    return path


def test_load_hand_written_objectnav_v1(tmp_path):
    ds = load_dataset(_write(tmp_path / "val.json.gz", HM3D_STYLE))
    assert ds.task == "objectnav"
    assert [e.episode_id for e in ds.episodes] == ["17", "18"]
    ep = ds.episodes[0]
    assert ep.object_category == "chair"
    # goals filled from goals_by_category at load time, keyed by basename(scene_id) + category
    assert [g.object_id for g in ep.goals] == [42, 43]
    assert isinstance(ep.goals[0], ObjectGoal)
    assert ep.goals[0].view_points[0].agent_state.rotation == [0, 0.7071, 0, 0.7071]
    # distance is measured to view points; a goal without view points falls back to its position
    pts = ep.goal_positions()
    assert pts.shape == (2, 3) and pts[0].tolist() == [2.5, 0.1, -1.0] and pts[1].tolist() == [5.0, 0.5, 2.0]
    assert ds.category_to_task_category_id == {"chair": 0, "bed": 1}
    assert ep.extra["scene_dataset_config"].endswith("config.json")


def test_round_trip_rounds_floats_and_keeps_ids(tmp_path):
    ds = load_dataset(_write(tmp_path / "in.json.gz", HM3D_STYLE))
    out = save_dataset(ds, tmp_path / "out.json.gz")
    raw = json.loads(gzip.decompress(out.read_bytes()))
    assert raw["episodes"][0]["goals"] == []  # ObjectNav-v1 keeps goals in the table
    assert raw["episodes"][0]["info"]["geodesic_distance"] == 5.12346
    assert set(raw["goals_by_category"]) == set(HM3D_STYLE["goals_by_category"])
    again = load_dataset(out)
    assert [e.episode_id for e in again.episodes] == ["17", "18"]
    assert again.episodes[0].goals[0].view_points[0].iou == pytest.approx(0.31)
    # byte-stable: writing the same dataset twice gives identical files
    first, second = save_dataset(again, tmp_path / "a.json.gz"), save_dataset(again, tmp_path / "b.json.gz")
    assert first.read_bytes() == second.read_bytes()


def test_pointnav_round_trip_plain_json(tmp_path):
    data = {"episodes": [{"episode_id": "0", "scene_id": "houses/val/house_008.glb",
                          "start_position": [1, 0, 2], "start_rotation": [0, 0, 0, 1],
                          "info": {"geodesic_distance": 3.5}, "goals": [{"position": [4, 0, 2], "radius": 0.2}]}]}
    p = tmp_path / "pn.json"
    p.write_text(json.dumps(data))
    ds = load_dataset(p)
    assert ds.task == "pointnav" and ds.episodes[0].goals[0].radius == 0.2
    again = load_dataset(save_dataset(ds, tmp_path / "pn2.json"))
    assert again.episodes[0].goals[0].position == [4.0, 0.0, 2.0]


def test_content_dir_per_scene_files(tmp_path):
    top = {"episodes": [], "goals_by_category": {}, "category_to_task_category_id": {"chair": 0, "bed": 1}}
    (tmp_path / "content").mkdir()
    _write(tmp_path / "val.json.gz", top)
    scene_part = dict(HM3D_STYLE)
    scene_part.pop("category_to_task_category_id")
    _write(tmp_path / "content" / "TEEsavR23oF.json.gz", scene_part)
    ds = load_dataset(tmp_path / "val.json.gz")
    assert len(ds.episodes) == 2 and ds.episodes[1].goals[0].object_id == 7


@pytest.mark.parametrize("content,needle", [
    (b'{"episodes": [', "corrupt or truncated JSON"),
    (b"\x1f\x8b\x08\x00garbage", "corrupt or truncated JSON"),
    (b'{"foo": 1}', "no top-level 'episodes'"),
    (b'{"episodes": [{"episode_id": "5", "scene_id": "s", "start_position": [0, 0], "start_rotation": [0,0,0,1]}]}',
     "episode 5"),
    (b'{"episodes": [{"episode_id": "6", "scene_id": "s", "start_position": [0, NaN, 0], '
     b'"start_rotation": [0,0,0,1]}]}', "episode 6"),
])
def test_bad_files_name_file_and_problem(tmp_path, content, needle):
    p = tmp_path / ("bad.json.gz" if content.startswith(b"\x1f") else "bad.json")
    p.write_bytes(content)
    with pytest.raises(EpisodeError) as err:
        load_dataset(p)
    assert str(p) in str(err.value) and needle in str(err.value)


def test_category_without_goals_is_an_error(tmp_path):
    data = json.loads(json.dumps(HM3D_STYLE))
    data["episodes"][1]["object_category"] = "sofa"
    with pytest.raises(EpisodeError, match="episode 18: no goals for category 'sofa'"):
        load_dataset(_write(tmp_path / "v.json.gz", data))


def test_missing_file(tmp_path):
    with pytest.raises(EpisodeError, match="file not found"):
        load_dataset(tmp_path / "nope.json.gz")


HM3D_CONFIG = "./data/scene_datasets/hm3d/hm3d_annotated_basis.scene_dataset_config.json"


def ovon_style() -> dict:
    """An HM3D-OVON file as naokiyokoyama/ovon's objectnav_generator.py writes one: goal object_ids are
    habitat-sim object names (HM3DSemanticScene.cpp: "{raw name}_{index in that name's rows}"), view
    points carry a radius, episodes carry children_object_categories (the goals' copy is deleted
    before writing) and the ObjectNav-v1 category tables are empty."""
    sid = "hm3d/val/00800-TEEsavR23oF/TEEsavR23oF.basis.glb"
    vp = {"agent_state": {"position": [2.5, 0.1, -1.0], "rotation": [0, 0.7071, 0, 0.7071]}, "iou": 0.0,
          "radius": 0.5}
    return {
        "episodes": [{"episode_id": "0", "scene_id": sid, "start_position": [0, 0.1, 0],
                      "start_rotation": [0, 0, 0, 1], "info": {"geodesic_distance": 4.0, "euclidean_distance": 3.0},
                      "goals": [], "start_room": None, "shortest_paths": None, "object_category": "couch",
                      "scene_dataset_config": HM3D_CONFIG,
                      "additional_obj_config_paths": [], "children_object_categories": []}],
        "goals_by_category": {"TEEsavR23oF.basis.glb_couch": [
            {"object_category": "couch", "object_id": "couch_0", "position": [3.0, 0.5, -1.0], "view_points": [vp]},
            {"object_category": "couch", "object_id": "couch_12", "position": [1.0, 0.5, 2.0], "view_points": [vp]}]},
        "category_to_task_category_id": {}, "category_to_scene_annotation_category_id": {},
    }


def test_ovon_string_object_ids_load_as_ovons_reader_reads_them_and_write_back_unchanged(tmp_path):
    from navbench.episodes.io import is_ovon

    path = tmp_path / "val_unseen.json.gz"
    path.write_bytes(gzip.compress(json.dumps(ovon_style()).encode()))
    ds = load_dataset(path)
    goals = ds.episodes[0].goals
    assert [g.object_id for g in goals] == [0, 12]  # the number after the last "_"
    assert [g.object_name for g in goals] == ["couch_0", "couch_12"]
    assert is_ovon(ds)
    out = tmp_path / "again.json"
    save_dataset(ds, out)
    written = json.loads(out.read_text())["goals_by_category"]["TEEsavR23oF.basis.glb_couch"]
    assert [g["object_id"] for g in written] == ["couch_0", "couch_12"]
    assert is_ovon(load_dataset(out))


def test_objectnav_v1_is_not_taken_for_ovon(tmp_path):
    from navbench.episodes.io import is_ovon

    path = tmp_path / "val.json"
    path.write_text(json.dumps(HM3D_STYLE))
    assert not is_ovon(load_dataset(path))


@pytest.mark.parametrize("bad", ["couch", "couch_", "_3", "couch_x1"])
def test_object_id_string_without_an_index_is_refused_naming_the_file(tmp_path, bad):
    data = ovon_style()
    data["goals_by_category"]["TEEsavR23oF.basis.glb_couch"][0]["object_id"] = bad
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(EpisodeError, match=r"bad\.json: .*object_id"):
        load_dataset(path)


def test_success_distance_defaults_to_ovons_for_an_ovon_file_and_habitats_for_objectnav_v1(tmp_path):
    from navbench.api import resolve_episodes

    ovon, v1 = tmp_path / "ovon.json", tmp_path / "v1.json"
    ovon.write_text(json.dumps(ovon_style()))
    v1.write_text(json.dumps(HM3D_STYLE))
    assert resolve_episodes(None, None, ovon) == ("objectnav", None, ovon, 0.25)
    assert resolve_episodes("objectnav", None, ovon)[3] == 0.25
    assert resolve_episodes(None, None, v1)[3] == 0.1
