"""compare takes each task's own measures, checked against the runs' task, and by default reports the task's
headline measures (VLN-CE's columns with nDTW, GOAT-Bench's success and SPL measures)."""

import json
import shutil

from navbench.cli import main
from navbench.eval.stats import metric_label
from navbench.paths import RESULTS_DIR
from navbench.tasks.goat import GOAT_HEADLINE

RUNS = RESULTS_DIR / "runs"
GOAT = RUNS / "goat" / "val"
R2R = RUNS / "r2r_ce" / "val"


def _json(capsys, *args):
    assert main(["compare", *map(str, args), "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_goat_runs_default_to_goat_bench_measures(capsys):
    doc = _json(capsys, GOAT / "memory", GOAT / "frontier")
    assert tuple(doc["metrics"]) == GOAT_HEADLINE
    assert "soft_spl" not in doc["metrics"] and "success" not in doc["metrics"]
    assert main(["compare", str(GOAT / "memory"), str(GOAT / "frontier")]) == 0
    rows = capsys.readouterr().out.splitlines()[-len(GOAT_HEADLINE):]
    heads = [metric_label("goat", m)[0] for m in GOAT_HEADLINE]  # goat-bench's names: "partial SR", ...
    assert [r[: len(h)] for r, h in zip(rows, heads)] == heads and "partial SR" in heads


def test_vlnce_runs_default_to_vlnce_columns_with_ndtw_never_softspl(capsys):
    doc = _json(capsys, R2R / "vln_random", R2R / "vln_forward")
    assert list(doc["metrics"]) == ["path_length", "distance_to_goal", "oracle_success", "success", "spl", "ndtw",
                                    "sdtw"]
    assert doc["metrics"]["path_length"]["p_better"] is None  # a longer path is neither better nor worse
    assert main(["compare", str(R2R / "vln_random"), str(R2R / "vln_forward")]) == 0
    out = capsys.readouterr().out
    assert "nDTW %" in out and "NE m" in out and "SoftSPL" not in out
    assert main(["compare", str(R2R / "vln_random"), str(R2R / "vln_forward"), "--metric", "soft_spl"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--metric soft_spl: not a measure of r2r_ce runs; choose from " in err[0]
    assert "ndtw" in err[0]


def test_a_task_s_own_measure_is_taken_and_another_task_s_refused(capsys):
    doc = _json(capsys, R2R / "vln_random", R2R / "vln_forward", "--metric", "sdtw", "--metric", "ndtw")
    assert list(doc["metrics"]) == ["sdtw", "ndtw"]
    doc = _json(capsys, GOAT / "memory", GOAT / "oracle", "--metric", "composite_spl")
    assert list(doc["metrics"]) == ["composite_spl"]
    assert main(["compare", str(GOAT / "memory"), str(GOAT / "oracle"), "--metric", "ndtw"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not a measure of goat runs" in err[0] and "partial_success" in err[0]
    # the trusted tasks keep their four
    val = RUNS / "objectnav" / "val_unseen"
    assert list(_json(capsys, val / "frontier", val / "memory")["metrics"]) == \
        ["success", "spl", "soft_spl", "distance_to_goal"]


def test_a_measure_some_episodes_lack_is_paired_where_both_have_it(capsys):
    # GOAT-Bench's corrected per-type success is null for an episode without a subtask of that type
    doc = _json(capsys, GOAT / "memory", GOAT / "frontier", "--metric", "description_success_corrected",
                "--metric", "partial_success")
    recs = [json.loads(x) for x in (GOAT / "memory" / "episodes.jsonl").read_text().splitlines()]
    n = sum(r["description_success_corrected"] is not None for r in recs)
    assert 0 < n < len(recs)
    assert doc["metrics"]["description_success_corrected"]["episodes"] == n
    assert "episodes" not in doc["metrics"]["partial_success"]


def test_nDTW_without_gt_is_left_out_of_the_defaults_and_refused_when_asked(tmp_path, capsys):
    runs = []
    for name in ("vln_random", "vln_forward"):
        d = tmp_path / name
        shutil.copytree(R2R / name, d, ignore=shutil.ignore_patterns("videos"))
        recs = [json.loads(x) for x in (d / "episodes.jsonl").read_text().splitlines()]
        (d / "episodes.jsonl").write_text("".join(json.dumps({**r, "ndtw": None, "sdtw": None}) + "\n" for r in recs))
        runs.append(d)
    doc = _json(capsys, *runs)
    assert "ndtw" not in doc["metrics"] and doc["unmeasured"] == ["ndtw", "sdtw"]
    assert main(["compare", *map(str, runs)]) == 0
    assert "not measured in these runs' records: nDTW, SDTW" in capsys.readouterr().out
    assert main(["compare", *map(str, runs), "--metric", "ndtw"]) == 2
    assert "no episode both runs scored has a value of ndtw" in capsys.readouterr().err
