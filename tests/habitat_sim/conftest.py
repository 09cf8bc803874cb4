"""``NAVBENCH_REQUIRE_HABITAT=1`` (``make test-habitat``) turns every skip in these tests into a failure.

The tests that drive habitat-lab skip where the habitat extra is absent (navbench's own virtualenv); in the
habitat virtualenv a skip would mean a part of the install is broken, so it fails there instead.
"""

from __future__ import annotations

import os

import pytest

REQUIRED = os.environ.get("NAVBENCH_REQUIRE_HABITAT") == "1"


def _fail_skip(report, what: str) -> None:
    if REQUIRED and report.skipped and not hasattr(report, "wasxfail"):
        report.outcome = "failed"
        report.longrepr = f"{what} skipped under NAVBENCH_REQUIRE_HABITAT=1: {report.longrepr}"


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    outcome = yield
    _fail_skip(outcome.get_result(), "module")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    _fail_skip(outcome.get_result(), "test")
