"""provenance.json: the protocol and its id, versions and checksums; tables, compare and merge refuse to mix
protocols."""

import hashlib
import json
import shutil

import pytest

from navbench.agents.pointnav import DEFAULT_CHECKPOINT
from navbench.agents.registry import make_oracle
from navbench.cli import main
from navbench.episodes.generate import SPLIT_VERSION
from navbench.episodes.io import load_dataset
from navbench.eval.merge import merge
from navbench.eval.provenance import (
    PROVENANCE,
    ProtocolError,
    check_same_protocol,
    config_protocol,
    protocol,
    protocol_id,
    provenance,
    run_protocol,
)
from navbench.eval.runner import RunConfig, RunError, read_records, run
from navbench.eval.stats import intervals
from navbench.eval.table import group_frame, render, runs_frame
from navbench.paths import RESULTS_DIR, SCENES_DIR, split_file

VAL = split_file("pointnav", "val")
RUNS = RESULTS_DIR / "runs"


def _cfg(**kw):
    base = dict(task="pointnav", split="val", agent="oracle", episodes=str(VAL), scene_dir=str(SCENES_DIR),
                success_distance=0.2, limit=3)
    return RunConfig(**{**base, **kw})


def _sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_protocol_id_is_stable_and_changes_with_the_rules():
    a = protocol_id(config_protocol(_cfg()))
    assert a == protocol_id(config_protocol(_cfg(seed=5, envs_per_worker=2, agent="pointnav")))  # not protocol
    assert a != protocol_id(config_protocol(_cfg(success_distance=0.36)))
    assert a != protocol_id(config_protocol(_cfg(env={"max_steps": 200})))
    assert a != protocol_id(config_protocol(_cfg(env={"forward_step": 0.1})))
    assert a == protocol_id(config_protocol(_cfg(env={"rgb": False})))  # which images render is the agent's
    with pytest.raises(ProtocolError, match="EnvConfig"):
        config_protocol(_cfg(env={"no_such_field": 1}))


def test_provenance_checksums_versions_and_relative_paths():
    eps = load_dataset(VAL).episodes[:60]
    doc = provenance(_cfg(agent="pointnav"), eps)
    files = doc["files"]
    assert files["episodes"] == {"path": "episodes/pointnav/val/val.json.gz", "root": "navbench", "sha256": _sha(VAL),
                                 "split_sha256": _sha(VAL), "split_version": SPLIT_VERSION}  # a one-file split
    assert files["checkpoint"]["sha256"] == _sha(DEFAULT_CHECKPOINT)
    assert files["checkpoint"]["path"] == "policies/pointnav_navbench.pth"
    assert set(files["scenes"]) == {e.scene_id for e in eps} and len(files["scenes"]) == 2
    sid = eps[0].scene_id
    assert files["scenes"][sid]["sha256"] == _sha(SCENES_DIR / sid)
    semantic = (SCENES_DIR / sid).with_suffix(".semantic.json")
    assert files["scenes"][sid]["sidecars"] == {semantic.name: _sha(semantic)}
    assert set(doc["versions"]) == {"python", "torch", "numpy", "gymnasium", "pyrender", "trimesh"}
    assert doc["cpu"]["model"] and doc["opengl_renderer"] and doc["navbench"]["version"]
    assert doc["protocol_id"] == protocol_id(doc["protocol"])
    assert "checkpoint" not in provenance(_cfg(), eps)["files"]  # the oracle has none


def test_a_run_records_provenance_and_intervals_that_reproduce(tmp_path):
    a = run(_cfg(), make_oracle, tmp_path / "a")
    b = run(_cfg(), make_oracle, tmp_path / "b")
    pa, pb = (json.loads((tmp_path / d / PROVENANCE).read_text()) for d in ("a", "b"))
    assert pa["protocol_id"] == pb["protocol_id"] == a["protocol_id"] == b["protocol_id"]
    assert pa["files"]["episodes"]["sha256"] == _sha(VAL)
    assert a["ci95"] == intervals(read_records(tmp_path / "a" / "episodes.jsonl"))
    assert a["ci95"]["spl"][0] <= a["spl"] <= a["ci95"]["spl"][1]
    c = run(_cfg(success_distance=0.3), make_oracle, tmp_path / "c")
    assert c["protocol_id"] != a["protocol_id"]
    # a resumed run scored under another protocol than its provenance says is refused
    doc = dict(pa, protocol_id="0" * 12)
    (tmp_path / "a" / PROVENANCE).write_text(json.dumps(doc))
    with pytest.raises(RunError, match="protocol"):
        run(_cfg(), make_oracle, tmp_path / "a", resume=True)


