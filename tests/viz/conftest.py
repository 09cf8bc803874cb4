"""A finished 3-episode oracle run on the smoke scene's short ObjectNav episodes, shared by the viz tests."""

import shutil
from pathlib import Path

import pytest

from navbench.cli import main


@pytest.fixture(scope="session")
def oracle_run(tmp_path_factory, objectnav_file) -> Path:
    out = tmp_path_factory.mktemp("viz") / "oracle"
    assert main(["run", "--episodes", str(objectnav_file), "--agent", "oracle", "--limit", "3", "--workers", "1",
                 "--out", str(out), "-q"]) == 0
    return out


@pytest.fixture
def run_copy(oracle_run, tmp_path) -> Path:
    """A copy of the run a test may change."""
    dst = tmp_path / "run"
    shutil.copytree(oracle_run, dst)
    return dst
