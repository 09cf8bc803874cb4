"""The 2-hour training recipe's stage switches, read from ``make -n`` (prints the commands, runs nothing)."""

import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.skipif(shutil.which("make") is None, reason="needs make")


def commands(target: str, *variables: str) -> list[str]:
    out = subprocess.run(["make", "-n", "-C", str(ROOT), target, "P2H_DIR=x", *variables],
                         capture_output=True, text=True, check=True).stdout
    # one navbench command per entry: join the backslash-continued lines
    return [c for c in out.replace("\\\n", " ").splitlines() if "navbench " in c]


def stages(*variables: str) -> list[tuple[str, str, str]]:
    """(kind, --init, --out) of each training command, in order; the encoder stage has no --init."""
    out = []
    for c in commands("train-pointnav-2h", *variables):
        init = re.search(r"--init (\S+)", c)
        out.append((re.search(r"navbench train (\w+)", c).group(1), init.group(1) if init else "",
                    re.search(r"--out (\S+)", c).group(1)))
    return out


def eval_checkpoints(*variables: str) -> list[str]:
    """The --checkpoint of each `navbench run` in eval-pointnav-2h, in order."""
    return [re.search(r"--checkpoint (\S+)", c).group(1) for c in commands("eval-pointnav-2h", *variables)
            if "navbench run" in c]


def test_default_recipe_runs_both_ppo_stages_with_24_epochs():
    assert stages() == [("encoder", "", "x/encoder.pth"), ("pointnav", "x/encoder.pth", "x/s1.pth"),
                        ("ppo", "x/s1.pth", "x/s2.pth"), ("pointnav", "x/s2.pth", "x/s3.pth"),
                        ("ppo", "x/s3.pth", "x/s4.pth")]
    assert "--epochs-per-iteration 24" in commands("train-pointnav-2h")[1]
    assert eval_checkpoints() == ["x/s4.pth"] * 3


def test_ppo1_0_leaves_out_the_first_ppo_stage_and_starts_tight_dagger_from_s1():
    assert [s[1:] for s in stages("P2H_PPO1=0")[2:]] == [("x/s1.pth", "x/s3.pth"), ("x/s3.pth", "x/s4.pth")]
    assert re.search(r"--iterations 39 .*--epochs-per-iteration 12",
                     commands("train-pointnav-2h", "P2H_ITERS=39", "P2H_EPOCHS=12")[1])


def test_ppo2_0_leaves_out_the_last_ppo_stage_and_evaluates_s3():
    assert stages("P2H_PPO1=0", "P2H_PPO2=0")[-1] == ("pointnav", "x/s1.pth", "x/s3.pth")
    assert stages("P2H_PPO2=0")[-1] == ("pointnav", "x/s2.pth", "x/s3.pth")
    assert eval_checkpoints("P2H_PPO2=0") == ["x/s3.pth"] * 3


def test_s1_flags_reach_the_cosine_dagger_stage_only():
    cmds = commands("train-pointnav-2h", "P2H_S1_FLAGS=--tight-starts 0.2", "P2H_PPO1=0", "P2H_PPO2=0")
    s1, s3 = [c for c in cmds if "navbench train pointnav" in c]
    assert s1.rstrip().endswith("--tight-starts 0.2")
    assert s3.count("--tight-starts") == 1 and "--tight-starts 0.3" in s3


def test_tight_0_leaves_out_the_tight_start_stage():
    # with both PPO stages off the recipe ends at the cosine stage's file, and that file is evaluated
    assert stages("P2H_PPO1=0", "P2H_TIGHT=0", "P2H_PPO2=0")[-1] == ("pointnav", "x/encoder.pth", "x/s1.pth")
    assert eval_checkpoints("P2H_PPO1=0", "P2H_TIGHT=0", "P2H_PPO2=0") == ["x/s1.pth"] * 3
    # the last PPO stage starts from the file before the skipped stage
    assert [s[1:] for s in stages("P2H_TIGHT=0")[2:]] == [("x/s1.pth", "x/s2.pth"), ("x/s2.pth", "x/s4.pth")]
    assert stages("P2H_PPO1=0", "P2H_TIGHT=0")[-1] == ("ppo", "x/s1.pth", "x/s4.pth")
