"""The InstanceImageNav reader on files written here from habitat-lab's published schema (not by navbench)."""

import copy
import gzip
import json

import pytest

from navbench.episodes.instance_imagenav import (
    SUCCESS_DISTANCE,
    InstanceImageEpisode,
    instance_goal_key,
    instance_imagenav_metrics,
    load_instance_imagenav,
)
from navbench.episodes.types import EpisodeError

SCENE = "hm3d_v0.2/minival/00800-TEEsavR23oF/TEEsavR23oF.basis.glb"

# One content file as habitat-challenge's v3 val_mini has them (content/TEEsavR23oF.json.gz): goals keyed
# "{scene}_{object_id}", episodes naming goal_object_id (a string) and goal_image_id.
CONTENT = {
    "goals": {
        "TEEsavR23oF_10": {
            "position": [-3.1, 3.9, -1.2], "object_id": 10, "object_name": "tv_10",
            "object_category": "tv_monitor", "object_surface_area": 2.308,
            "view_points": [
                {"agent_state": {"position": [-3.0, 3.16, -2.0], "rotation": [0, 0.2, 0, 0.98]}, "iou": 1.02},
                {"agent_state": {"position": [-2.5, 3.16, -2.1], "rotation": [0, 0.1, 0, 0.99]}, "iou": 0.8},
            ],
            "image_goals": [
                {"position": [-3.0, 4.3, -2.5], "rotation": [0.0, 0.0, 0.0, 1.0], "hfov": 65,
                 "image_dimensions": [512, 512], "frame_coverage": 0.252, "object_coverage": 0.858},
                {"position": [-2.4, 4.1, -2.6], "rotation": [-0.1305262, 0.0, 0.0, 0.9914449], "hfov": 90,
                 "image_dimensions": [120, 160], "frame_coverage": 0.1, "object_coverage": 0.9},
            ],
        },
    },
    "episodes": [
        {"episode_id": "331", "scene_id": SCENE,
         "scene_dataset_config": "./data/scene_datasets/hm3d_v0.2/hm3d_annotated_basis.scene_dataset_config.json",
         "additional_obj_config_paths": [], "start_position": [-5.9657, 3.1634, -3.3209],
         "start_rotation": [0, 0.8907, 0, 0.4547],
         "info": {"geodesic_distance": 5.6693, "euclidean_distance": 4.597}, "goals": [],
         "object_category": "tv_monitor", "goal_object_id": "10", "goal_image_id": 1},
    ],
}


def _split(tmp_path, content=CONTENT, top=None):
    d = tmp_path / "val_mini"
    (d / "content").mkdir(parents=True, exist_ok=True)
    (d / "val_mini.json.gz").write_bytes(gzip.compress(json.dumps(top or {"episodes": []}).encode()))
    (d / "content" / "TEEsavR23oF.json.gz").write_bytes(gzip.compress(json.dumps(content).encode()))
    return d / "val_mini.json.gz"


def test_reads_the_published_layout(tmp_path):
    ds = load_instance_imagenav(_split(tmp_path))
    (ep,) = ds.episodes
    assert isinstance(ep, InstanceImageEpisode)
    assert (ep.episode_id, ep.goal_object_id, ep.goal_image_id, ep.goal_key) == ("331", "10", 1, "TEEsavR23oF_10")
    assert ep.object_category == "tv_monitor"
    (goal,) = ep.goals
    assert goal.object_id == 10 and goal.object_surface_area == 2.308 and len(goal.image_goals) == 2
    img = ep.image_goal
    assert (img.height, img.width, img.hfov_deg) == (120, 160, 90.0)
    assert img.rotation == (-0.1305262, 0.0, 0.0, 0.9914449) and img.position == (-2.4, 4.1, -2.6)
    # distance is measured to the view points (distance_to: VIEW_POINTS), not to the object centre
    assert ep.goal_positions().tolist() == [[-3.0, 3.16, -2.0], [-2.5, 3.16, -2.1]]
    assert ep.extra["scene_dataset_config"].endswith("scene_dataset_config.json")


