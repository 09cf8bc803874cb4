"""The shared progress helper: items pass through; off a terminal, one plain line per 10 %."""

import os

from navbench.loop_progress import progress, silenced


def test_plain_lines_off_a_terminal(capsys, monkeypatch):
    monkeypatch.delenv("NAVBENCH_PROGRESS", raising=False)
    assert list(progress(iter(range(20)), 20, "work")) == list(range(20))
    lines = capsys.readouterr().err.splitlines()
    assert lines[0] == "work: 2/20 (10%)" and lines[-1] == "work: 20/20 (100%)" and len(lines) == 10


def test_off_by_environment(capsys, monkeypatch):
    monkeypatch.setenv("NAVBENCH_PROGRESS", "0")
    assert list(progress([1, 2, 3], desc="x")) == [1, 2, 3]
    assert capsys.readouterr().err == ""


def test_silenced_block_and_restored_after(capsys, monkeypatch):
    monkeypatch.setenv("NAVBENCH_PROGRESS", "1")
    with silenced():
        assert list(progress(range(3), desc="x")) == [0, 1, 2]
    assert capsys.readouterr().err == ""
    assert os.environ["NAVBENCH_PROGRESS"] == "1"
    list(progress(range(3), desc="x"))
    assert capsys.readouterr().err
