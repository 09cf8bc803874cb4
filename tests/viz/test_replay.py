"""`navbench viz` replays a finished run from its records: the recorded path exactly, or one line and exit 2."""

import dataclasses
import json

import numpy as np
import pytest

from navbench.cli import main
from navbench.eval.runner import read_records
from navbench.viz.replay import Replayer, Run


def _write(run, records):
    (run / "episodes.jsonl").write_text("".join(json.dumps(r) + "\n" for r in records))


def test_records_carry_a_compact_trace(oracle_run):
    for r in read_records(oracle_run / "episodes.jsonl"):
        t = r["trace"]
        assert len(t["actions"]) == r["num_steps"] and set(t["actions"]) <= set("0123")
        assert len(t["poses"]) == r["num_steps"] + 1 and all(len(p) == 3 for p in t["poses"])
        assert t["actions"][-1] == "0" if r["stop_called"] else True
        # metres to mm, yaw to mrad
        assert all(round(v, 3) == v for p in t["poses"] for v in p)


def test_replay_reproduces_the_recorded_path(oracle_run, capsys):
    run = Run.load(oracle_run)
    rp = Replayer(run)
    for r in run.records:
        steps = list(rp.steps(r))
        assert len(steps) == r["num_steps"] + 1
        info = steps[-1][1]
        assert info["path_length"] == r["path_length"] and info["collisions"] == r["collisions"]
        assert info["distance_to_goal"] == r["distance_to_goal"]
    ids = [r["episode_id"] for r in run.records]
    assert main(["viz", str(oracle_run), "--episode", ids[0], "--episode", ids[1], "-o",
                 str(oracle_run / "maps")]) == 0
    out = capsys.readouterr().out
    assert out.count("path matches the record") == 2
    assert (oracle_run / "maps" / f"{ids[0]}.png").is_file()


def test_a_record_the_replay_does_not_match_is_refused(run_copy, capsys):
    recs = read_records(run_copy / "episodes.jsonl")
    recs[0]["trace"]["poses"][-1][0] += 0.01  # the last pose 1 cm off
    _write(run_copy, recs)
    assert main(["viz", str(run_copy), "--episode", recs[0]["episode_id"]]) == 2
    err = capsys.readouterr().err.strip()
    assert "leaves the recorded path at step" in err and len(err.splitlines()) == 1


def test_bad_input_is_one_line_and_exit_2(run_copy, tmp_path, capsys):
    assert main(["viz", str(run_copy), "--episode", "no-such-episode"]) == 2
    assert "no episode 'no-such-episode'" in capsys.readouterr().err
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["viz", str(empty), "--failures"]) == 2
    assert main(["report", str(empty), "-o", str(tmp_path / "r.html")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all("no episode records" in e for e in err)
    recs = read_records(run_copy / "episodes.jsonl")
    for r in recs:
        del r["trace"]
    _write(run_copy, recs)
    assert main(["viz", str(run_copy), "--episode", recs[0]["episode_id"]]) == 2
    err = capsys.readouterr().err.strip()
    assert "predates pose recording" in err and len(err.splitlines()) == 1


def test_map_marks_start_and_stop_where_the_trace_says(oracle_run):
    from navbench.viz.maps import episode_map
    from navbench.viz.topdown import START, STOP_MARK
    run = Run.load(oracle_run)
    rp = Replayer(run)
    r = run.records[0]
    view = None
    img = episode_map(rp, r, max_side=400, with_legend=False)
    view = rp.view(400)
    x0, z0, _ = r["trace"]["poses"][0]
    u, v = view.px(x0, z0)
    assert tuple(img[v, u]) == START
    x1, z1, _ = r["trace"]["poses"][-1]
    u, v = view.px(x1, z1)
    patch = img[v - 6:v + 7, u - 6:u + 7].reshape(-1, 3)
    assert (patch == np.array(STOP_MARK)).all(axis=1).any()


@pytest.mark.parametrize("explores,flag,shaded", [
    (True, [], True), (False, [], False), (True, ["--no-explored"], False), (False, ["--explored"], True)])
def test_the_explored_overlay_defaults_to_what_the_agents_spec_says(oracle_run, monkeypatch, tmp_path,
                                                                    explores, flag, shaded):
    """`navbench viz` shades the seen cells by default for an agent whose registry spec explores."""
    import navbench.viz.video
    from navbench.agents.registry import AGENTS

    monkeypatch.setitem(AGENTS, "oracle", dataclasses.replace(AGENTS["oracle"], explores=explores))
    calls = []
    monkeypatch.setattr(navbench.viz.video, "explored_mask", lambda rp, r: calls.append(r["episode_id"]))
    episode = read_records(oracle_run / "episodes.jsonl")[0]["episode_id"]
    assert main(["viz", str(oracle_run), "--episode", episode, *flag, "-o", str(tmp_path / "maps")]) == 0
    assert calls == ([episode] if shaded else [])
