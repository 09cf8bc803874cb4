"""Fuzz ``navbench table``'s readers of a run's ``config.json`` (and ``summary.json``).

Every mutation must print a table or exit 2 with one line naming the file.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from fuzzlib import mutations, run_cli
from hypothesis import given
from hypothesis import strategies as st

from navbench.paths import ROOT

RUN = ROOT / "results" / "runs" / "objectnav" / "val_unseen" / "memory"
CONFIG = json.loads((RUN / "config.json").read_text())
SUMMARY = json.loads((RUN / "summary.json").read_text())
FIRST = 5


def make_run(root: Path, config: bytes, summary: bytes) -> Path:
    run = root / "run"
    if run.exists():
        shutil.rmtree(run)
    run.mkdir(parents=True)
    (run / "config.json").write_bytes(config)
    (run / "summary.json").write_bytes(summary)
    lines = (RUN / "episodes.jsonl").read_text().splitlines()[:40]
    (run / "episodes.jsonl").write_text("\n".join(lines) + "\n")
    return run


def check_table(run: Path, bad: str, variants=([], ["--long", "--format", "csv"])) -> None:
    for extra in variants:
        code, out, err = run_cli(["table", str(run), *extra])
        lines = err.strip("\n").splitlines()
        if code == 0:
            assert "|" in out or "," in out, out
            continue
        assert code == 2, (extra, code, err)
        assert len(lines) == 1, (extra, err)
        if extra[:1] != ["--first"]:  # --first may fail on the episode file config.json names, named instead
            assert str(run / bad) in lines[0], (extra, lines[0])


@given(doc=mutations(CONFIG), raw=st.booleans())
def test_config_mutations(doc, raw, fuzz_dir):
    text = json.dumps(doc).encode()
    check_table(make_run(fuzz_dir / "table_cfg", text, json.dumps(SUMMARY).encode()), "config.json")


@given(doc=mutations(SUMMARY))
def test_summary_mutations(doc, fuzz_dir):
    check_table(make_run(fuzz_dir / "table_sum", json.dumps(CONFIG).encode(), json.dumps(doc).encode()),
                "summary.json")


def test_config_truncation_and_bytes(fuzz_dir):
    data = json.dumps(CONFIG).encode()
    summary = json.dumps(SUMMARY).encode()
    for cut in range(0, len(data), max(1, len(data) // 60)):
        check_table(make_run(fuzz_dir / "table_trunc", data[:cut], summary), "config.json")
    first = (["--first", str(FIRST)],)  # reads the run's episode file: a few cases only
    for doc in ({**CONFIG, "task": 3}, {**CONFIG, "split": None, "episodes": None}, {**CONFIG, "episodes": "nope.json"},
                {k: v for k, v in CONFIG.items() if k != "task"}, [CONFIG]):
        check_table(make_run(fuzz_dir / "table_first", json.dumps(doc).encode(), summary), "config.json", first)
    for junk in (b"\xff\xfe", b"[" * 100_000 + b"]" * 100_000, b"null", b"[]", b"1"):
        check_table(make_run(fuzz_dir / "table_junk", junk, summary), "config.json")
        check_table(make_run(fuzz_dir / "table_junk", data, junk), "summary.json")
