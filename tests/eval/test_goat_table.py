"""python -m navbench.eval.goat_table: GOAT-Bench runs by subtask position and goal type."""

import json
import shutil

from navbench.episodes.goat import load_goat
from navbench.eval.goat_table import main, subtask_rows
from navbench.paths import RESULTS_DIR, split_file


def test_rows_follow_the_episodes_tasks_and_a_subtask_never_reached_fails(tmp_path, capsys):
    run = tmp_path / "oracle"
    shutil.copytree(RESULTS_DIR / "runs" / "goat" / "val" / "oracle", run)  # the committed run, its first two records
    recs = [json.loads(line) for line in (run / "episodes.jsonl").read_text().splitlines()[:2]]
    recs[1]["subtask_success"] = recs[1]["subtask_success"][:2]  # as if it had stopped after two subtasks
    recs[1]["spl_by_subtask"] = recs[1]["spl_by_subtask"][:2]
    recs[1]["subtasks_closed"] = 2
    (run / "episodes.jsonl").write_text("".join(json.dumps(r) + "\n" for r in recs))
    label, rows = subtask_rows(run)
    episodes = load_goat(split_file("goat", "val")).episodes
    tasks = {(e.scene_id, e.episode_id): e.tasks for e in episodes}
    expected = [t.type for r in recs for t in tasks[(r["scene_id"], r["episode_id"])]]
    assert label == "oracle" and [r["type"] for r in rows] == expected
    n0 = len(tasks[(recs[0]["scene_id"], recs[0]["episode_id"])])
    assert [r["success"] for r in rows] == [1.0] * (n0 + 2) + [0.0] * (len(rows) - n0 - 2)
    assert main([str(run)]) == 0
    out = capsys.readouterr().out
    assert "| 1st | 2 | 100.0 [100.0, 100.0] |" in out and "| `partial_success` |" in out
    assert "| object |" in out or "| description |" in out
    steps = sum(r["num_steps"] for r in recs)  # the first episode closed all its subtasks, the second two
    assert f"| oracle | 2 | {steps} | {n0 + 2} | {steps / (n0 + 2):.1f} |" in out


def test_a_run_of_another_task_is_refused_in_one_line(tmp_path, capsys):
    (tmp_path / "config.json").write_text(json.dumps({"task": "objectnav", "split": "val_unseen"}))
    assert main([str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not a GOAT-Bench run" in err[0]


def test_navbench_table_long_bootstraps_a_measure_over_the_episodes_that_take_it():
    """goat-bench's corrected per-type measures are null in an episode without that type: ``navbench table
    --long`` scores them over the episodes that have them, and every other measure over all episodes."""
    from navbench.eval.stats import intervals
    from navbench.eval.table import run_intervals, run_records

    run = RESULTS_DIR / "runs" / "goat" / "val" / "memory"
    recs = run_records(run)
    m = "description_success_corrected"
    assert any(r[m] is None for r in recs)
    ci = run_intervals(run, {"task": "goat", "success": 1.0, m: 1.0})
    assert ci[m] == intervals([r for r in recs if r[m] is not None], (m,))[m]
    assert ci["success"] == intervals(recs, ("success",))["success"]
