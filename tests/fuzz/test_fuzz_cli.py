"""Fuzz every ``navbench`` subcommand's arguments: unknown choices, bad numbers, missing files and
directories where files are expected. Each must exit 2 with one line on stderr, before any work."""

from __future__ import annotations

import pytest
from fuzzlib import assert_cli_error
from hypothesis import given
from hypothesis import strategies as st

from navbench.cli import build_parser

# (subcommand prefix, option) for every numeric option, with the smallest valid value.
COUNTS = [(["run", "--split", "val_unseen"], "--limit"), (["run", "--split", "val_unseen"], "--per-scene"),
          (["run", "--split", "val_unseen"], "--workers"), (["run", "--split", "val_unseen"], "--envs-per-worker"),
          (["localize"], "-k"), (["localize"], "--limit"), (["table", "runs/x"], "--first"),
          (["generate", "benchmark"], "--houses"), (["generate", "benchmark"], "--episodes-per-split")]
POSITIVE = [(["run", "--split", "val_unseen"], "--success-distance"), (["bench"], "--seconds")]
SEEDS = [(["run", "--split", "val_unseen"], "--seed"), (["generate", "episodes"], "--seed")]
CHOICES = [["run", "--task"], ["serve-agent", "x", "--task"], ["check-agent", "http://x", "--task"],
           ["run", "--decoding"], ["run", "--video"], ["run", "--rerank"], ["run", "--keyframe-res"],
           ["table", "x", "--format"], ["table", "x", "--by"], ["protocol", "x", "--format"],
           ["compare", "x", "y", "--metric"], ["generate"],
           ["memory"], ["memory", "build", "--scene", "x", "--keyframe-res"],
           ["localize", "--rerank"]]

bad_numbers = st.sampled_from(["nan", "inf", "-inf", "-1", "0", "-0", "1e999", "abc", "", "1.5", "0x10", " "])


def test_parser_covers_every_subcommand():
    sub = next(a for a in build_parser()._actions if a.dest == "command")
    assert set(sub.choices) == {"run", "table", "generate", "train", "memory", "localize", "bench", "merge", "viz",
                                "report", "agents", "tasks", "serve-agent", "compare", "check-agent", "protocol",
                                "export"}


@given(case=st.sampled_from(COUNTS + POSITIVE + SEEDS), value=bad_numbers)
def test_bad_numbers(case, value):
    prefix, opt = case
    ok = {"1.5"} if case in POSITIVE else set()
    if (case in SEEDS and value in ("0", "-0")) or value in ok:
        return  # valid values
    assert_cli_error([*prefix, f"{opt}={value}"], opt)


@pytest.mark.parametrize("value", ["nan", "0", "-1", "abc"])
def test_bad_temperature(value):
    assert_cli_error(["run", "--split", "val_unseen", "--decoding", "sample", f"--temperature={value}"], "temperature")


@pytest.mark.parametrize("prefix", CHOICES, ids=" ".join)
def test_unknown_choices(prefix):
    assert_cli_error([*prefix, "no-such-choice"], "no-such-choice")


@pytest.mark.parametrize("argv", [[], ["nosuch"], ["run", "--nosuch"], ["table"], ["memory", "build"], ["merge"],
                                  ["merge", "x"], ["compare"], ["compare", "x"], ["viz"], ["report"], ["serve-agent"],
                                  ["check-agent"], ["protocol"], ["protocol", "x", "y"],
                                  ["export"], ["export", "x"], ["export", "x", "--format", "r2r"],
                                  ["agents", "extra"], ["tasks", "extra"],
                                  ["run", "--limit"], ["run", "--split", "val_unseen", "extra-positional"]],
                         ids=repr)
def test_usage_errors(argv):
    assert_cli_error(argv)


@pytest.mark.parametrize("argv", [
    ["run", "--split", "nosuch"],
    ["run", "--task", "pointnav", "--split", "val_unseen"],
    ["run", "--agent", "nosuch"],
    ["run", "--split", "val_unseen", "--agent", "oracle", "--checkpoint", "policies/pointnav_navbench.pth"],
    ["run", "--split", "val_unseen", "--noise", "nosuch", "--limit", "1"],
    ["run", "--split", "val_unseen", "--perception", "nosuch", "--limit", "1"],
    ["localize", "--split", "nosuch"],
    ["localize", "--noise", "nosuch", "--limit", "1"],
    ["localize", "--perception", "nosuch", "--limit", "1"],
    ["memory", "build", "--scene", "nosuch.glb", "--perception", "nosuch"],
], ids=" ".join)
def test_bad_names(argv):
    assert_cli_error(argv)


@pytest.mark.parametrize("kind", ["missing", "directory", "empty"])
@pytest.mark.parametrize("argv", [
    ["run", "--episodes", "{}", "--limit", "1", "--workers", "1"],
    ["run", "--task", "pointnav", "--split", "val", "--checkpoint", "{}", "--limit", "1", "--workers", "1"],
    ["memory", "build", "--scene", "{}"],
    ["bench", "--scene", "{}", "--seconds", "0.1"],
    ["table", "{}"],
    ["compare", "{}", "{}"],
    ["protocol", "{}"],
    ["run", "--habitat-config", "{}", "--limit", "1", "--workers", "1"],
    ["train", "--config", "{}"],
    ["merge", "{}", "--out", "{}-merged"],
    ["viz", "{}"],
    ["report", "{}", "-o", "{}.html"],
    ["localize", "--split", "{}/x.json.gz", "--limit", "1"],
], ids=lambda a: " ".join(a[:2]))
def test_missing_files_and_directories(argv, kind, tmp_path):
    target = tmp_path / ("d" if kind == "directory" else "f.json.gz")
    if kind == "directory":
        target.mkdir()
    elif kind == "empty":
        target.write_bytes(b"")
    args = [a.replace("{}", str(target)) for a in argv]
    if args[0] in ("run", "memory"):  # whatever a failing command leaves behind goes to tmp_path
        args += ["--out", str(tmp_path / "out")]
    assert_cli_error(args, target)
