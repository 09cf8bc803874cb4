"""python -m navbench.eval.goat_table: GOAT-Bench runs by subtask position and goal type."""

import json
import shutil

from navbench.cli import main as main_cli
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


def test_navbench_table_bootstraps_a_measure_over_the_episodes_that_take_it(tmp_path):
    """The table's GOAT columns (partial and composite success, composite SPL) get intervals from the records
    (the committed runs' ci95 predates them); a measure null in some episodes is bootstrapped over the others."""
    from navbench.eval.stats import intervals
    from navbench.eval.table import run_intervals, run_records

    run = tmp_path / "memory"
    shutil.copytree(RESULTS_DIR / "runs" / "goat" / "val" / "memory", run)
    recs = run_records(run)
    shown = ("partial_success", "composite_success", "composite_spl")
    summary = {"task": "goat", **{m: 0.5 for m in shown}}
    assert run_intervals(run, summary) == intervals(recs, shown)
    recs[0]["composite_spl"] = None
    (run / "episodes.jsonl").write_text("".join(json.dumps(r) + "\n" for r in recs))
    ci = run_intervals(run, summary)
    assert ci["composite_spl"] == intervals(recs[1:], ("composite_spl",))["composite_spl"]
    assert ci["partial_success"] == intervals(recs, ("partial_success",))["partial_success"]


def test_navbench_table_shows_goat_bench_measures_by_name_and_goal_type(tmp_path, capsys):
    """`navbench table` on GOAT runs: success and SPL by goal type (as goat_table's by-type table), then
    partial_success, composite_success and composite_spl under their own names; never plain SR / SPL."""
    from navbench.eval.goat_table import scored_run, table, type_figures
    from navbench.eval.table import runs_frame

    run = RESULTS_DIR / "runs" / "goat" / "val" / "memory"
    df = runs_frame([run], wide=False)
    cols = [c for c in df.columns if not c.endswith((" lo", " hi"))]
    assert cols[-9:] == ["object SR", "object SPL", "description SR", "description SPL", "image SR", "image SPL",
                         "partial SR", "composite SR", "composite SPL"]
    assert not {"SR", "SPL", "SoftSPL", "DTG"} & set(df.columns)
    summary = json.loads((run / "summary.json").read_text())
    assert df.loc[0, "partial SR"] == 100 * summary["partial_success"]
    assert df.loc[0, "composite SR"] == 100 * summary["composite_success"]
    assert df.loc[0, "composite SPL"] == 100 * summary["composite_spl"]
    by_type = type_figures(run)
    assert df.loc[0, "image SPL"] == 100 * by_type["image"]["spl"]
    # the same figures as goat_table's table by goal type
    label, rows = subtask_rows(scored_run(run))
    line = next(x for x in table([(label, rows)], "type", ["image"], str) if x.startswith("| image |"))
    assert f"{df.loc[0, 'image SR']:.1f} [{df.loc[0, 'image SR lo']:.1f}, {df.loc[0, 'image SR hi']:.1f}]" in line
    assert main_cli(["table", str(run)]) == 0
    out = capsys.readouterr().out
    assert "| composite SPL " in out.splitlines()[0] and "goat-bench's partial_success" in out
    # --first reads the split with GOAT-Bench's reader; a GOAT run beside another task's keeps its row
    first = runs_frame([run], wide=False, first=3)
    assert first.loc[0, "episodes"] == 3 and "object SR" in first.columns
    mixed = runs_frame([run, RESULTS_DIR / "runs" / "objectnav" / "val_unseen" / "memory"])
    assert list(mixed["task"]) == ["goat", "objectnav"] and mixed.loc[1, "SR"] > 0
