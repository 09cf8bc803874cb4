"""Each failure the fuzz suite found, as a plain test with its minimal input: exit 2 and one line naming
the file (through the CLI where a command reads the file), or the reader's one-line error."""

from __future__ import annotations

import gzip
import json
import shutil

import pytest
import torch
import trimesh
from fuzzlib import assert_cli_error, check_user_error, run_cli

from navbench.episodes.io import load_dataset
from navbench.localize.goat import load_goat_split
from navbench.paths import ROOT
from navbench.policy.checkpoint import load_checkpoint, read_checkpoint, save_checkpoint
from navbench.policy.net import PointNavResNetPolicy, PolicyNetConfig
from navbench.scene.asset import load_scene
from navbench.scene.cache import load_scene_and_navgrid

EPISODE = {"episode_id": "0", "scene_id": "houses/val/house_008.glb", "start_position": [0, 0, 0],
           "start_rotation": [0, 0, 0, 1], "goals": [{"position": [1, 0, 1], "radius": None}]}
RUN = ROOT / "results" / "runs" / "objectnav" / "val_unseen" / "memory"


def _episodes_error(tmp_path, doc, name="ep.json"):
    path = tmp_path / name
    path.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    assert_cli_error(["run", "--episodes", str(path), "--limit", "1"], path)
    with pytest.raises(ValueError) as exc:
        load_dataset(path)
    check_user_error(exc.value, path)


def test_episode_that_is_not_an_object_is_refused(tmp_path):
    _episodes_error(tmp_path, {"episodes": [[]]})


def test_episode_without_goals_is_refused(tmp_path):
    _episodes_error(tmp_path, {"episodes": [dict(EPISODE, goals=[])]})


def test_goal_radius_that_is_not_a_number_is_refused(tmp_path):
    _episodes_error(tmp_path, {"episodes": [dict(EPISODE, goals=[{"position": [1, 0, 1], "radius": "x"}])]})


def test_deeply_nested_episode_file_is_refused(tmp_path):
    _episodes_error(tmp_path, '{"episodes": ' + "[" * 100_000 + "]" * 100_000 + "}")


def test_truncated_goat_split_is_refused(tmp_path):
    path = tmp_path / "g.json.gz"
    path.write_bytes(gzip.compress(b'{"subtasks": []}')[:-4])
    assert_cli_error(["localize", "--split", str(path)], path)


def test_goat_subtask_of_unknown_type_is_refused(tmp_path):
    path = tmp_path / "g.json.gz"
    path.write_bytes(gzip.compress(json.dumps({"subtasks": [
        {"id": "a", "scene_id": "s", "type": None, "query": "x", "target_ids": [1], "gt_positions": [[0, 0, 0]]}
    ]}).encode()))
    with pytest.raises(ValueError) as exc:
        load_goat_split(path)
    check_user_error(exc.value, path)


def _box_scene(tmp_path, size=4.0):
    floor = trimesh.creation.box((size, 0.1, size))
    path = tmp_path / "room.glb"
    path.write_bytes(trimesh.Scene(floor).export(file_type="glb"))
    return path


def test_semantic_annotation_not_an_object_is_refused(tmp_path):
    glb = _box_scene(tmp_path)
    sem = tmp_path / "room.semantic.json"
    sem.write_text("[]")  # a JSON array where an object is expected
    with pytest.raises(ValueError) as exc:
        load_scene(glb)
    check_user_error(exc.value, sem)
    assert_cli_error(["memory", "build", "--scene", str(glb), "--out", str(tmp_path / "m")], sem)


def test_scene_without_floor_names_the_file(tmp_path):
    path = tmp_path / "pillar.glb"
    path.write_bytes(trimesh.Scene(trimesh.creation.box((0.5, 2.0, 0.5))).export(file_type="glb"))
    with pytest.raises(ValueError) as exc:
        load_scene_and_navgrid(path, use_cache=False)
    check_user_error(exc.value, path)


