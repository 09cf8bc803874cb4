"""A run directory from someone else: planted symlinks redirect no write, oversized or deeply nested records
are one line, and a killed run's lock is still taken over."""

import json

from navbench.cli import main
from navbench.eval.rundir import RunError, read_records, write_atomic


def test_planted_temporary_symlinks_redirect_no_write(tmp_path, pointnav_file):
    victim = tmp_path / "victim.txt"
    victim.write_text("untouched")
    out = tmp_path / "run"
    out.mkdir()
    for name in (".config.json.tmp", ".episodes.jsonl.tmp", ".summary.json.tmp"):
        (out / name).symlink_to(victim)
    assert main(["run", "--episodes", str(pointnav_file), "--agent", "oracle", "--limit", "1", "--workers", "1",
                 "--out", str(out), "-q"]) == 0
    assert victim.read_text() == "untouched"
    assert json.loads((out / "config.json").read_text())["agent"] == "oracle"
    assert not (out / "config.json").is_symlink() and len(read_records(out / "episodes.jsonl")) == 1


def test_write_atomic_never_follows_a_link(tmp_path):
    victim = tmp_path / "victim"
    victim.write_text("x")
    target = tmp_path / "config.json"
    (tmp_path / ".config.json.tmp").symlink_to(victim)
    write_atomic(target, "{}")
    assert victim.read_text() == "x" and target.read_text() == "{}"


def test_records_over_the_cap_and_deep_records_are_one_line(tmp_path, monkeypatch):
    path = tmp_path / "episodes.jsonl"
    path.write_text("[" * 100_000 + "]" * 100_000 + "\n" + '{"episode_id": "1"}\n')
    try:
        read_records(path)
        raise AssertionError("a corrupt line was read")
    except RunError as exc:
        assert "line 1 is corrupt" in str(exc)
    monkeypatch.setenv("NAVBENCH_MAX_INPUT_BYTES", "1K")
    path.write_text('{"episode_id": "1", "scene_id": "s"}\n' * 100)
    try:
        read_records(path)
        raise AssertionError("an oversized file was read")
    except RunError as exc:
        assert str(path) in str(exc) and "larger than 1 KiB" in str(exc)


def test_a_killed_runs_lock_is_taken_over(tmp_path, pointnav_file, capsys):
    out = tmp_path / "run"
    out.mkdir()
    (out / ".lock").write_text(json.dumps({"pid": 2 ** 22 + 12345, "host": __import__("socket").gethostname()}))
    assert main(["run", "--episodes", str(pointnav_file), "--agent", "oracle", "--limit", "1", "--workers", "1",
                 "--out", str(out), "-q"]) == 0
    assert "taking over a stale lock" in capsys.readouterr().err
