"""A split's identity covers every file it is read from (habitat-lab's content/ files, VLN-CE's gt file), and
compare refuses two runs whose splits differ in any of them."""

import gzip
import json
import shutil

from navbench.cli import main
from navbench.eval.provenance import split_entry
from navbench.eval.runner import RunConfig
from navbench.paths import RESULTS_DIR, SCENES_DIR, split_file

GOAT_RUN = RESULTS_DIR / "runs" / "goat" / "val" / "memory"


def _copy_split(task, dst):
    """The bundled val split of ``task`` (its episode file and content/ folder) copied to ``dst``."""
    shutil.copytree(split_file(task, "val").parent, dst)
    return dst / "val.json.gz"


def _edit_content(path):
    """One content file's first episode moved 1 cm: the same ids, another episode."""
    doc = json.loads(gzip.decompress(path.read_bytes()))
    doc["episodes"][0]["start_position"][0] += 0.01
    path.write_bytes(gzip.compress(json.dumps(doc).encode(), mtime=0))


def _run_on(src, dst, episodes_entry):
    """The run ``src`` copied to ``dst``, its provenance recording ``episodes_entry`` for its split."""
    shutil.copytree(src, dst, ignore=shutil.ignore_patterns("videos"))
    doc = json.loads((dst / "provenance.json").read_text())
    doc["files"]["episodes"] = {"path": "episodes/goat/val/val.json.gz", "root": "navbench", **episodes_entry}
    (dst / "provenance.json").write_text(json.dumps(doc))
    return dst


def test_a_split_differing_only_in_content_gets_another_identity(tmp_path):
    a, b = _copy_split("goat", tmp_path / "a"), _copy_split("goat", tmp_path / "b")
    assert split_entry("goat", a) == split_entry("goat", b)  # where a copy lies does not matter
    _edit_content(tmp_path / "b" / "content" / "house_009.json.gz")
    ea, eb = split_entry("goat", a), split_entry("goat", b)
    assert ea["sha256"] == eb["sha256"]  # the 53-byte stub is the same
    assert ea["split_sha256"] != eb["split_sha256"]
    assert sorted(ea["split_files"]) == [f"content/house_{k:03d}.json.gz" for k in range(8, 12)]
    assert [n for n in ea["split_files"] if ea["split_files"][n] != eb["split_files"][n]] == \
        ["content/house_009.json.gz"]


def test_the_bundled_goat_and_instance_imagenav_splits_differ():
    goat = split_entry("goat", split_file("goat", "val"))
    iin = split_entry("instance_imagenav", split_file("instance_imagenav", "val"))
    assert goat["sha256"] == iin["sha256"]  # both stubs are `{"episodes": []}`-like
    assert goat["split_sha256"] != iin["split_sha256"]


def test_vlnce_gt_file_is_part_of_the_split(tmp_path):
    shutil.copytree(split_file("r2r_ce", "val").parent, tmp_path / "r2r")
    path = tmp_path / "r2r" / "val.json.gz"
    before = split_entry("r2r_ce", path)
    assert list(before["split_files"]) == ["val_gt.json.gz"]
    gt = tmp_path / "r2r" / "val_gt.json.gz"
    gt.write_bytes(gzip.compress(gzip.decompress(gt.read_bytes()) + b" ", mtime=0))
    assert split_entry("r2r_ce", path)["split_sha256"] != before["split_sha256"]
    # a --gt given elsewhere is hashed under its own name
    other = tmp_path / "mine_gt.json.gz"
    shutil.copy(gt, other)
    assert list(split_entry("r2r_ce", path, other)["split_files"]) == ["mine_gt.json.gz"]
    # a task without such files: the episode file's sha256 is the split's
    pointnav = split_entry("pointnav", split_file("pointnav", "val"))
    assert "split_files" not in pointnav and pointnav["split_sha256"] == pointnav["sha256"]


def test_provenance_records_the_split_files_of_a_run():
    from navbench.eval.provenance import provenance

    cfg = RunConfig(task="r2r_ce", split="val", agent="vln_oracle", episodes=str(split_file("r2r_ce", "val")),
                    scene_dir=str(SCENES_DIR), success_distance=3.0, limit=1)
    entry = provenance(cfg, [])["files"]["episodes"]
    assert entry["path"] == "episodes/r2r_ce/val/val.json.gz" and list(entry["split_files"]) == ["val_gt.json.gz"]


def test_compare_refuses_runs_whose_splits_differ_only_in_content(tmp_path, capsys):
    a, b = _copy_split("goat", tmp_path / "a"), _copy_split("goat", tmp_path / "b")
    _edit_content(tmp_path / "b" / "content" / "house_009.json.gz")
    base = _run_on(GOAT_RUN, tmp_path / "base", split_entry("goat", a))
    other = _run_on(GOAT_RUN, tmp_path / "other", split_entry("goat", b))
    assert main(["compare", str(base), str(other), "--metric", "success"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{base} vs {other}: scored on different episode files" in err[0]
    assert "content/house_009.json.gz differ" in err[0] and "split sha256" in err[0]
    same = _run_on(GOAT_RUN, tmp_path / "same", split_entry("goat", a))
    assert main(["compare", str(base), str(same), "--metric", "success"]) == 0
    assert "differs:" not in capsys.readouterr().out


def test_a_run_recorded_before_split_hashing_pairs_on_its_episode_file_and_says_so(tmp_path, capsys):
    # the committed GOAT run records the stub's sha256 only
    new = _run_on(GOAT_RUN, tmp_path / "new", split_entry("goat", split_file("goat", "val")))
    assert main(["compare", str(GOAT_RUN), str(new), "--metric", "success"]) == 0
    out = capsys.readouterr().out
    assert "differs: split files: BASE recorded the episode file's sha256 only" in out
    assert "paired on 40 episodes" in out


def test_protocol_names_the_split_identity(tmp_path, capsys):
    entry = split_entry("goat", split_file("goat", "val"))
    run = _run_on(GOAT_RUN, tmp_path / "run", entry)
    assert main(["protocol", str(run)]) == 0
    text = capsys.readouterr().out
    assert f"(sha256 {entry['sha256']}; with the 4 files read beside it, split sha256 {entry['split_sha256']})" in text
    assert main(["protocol", str(run), "--format", "json"]) == 0
    facts = json.loads(capsys.readouterr().out)["episodes"]
    assert facts["split_sha256"] == entry["split_sha256"] and len(facts["split_files"]) == 4
