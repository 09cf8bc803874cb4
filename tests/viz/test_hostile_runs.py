"""Run directories and episode files from strangers: names from data never become paths, and the report
escapes every string it did not write and refuses a record of the wrong type in one line."""

import gzip
import json
import os

import pytest

from navbench.cli import main
from navbench.eval.runner import read_records
from navbench.safeio import UniqueNames, child, safe_name

EVIL = '<img src=x onerror=alert(1)>'


def _files(root):
    return sorted(p.relative_to(root).as_posix() for p in root.rglob("*"))


def test_safe_names_are_plain_distinct_and_stable(tmp_path):
    ids = ["0", "12", "../../etc/passwd", "/abs/path", "..", ".", "", "a/b", "a_b", "a\\b", "x" * 300, "CON",
           "ep\0", "\u202eevil", ".hidden"]
    names = UniqueNames()
    made = [names(i) for i in ids]
    assert len({m.lower() for m in made}) == len(ids)
    for i, m in zip(ids, made):
        assert child(tmp_path, m).parent == tmp_path and m not in (".", "..") and len(m) <= 100
        assert m == safe_name(i) or m.startswith(safe_name(i))
    assert made[:2] == ["0", "12"] and safe_name("a/b") == safe_name("a/b")
    with pytest.raises(ValueError):
        child(tmp_path, "../x")


def _hostile_episodes(objectnav_file, tmp_path, ids):
    doc = json.loads(gzip.decompress(objectnav_file.read_bytes()))
    for ep, eid in zip(doc["episodes"], ids):
        ep["episode_id"] = eid
    path = tmp_path / "hostile.json.gz"
    path.write_bytes(gzip.compress(json.dumps(doc).encode()))
    return path


@pytest.mark.slow
def test_episode_ids_that_are_paths_stay_inside_the_run(objectnav_file, tmp_path):
    absolute = f"/tmp/nbsec{os.getpid()}"  # episode ids are kept to 40 characters
    ids = ["../../escaped", absolute + "/abs", "sub/dir/x"]
    episodes = _hostile_episodes(objectnav_file, tmp_path, ids)
    out = tmp_path / "run"
    assert main(["run", "--episodes", str(episodes), "--agent", "oracle", "--limit", "3", "--workers", "1",
                 "--out", str(out), "-q", "--video", "all"]) == 0
    assert main(["viz", str(out), "--episode", ids[0], "--episode", ids[1], "--size", "64"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["hostile.json.gz", "run"]
    assert not os.path.exists(absolute) and not (tmp_path.parent / "escaped.mp4").exists()
    videos, pngs = _files(out / "videos"), _files(out / "viz")
    assert len(videos) == 3 and all("/" not in v and v.endswith(".mp4") for v in videos)
    assert len(pngs) == 2 and all("/" not in p for p in pngs)


def _edit_records(run, change):
    recs = read_records(run / "episodes.jsonl")
    change(recs)
    (run / "episodes.jsonl").write_text("".join(json.dumps(r) + "\n" for r in recs))


def test_report_escapes_strings_from_records_and_config(run_copy, tmp_path):
    def change(recs):
        recs[0]["object_category"] = "<script>alert(1)</script>"
        recs[1].update(failed=False, skipped=True, object_category=EVIL)
    _edit_records(run_copy, change)
    cfg = json.loads((run_copy / "config.json").read_text())
    cfg["label"] = "</script><script>alert(2)</script>"
    (run_copy / "config.json").write_text(json.dumps(cfg))
    out = tmp_path / "report.html"
    assert main(["report", str(run_copy), "-o", str(out)]) == 0
    page = out.read_text()
    assert "<script>alert" not in page and "<img src=x" not in page
    assert page.count("<script") == 2  # the page's own: the JSON of the runs and the filter script


@pytest.mark.parametrize("field,value", [("num_steps", "12"), ("spl", "0.5"), ("success", "yes"),
                                         ("episode_id", {"a": 1}), ("trace", "x"), ("collisions", 1.5)])
def test_report_refuses_a_record_of_the_wrong_type_in_one_line(field, value, run_copy, tmp_path, capsys):
    def change(recs):
        recs[1][field] = value
    _edit_records(run_copy, change)
    assert main(["report", str(run_copy), "-o", str(tmp_path / "r.html")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(run_copy / "episodes.jsonl") in err[0] and "record 2" in err[0], err


def test_report_refuses_records_that_are_not_objects(run_copy, tmp_path, capsys):
    (run_copy / "episodes.jsonl").write_text('[1, 2]\n')
    assert main(["report", str(run_copy), "-o", str(tmp_path / "r.html")]) == 2
    assert "record 1" in capsys.readouterr().err
