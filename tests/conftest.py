"""``--slow`` runs the tests marked ``slow`` (full studies, minutes each); without it they are skipped."""
import pytest


def pytest_addoption(parser):
    parser.addoption("--slow", action="store_true", default=False, help="run the tests marked slow (full studies)")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--slow"):
        return
    skip = pytest.mark.skip(reason="slow: full study (run with --slow, or make test-slow)")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)