def test_runs_without_provenance_get_a_derived_protocol_never_taken_for_todays(tmp_path):
    d = tmp_path / "old"
    shutil.copytree(RUNS / "objectnav" / "val_unseen" / "frontier", d, ignore=shutil.ignore_patterns("videos"))
    (d / PROVENANCE).unlink(missing_ok=True)
    proto = run_protocol(d)
    cfg = json.loads((d / "config.json").read_text())
    assert proto.pop("derived") is True
    today = config_protocol(RunConfig(**{k: v for k, v in cfg.items() if k in RunConfig.__dataclass_fields__}))
    assert today.pop("navigability") >= 2
    assert proto == today  # every rule config.json states; not which navigability rules it ran under
    with pytest.raises(ProtocolError, match="navigability"):
        check_same_protocol([RUNS / "objectnav" / "val_unseen" / "memory", d])


def test_table_shows_runs_under_different_protocols_and_names_what_differs(copy_run, capsys):
    """A table puts runs under different protocols side by side: the protocol's id and each field that
    differs as columns (a condition a protocol leaves out shows its default), and a note; compare refuses."""
    mem = RUNS / "objectnav" / "val_unseen" / "memory"
    far = copy_run(RUNS / "objectnav/val_unseen/frontier", "frontier", success_distance=1.0)
    df = runs_frame([mem, far], wide=False)
    assert list(df["success_distance"]) == ["0.25", "1.0"] and df["protocol"].nunique() == 2
    assert main(["table", str(mem), str(far)]) == 0
    text = capsys.readouterr().out
    head = text.splitlines()[0]
    assert "| protocol " in head and " success_distance |" in head
    assert "differ in success_distance (a column each)" in text and "navbench compare" in text
    assert main(["compare", str(mem), str(far)]) == 2
    assert "success_distance" in capsys.readouterr().err
    noisy = copy_run(RUNS / "objectnav/val_unseen/frontier", "noisy")
    doc = json.loads((noisy / PROVENANCE).read_text())
    doc["protocol"]["gps_compass"] = False  # a realistic condition, in the protocol only when on
    (noisy / PROVENANCE).write_text(json.dumps(doc))
    assert list(runs_frame([mem, noisy], wide=False)["gps_compass"]) == ["true", "false"]
    # by scene too
    assert set(group_frame([mem, far], "scene")["success_distance"]) == {"0.25", "1.0"}


def test_table_shows_intervals_from_summary_or_records_in_every_format(copy_run):
    old = copy_run(RUNS / "objectnav/val_unseen/frontier", "frontier")  # a summary.json written without ci95
    s = json.loads((old / "summary.json").read_text())
    s.pop("ci95")
    (old / "summary.json").write_text(json.dumps(s))
    new = copy_run(RUNS / "objectnav/val_unseen/memory", "memory")
    s = json.loads((new / "summary.json").read_text())
    s["ci95"] = intervals(read_records(new / "episodes.jsonl"))
    (new / "summary.json").write_text(json.dumps(s))
    df = runs_frame([old, new], wide=False)
    want = intervals(read_records(old / "episodes.jsonl"))["spl"]
    assert [df.loc[0, "SPL lo"], df.loc[0, "SPL hi"]] == pytest.approx([100 * want[0], 100 * want[1]])
    assert f"{df.loc[1, 'SPL']:.1f} [{df.loc[1, 'SPL lo']:.1f}, {df.loc[1, 'SPL hi']:.1f}]" in render(df)
    assert "SPL lo,SPL hi" in render(df, "csv").splitlines()[0]
    assert "[" in render(df, "latex")
    by_scene = group_frame([old], "scene")
    assert len(by_scene) == 4 and set(by_scene["episodes"]) == {40}
    by_cat = group_frame([old], "category")
    assert by_cat["episodes"].sum() == 160 and "SR lo" in by_cat.columns


def test_merge_refuses_shards_under_different_protocols(tmp_path):
    dirs = []
    for i in (1, 2):
        d = tmp_path / f"s{i}"
        run(_cfg(shard=f"{i}/2"), make_oracle, d)
        dirs.append(d)
    merge(dirs, tmp_path / "ok")
    assert json.loads((tmp_path / "ok" / PROVENANCE).read_text())["protocol_id"] == \
        json.loads((dirs[0] / PROVENANCE).read_text())["protocol_id"]
    doc = json.loads((dirs[1] / PROVENANCE).read_text())
    doc["protocol"]["max_steps"] = 100
    (dirs[1] / PROVENANCE).write_text(json.dumps(doc))
    with pytest.raises(ProtocolError, match="max_steps 500 vs 100"):
        merge(dirs, tmp_path / "bad")


