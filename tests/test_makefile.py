"""The 2-hour training recipe's stage switches, read from ``make -n`` (prints the commands, runs nothing)."""

import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.skipif(shutil.which("make") is None, reason="needs make")


def recipe(*variables: str) -> list[str]:
    out = subprocess.run(["make", "-n", "-C", str(ROOT), "train-pointnav-2h", "P2H_DIR=x", *variables],
                         capture_output=True, text=True, check=True).stdout
    # one navbench command per entry: join the backslash-continued lines
    return [c for c in out.replace("\\\n", " ").splitlines() if "navbench train" in c]


def test_default_recipe_runs_both_ppo_stages_with_24_epochs():
    cmds = recipe()
    assert len(cmds) == 5
    assert "--epochs-per-iteration 24" in cmds[1]
    assert cmds[2].startswith('if [ "1" != 0 ]') and "--out x/s2.pth" in cmds[2]
    assert "--init x/s2.pth" in cmds[3] and "--tight-starts" in cmds[3]


def test_ppo1_0_skips_the_first_ppo_stage_and_starts_tight_dagger_from_s1():
    cmds = recipe("P2H_PPO1=0", "P2H_EPOCHS=12", "P2H_ITERS=39")
    assert re.search(r"--iterations 39 .*--epochs-per-iteration 12", cmds[1])
    assert cmds[2].startswith('if [ "0" != 0 ]')  # the shell skips it
    assert "--init x/s1.pth" in cmds[3] and "--tight-starts" in cmds[3]
    assert "--init x/s3.pth" in cmds[4] and "--out x/s4.pth" in cmds[4]