def test_scene_of_huge_extent_is_refused_before_allocating(tmp_path):
    path = _box_scene(tmp_path, size=1e6)
    with pytest.raises(ValueError) as exc:
        load_scene_and_navgrid(path, use_cache=False)
    check_user_error(exc.value, path)
    assert "grid cells" in str(exc.value)


@pytest.fixture
def small_checkpoint(tmp_path):
    cfg = PolicyNetConfig(hidden_size=16, num_layers=1, base_planes=8, ngroups=4)
    return save_checkpoint(tmp_path / "small.pth", PointNavResNetPolicy(cfg), {})


@pytest.mark.parametrize("change", ["int64", "nan"])
def test_checkpoint_with_integer_or_nan_weights_is_refused(change, small_checkpoint, tmp_path):
    state = dict(read_checkpoint(small_checkpoint).state_dict)
    key = "critic.fc.bias"
    state[key] = state[key].long() if change == "int64" else torch.full_like(state[key].float(), float("nan"))
    path = tmp_path / f"{change}.pth"
    torch.save({"state_dict": state, "config": {}}, path)
    with pytest.raises(ValueError) as exc:
        load_checkpoint(path)
    check_user_error(exc.value, path)
    assert key in str(exc.value)


@pytest.mark.parametrize("name,text", [("config.json", "null"), ("summary.json", "null"),
                                       ("summary.json", '{"success": "x"}'), ("config.json", '{"seed": []}')])
def test_table_refuses_malformed_run_files(name, text, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(RUN, run)
    (run / name).write_text(text)
    assert_cli_error(["table", str(run)], run / name)


def test_table_first_with_corrupt_config_names_it(tmp_path):
    run = tmp_path / "run"
    shutil.copytree(RUN, run)
    (run / "config.json").write_text("")
    assert_cli_error(["table", str(run), "--first", "5"], run / "config.json")


def test_usage_errors_are_one_line():
    assert_cli_error(["run", "--task", "nosuch"], "--task")
    assert_cli_error(["nosuch"])


@pytest.mark.parametrize("argv", [["run", "--limit", "-1"], ["run", "--workers", "0"],
                                  ["run", "--success-distance", "nan"], ["bench", "--seconds", "inf"],
                                  ["localize", "-k", "0"], ["run", "--seed", "-1"]], ids=" ".join)
def test_bad_counts_and_distances_are_refused_at_parse_time(argv):
    assert_cli_error(argv, argv[1])


def test_memory_build_unknown_perception_is_one_line():
    assert_cli_error(["memory", "build", "--scene", "houses/val/house_008.glb", "--perception", "nosuch"], "nosuch")


def test_train_config_directory_is_one_line(tmp_path):
    assert_cli_error(["train", "--config", str(tmp_path)], tmp_path)


@pytest.mark.parametrize("key", ["critic.fc.weight", "action_distribution.linear.weight",
                                 "net.visual_encoder.backbone.conv1.0.weight"])
def test_checkpoint_with_a_0d_tensor_where_a_matrix_belongs_is_refused(key, small_checkpoint, tmp_path):
    state = dict(read_checkpoint(small_checkpoint).state_dict)
    state[key] = torch.tensor(1.0)
    path = tmp_path / "scalar.pth"
    torch.save({"state_dict": state, "config": {}}, path)
    with pytest.raises(ValueError) as exc:
        load_checkpoint(path)
    check_user_error(exc.value, path)


@pytest.mark.parametrize("option", ["perception", "noise", "checkpoint", "decoding"])
def test_table_reads_a_null_agent_option(option, tmp_path):
    run = tmp_path / "run"
    shutil.copytree(RUN, run)
    cfg = json.loads((run / "config.json").read_text())
    cfg["agent_options"][option] = None
    (run / "config.json").write_text(json.dumps(cfg))
    code, out, err = run_cli(["table", str(run)])
    assert code == 0 and not err, err
    assert "oracle" in out
