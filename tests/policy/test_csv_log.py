"""Training logs: one CSV row per step, columns kept aligned across a resumed run."""

import csv

from navbench.policy.csv_log import log_row


def test_rows_append_under_the_first_header_and_echo_as_key_value(tmp_path):
    path = tmp_path / "log.csv"
    assert log_row(path, {"update": 1, "loss": 0.123456}) == "update=1 loss=0.1235"
    log_row(path, {"update": 2, "loss": 0.5})
    rows = list(csv.DictReader(open(path)))
    assert [r["update"] for r in rows] == ["1", "2"] and rows[0]["loss"] == "0.12346"


def test_a_resumed_run_that_logs_other_keys_keeps_the_files_columns(tmp_path):
    path = tmp_path / "log.csv"
    log_row(path, {"update": 1, "loss": 0.5, "wall_s": 10.0})
    echo = log_row(path, {"update": 2, "replayed": 3, "loss": 0.25})  # a new key and a missing one
    assert "replayed=3" in echo
    lines = open(path).read().splitlines()
    assert lines[0] == "update,loss,wall_s" and lines[2] == "2,0.25,"


def test_a_resumed_run_drops_the_rows_written_past_its_saved_state(tmp_path):
    from navbench.policy.csv_log import keep_rows_through

    path = tmp_path / "log.csv"
    for u in (1, 2, 3, 4):  # saved at update 2, killed after 4
        log_row(path, {"update": u, "loss": float(u)})
    keep_rows_through(path, "update", 2)
    for u in (3, 4):  # the resumed run logs them again
        log_row(path, {"update": u, "loss": 10.0 * u})
    rows = list(csv.DictReader(open(path)))
    assert [(r["update"], r["loss"]) for r in rows] == [("1", "1.0"), ("2", "2.0"), ("3", "30.0"), ("4", "40.0")]
    keep_rows_through(tmp_path / "absent.csv", "update", 2)  # nothing to keep: no file is made
    assert not (tmp_path / "absent.csv").exists()
