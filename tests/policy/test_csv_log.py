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
