"""Hypothesis profiles for the fuzz suite and the outcome every fuzzed reader must have.

Profiles: ``ci`` (the default; a modest example count so the suite fits CI's 3 minutes on 2 cores,
derandomized when ``CI`` is set so a CI failure reproduces) and ``long`` (``HYPOTHESIS_PROFILE=long``,
for ``make test-slow``). A reader given bad input must raise one of the errors the CLI turns into
``navbench: error: <first line>`` (exit 2) with the file named on that line, or return a result.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

_COMMON = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                                      HealthCheck.function_scoped_fixture])
settings.register_profile("ci", max_examples=25, derandomize=bool(os.environ.get("CI")), **_COMMON)
settings.register_profile("long", max_examples=500, **_COMMON)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

sys.path.insert(0, str(Path(__file__).parent))  # the tests import fuzzlib

@pytest.fixture(scope="session")
def fuzz_dir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("fuzz")