def _pointnav_file(path, starts):
    from navbench.episodes.io import save_dataset
    from navbench.episodes.types import Episode, EpisodeDataset, NavigationGoal
    eps = [Episode(episode_id=str(i), scene_id="house_008.glb", start_position=list(s),
                   start_rotation=[0.0, 0.0, 0.0, 1.0], goals=[NavigationGoal(position=[1.0, s[1], 1.0])])
           for i, s in enumerate(starts)]
    return save_dataset(EpisodeDataset(episodes=eps), path)


def test_a_multi_storey_episode_file_runs_under_the_storeys_navigability(tmp_path):
    from navbench.scene import MULTI_STOREY_NAVIGABILITY_VERSION, NAVIGABILITY_VERSION
    one = _pointnav_file(tmp_path / "one.json", [(0.0, 0.0, 0.0), (2.0, 0.15, 0.0)])  # a step, one storey
    two = _pointnav_file(tmp_path / "two.json", [(0.0, 0.0, 0.0), (2.0, 2.9, 0.0)])  # the storey above
    p1, p2 = config_protocol(_cfg(episodes=str(one))), config_protocol(_cfg(episodes=str(two)))
    assert p1["navigability"] == NAVIGABILITY_VERSION == 2 and p2["navigability"] == MULTI_STOREY_NAVIGABILITY_VERSION
    assert protocol_id(p1) == protocol_id(config_protocol(_cfg()))  # one storey: the id it always had
    # what a multi-storey run's protocol was before the layered surfaces were rebuilt: the grid's version
    assert protocol_id(p2) != protocol_id({**p2, "navigability": 2})
    # the agent's height decides what counts as another storey
    assert config_protocol(_cfg(episodes=str(two), env={"agent_height": 3.0}))["navigability"] == 2


def test_the_action_space_is_the_configurations_and_a_tilt_counts_only_with_a_look_action():
    four = ["STOP", "MOVE_FORWARD", "TURN_LEFT", "TURN_RIGHT"]
    assert protocol("objectnav", None)["actions"] == four and "tilt_angle_deg" not in protocol("objectnav", None)
    assert "tilt_angle_deg" not in protocol("objectnav", None, {"tilt_angle_deg": 30.0})  # nothing looks
    six = [*four, "LOOK_UP", "LOOK_DOWN"]
    looks = protocol("objectnav", None, {"actions": six, "tilt_angle_deg": 30.0})
    assert looks["actions"] == six and looks["tilt_angle_deg"] == 30.0
    assert protocol_id(looks) != protocol_id(protocol("objectnav", None, {"actions": six}))
    assert protocol_id(protocol("objectnav", None, {"actions": six})) != protocol_id(protocol("objectnav", None))


def test_provenance_names_torchs_build_and_the_dataset_releases_its_paths_tell(tmp_path):
    import torch

    from navbench.eval.provenance import dataset_versions, versions
    assert versions()["torch"] == torch.__version__
    ep = tmp_path / "data/datasets/objectnav/hm3d/v2/val/val.json.gz"
    scene = tmp_path / "data/scene_datasets/hm3d_v0.2/val/00800-TEEsavR23oF/TEEsavR23oF.basis.glb"
    assert dataset_versions(ep, [scene]) == {"episodes": "objectnav/hm3d/v2", "scenes": "hm3d/v0.2"}
    assert dataset_versions(tmp_path / "objectnav_hm3d_v1/val/val.json.gz", []) == {"episodes": "objectnav/hm3d/v1"}
    assert dataset_versions(VAL, [SCENES_DIR / "house_008.glb"]) == {}  # navbench's own: split_version says it
    # InstanceImageNav's and GOAT-Bench's releases, in habitat-challenge's and goat-bench's layouts
    iin = tmp_path / "habitat-challenge-data/data/datasets/instance_imagenav/hm3d/v3/val_mini/val_mini.json.gz"
    assert dataset_versions(iin, []) == {"episodes": "instance_imagenav/hm3d/v3"}
    assert dataset_versions(tmp_path / "data/datasets/goat_bench/hm3d/v1/val_seen/val_seen.json.gz", []) == \
        {"episodes": "goat_bench/hm3d/v1"}


def test_how_goal_images_are_rendered_is_part_of_an_image_tasks_protocol():
    from navbench.tasks import TASKS
    assert "goal_images" not in protocol("pointnav", None) and "goal_images" not in protocol("objectnav", None)
    for task in ("imagenav", "instance_imagenav", "goat"):
        assert protocol(task, None)["goal_images"] == TASKS[task].goal_images != ""
    assert "sha256(episode_id)" in protocol("imagenav", None)["goal_images"]  # not Python's salted hash
