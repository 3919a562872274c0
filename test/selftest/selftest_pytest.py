"""A probe of scripts/ci_selftest (not in the suite): fails only under HYDROJET_SELFTEST_INJECT=pytest_failure,
to show that a failing Python test fails scripts/test."""
import os


def test_probe():
    assert os.environ.get("HYDROJET_SELFTEST_INJECT") != "pytest_failure", "injected failure"
