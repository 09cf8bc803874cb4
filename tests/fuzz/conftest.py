"""Hypothesis profiles for the fuzz suite and the outcome every fuzzed reader must have.

Every fuzz test runs twice: a derandomized ``core`` pass (the same examples on every machine, so a CI
failure reproduces) and an ``explore`` pass drawn from this run's seed, which changes per run (set it
with ``NAVBENCH_FUZZ_SEED``), is printed in the header and named in the failure report: CI explores new
inputs on every run, and what ``make test`` finds on a user's machine reproduces with that seed.
Profiles: ``ci`` (the default; modest example counts so the suite fits CI's 3 minutes on 2 cores) and
``long`` (``HYPOTHESIS_PROFILE=long``, for ``make test-slow`` and for probing with several seeds).
A reader given bad input must raise one of the errors the CLI turns into ``navbench: error: <first
line>`` (exit 2) with the file named on that line, or return a result.
"""

from __future__ import annotations

import os
import random
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

_COMMON = dict(deadline=None, database=None,
               suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                      HealthCheck.function_scoped_fixture])
# (core examples, explore examples) per profile
_EXAMPLES = {"ci": (20, 8), "long": (25, 500)}
PROFILE = os.environ.get("HYPOTHESIS_PROFILE", "ci")
if PROFILE not in _EXAMPLES:
    raise pytest.UsageError(f"HYPOTHESIS_PROFILE={PROFILE!r}: choose one of {', '.join(_EXAMPLES)}")
SEED = int(os.environ.get("NAVBENCH_FUZZ_SEED") or random.SystemRandom().randrange(1 << 32))
settings.register_profile("fuzz", max_examples=_EXAMPLES[PROFILE][0], derandomize=True, **_COMMON)
settings.load_profile("fuzz")

sys.path.insert(0, str(Path(__file__).parent))  # the tests import fuzzlib


def pytest_report_header(config) -> str:
    return f"fuzz: profile {PROFILE}, explore seed {SEED} (rerun with NAVBENCH_FUZZ_SEED={SEED})"


def pytest_generate_tests(metafunc) -> None:
    if getattr(metafunc.function, "is_hypothesis_test", False):
        metafunc.parametrize("fuzz_pass", ["core", "explore"], indirect=True)


@pytest.fixture(autouse=True)
def fuzz_pass(request):
    """A Hypothesis test runs with its pass's profile; the explore pass draws from this run's seed."""
    name = getattr(request, "param", None)
    if name is None:  # not a Hypothesis test
        yield None
        return
    test = request.function
    before = test._hypothesis_internal_use_settings
    test._hypothesis_internal_use_settings = settings(before, **_pass_settings(name))
    test._hypothesis_internal_use_seed = SEED if name == "explore" else None
    try:
        yield name
    finally:
        test._hypothesis_internal_use_settings = before
        test._hypothesis_internal_use_seed = None


def _pass_settings(name: str) -> dict:
    core, explore = _EXAMPLES[PROFILE]
    return dict(max_examples=core, derandomize=True) if name == "core" else \
        dict(max_examples=explore, derandomize=False)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if report.failed and "[explore" in item.nodeid:
        report.sections.append(("fuzz seed", f"explore pass drew from seed {SEED}: rerun with "
                                              f"NAVBENCH_FUZZ_SEED={SEED} HYPOTHESIS_PROFILE={PROFILE}"))


@pytest.fixture(scope="session")
def fuzz_dir(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("fuzz")
