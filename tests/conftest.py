"""``--slow`` runs the tests marked ``slow`` (full studies, minutes each); without it they are skipped.

With pytest-xdist (``make test`` runs ``-n 2 --dist loadgroup``), each test module is one unit of work, run on
one worker, so that its module-scoped fixtures (a built wheel, a study's smoke run) are computed once; the
modules in :data:`SPLIT` hold independent tests without costly shared fixtures and are spread over the
workers test by test. The grouping is this file's scheduler (:func:`pytest_xdist_make_scheduler`), not
xdist's ``xdist_group`` marker: xdist 3.8 groups by rewriting ``item._nodeid``, which pytest 9.2 no longer
reads, so with it every module was spread test by test and its fixtures made once per worker (the MuJoCo
smoke runs twice: 33 s of setup where 17 s do).
"""
import os

import pytest

#: modules whose tests are spread over the xdist workers one by one (no costly module-scoped fixture: each
#: test sets up what it needs)
SPLIT = frozenset({"tests.test_dask_faults", "tests.test_runner_faults", "tests.test_outputs_set",
                   "tests.test_cli_estimate", "tests.test_history"})
#: the modules that cost most (CPU-s of a make test run: their processes, builds and study runs), most first,
#: so that the workers finish together rather than one of them starting a long unit at the end: the units go
#: out in this order (the tests of a SPLIT module one by one), then every other module (each under 4 CPU-s) in
#: collection order. A stale order costs balance, never a result.
FIRST = ("tests.test_side_by_side",         # 21 CPU-s: runs of several studies with --jobs
         "tests.test_plugins",              # 20: pip installs, 4 processes, 2 local Dask clusters
         "tests.test_backends_harness",     # 14: each paper study on MuJoCo
         "tests.test_nightly",              # 12: nightly runs, make nightly, Chromium
         "tests.test_dask_faults",          # 19 in tests of 8, 5, 4, 1 ... (split)
         "tests.test_estimators", "tests.test_comparison_report", "tests.test_executors", "tests.test_wheel",  # 9-10
         "tests.test_runner_faults",        # 15 in tests of 5, 4, 3, 2 ... (split)
         "tests.test_history",              # 11 in tests of 4, 3, 1 ... (split)
         "tests.test_estimate_robust", "tests.test_estimate_acceptance",                  # 7 each
         "tests.test_outputs_set", "tests.test_cli_estimate",                             # 6 each (split)
         "tests.test_grid", "tests.test_interval_coverage", "tests.test_sims_tv", "tests.test_band_checks",
         "tests.test_westwick2012")         # 4-5 each


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


def work_unit(nodeid: str) -> str:
    """The xdist unit of work of a test (``make test``): its module's path, or the test itself for a module of
    :data:`SPLIT`."""
    path = nodeid.split("::", 1)[0]
    return nodeid if path[:-3].replace("/", ".") in SPLIT else path


def pytest_xdist_make_scheduler(config, log):
    """With ``--dist loadgroup``: xdist's scope scheduling with :func:`work_unit` as the scope. Units go to
    the workers in collection order (:data:`FIRST` first), each as a worker finishes the last."""
    if config.getvalue("dist") != "loadgroup":
        return None                                  # xdist's own scheduler for any other --dist
    from xdist.scheduler import LoadScopeScheduling

    # xdist 3.x hands out the units largest first by their number of tests (its --loadscope-reorder, on by
    # default), not in collection order: the two tests of test_plugins (20 CPU-s) and every test of SPLIT
    # were the last units given out, and a worker could start a 20 s unit while the other had nothing left
    config.option.loadscopereorder = False

    class ModuleScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return work_unit(nodeid)

    return ModuleScheduling(config, log)


def pytest_collection_modifyitems(config, items):
    rank = {m: i for i, m in enumerate(FIRST)}
    items.sort(key=lambda item: rank.get(_module(item), len(FIRST)))       # stable: the order within a module kept
    if config.getoption("--slow"):
        return
    skip = pytest.mark.skip(reason="slow: full study (run with --slow, or make test-slow)")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)