def test_goal_key_strips_glb_then_basis():
    assert instance_goal_key("a/b/X.basis.glb", "3") == "X_3"
    assert instance_goal_key("X.glb", 3) == "X_3"
    assert instance_goal_key("X.ply", "3") == "X.ply_3"


def _error(tmp_path, mutate):
    content = copy.deepcopy(CONTENT)
    mutate(content)
    with pytest.raises(EpisodeError) as info:
        load_instance_imagenav(_split(tmp_path, content))
    msg = str(info.value)
    assert "\n" not in msg and "TEEsavR23oF.json.gz" in msg
    return msg


def test_missing_goal_key_is_one_line(tmp_path):
    msg = _error(tmp_path, lambda c: c["episodes"][0].update(goal_object_id="11"))
    assert "episode 331" in msg and "'TEEsavR23oF_11'" in msg and "goal_object_id" in msg


def test_missing_object_id_is_one_line(tmp_path):
    msg = _error(tmp_path, lambda c: c["episodes"][0].pop("goal_object_id"))
    assert "episode 331: goal_object_id" in msg


def test_image_index_out_of_range_is_one_line(tmp_path):
    msg = _error(tmp_path, lambda c: c["episodes"][0].update(goal_image_id=2))
    assert "goal_image_id 2" in msg and "image_goals has 2 entries" in msg
    msg = _error(tmp_path, lambda c: c["episodes"][0].update(goal_image_id=-1))
    assert "goal_image_id -1" in msg
    msg = _error(tmp_path, lambda c: c["episodes"][0].pop("goal_image_id"))
    assert "goal_image_id must be an integer" in msg


@pytest.mark.parametrize("field, value, words", [
    ("hfov", 0, "hfov"), ("hfov", None, "'hfov'"), ("image_dimensions", [512], "image_dimensions"),
    ("image_dimensions", [10 ** 6, 512], "image_dimensions"), ("rotation", [0, 0, 0, 2], "unit quaternion"),
    ("position", [0, "a", 0], "position"),
])
def test_bad_image_goal_names_the_field(tmp_path, field, value, words):
    msg = _error(tmp_path, lambda c: c["goals"]["TEEsavR23oF_10"]["image_goals"][1].update({field: value}))
    assert "goals['TEEsavR23oF_10']: image_goals[1]" in msg and words in msg


def test_goal_without_view_points_or_images(tmp_path):
    msg = _error(tmp_path, lambda c: c["goals"]["TEEsavR23oF_10"].update(view_points=[]))
    assert "view_points" in msg
    msg = _error(tmp_path, lambda c: c["goals"]["TEEsavR23oF_10"].pop("image_goals"))
    assert "'image_goals'" in msg


def test_file_without_episodes_gives_no_goals(tmp_path):
    # from_json returns before reading goals when a file has no episodes (instance_image_nav_dataset.py L72)
    ds = load_instance_imagenav(_split(tmp_path, {"episodes": [], "goals": "not even a dict"}))
    assert ds.episodes == []


def test_oversized_file_is_refused(tmp_path):
    with pytest.raises(EpisodeError, match="larger than|too large|exceeds"):
        load_instance_imagenav(_split(tmp_path), cap=100)


def test_measures_are_habitats_at_01m():
    assert SUCCESS_DISTANCE == 0.1
    m = instance_imagenav_metrics(True, 0.09, 4.0, 5.0)
    assert m == {"success": 1.0, "spl": 0.8, "soft_spl": pytest.approx((1 - 0.09 / 4) * 0.8),
                 "distance_to_goal": 0.09}
    assert instance_imagenav_metrics(True, 0.1, 4.0, 4.0)["success"] == 0.0  # strict <
    assert instance_imagenav_metrics(False, 0.0, 4.0, 4.0)["success"] == 0.0  # STOP needed
    assert instance_imagenav_metrics(False, 2.0, 4.0, 8.0)["soft_spl"] == 0.25  # SoftSPL needs no STOP
