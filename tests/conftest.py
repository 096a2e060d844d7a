"""``--slow`` runs the tests marked ``slow`` (full studies, minutes each); without it they are skipped.

With pytest-xdist (``make test`` runs ``-n 2 --dist loadgroup``), each test module is one group, run on one
worker, so that its module-scoped fixtures (a built wheel, a study's smoke run) are computed once; the
modules in :data:`SPLIT` hold independent tests without costly shared fixtures and are spread over the
workers test by test.
"""
import os

import pytest

#: modules whose tests are spread over the xdist workers one by one (no costly module-scoped fixture: each
#: test sets up what it needs)
SPLIT = frozenset({"tests.test_dask_faults", "tests.test_runner_faults", "tests.test_outputs_set",
                   "tests.test_cli_estimate", "tests.test_history"})
#: the longest modules (minutes of processes, builds and whole-study runs; pytest --durations), run first, so
#: that the workers finish together rather than one of them starting a long module at the end
FIRST = ("tests.test_plugins", "tests.test_outputs_set", "tests.test_dask_faults", "tests.test_runner_faults",
         "tests.test_wheel", "tests.test_nightly", "tests.test_history", "tests.test_cli_estimate",
         "tests.test_nightly_alarms")


def pytest_configure(config):
    """On an xdist worker, one BLAS thread: two workers with a BLAS pool each on two cores wait on each other
    (an estimator's many small products then took ten times as long); a test's own processes are not
    affected (threadpoolctl limits this process only)."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        import numpy  # noqa: F401 - the BLAS libraries must be loaded to be limited: numpy's and scipy's own
        import scipy.linalg  # noqa: F401
        from threadpoolctl import threadpool_limits

        config.stash[_BLAS_LIMIT] = threadpool_limits(limits=1)


_BLAS_LIMIT = pytest.StashKey()


def pytest_addoption(parser):
    parser.addoption("--slow", action="store_true", default=False, help="run the tests marked slow (full studies)")


def _module(item) -> str:
    return getattr(getattr(item, "module", None), "__name__", "")


@pytest.hookimpl(tryfirst=True)          # before xdist reads the groups
def pytest_collection_modifyitems(config, items):
    rank = {m: i for i, m in enumerate(FIRST)}
    items.sort(key=lambda item: rank.get(_module(item), len(FIRST)))       # stable: the order within a module kept
    for item in items:
        module = _module(item)
        if module and module not in SPLIT and item.get_closest_marker("xdist_group") is None:
            item.add_marker(pytest.mark.xdist_group(module))
    if config.getoption("--slow"):
        return
    skip = pytest.mark.skip(reason="slow: full study (run with --slow, or make test-slow)")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)
