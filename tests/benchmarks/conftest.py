"""Benchmarks run with one BLAS thread, as the harness runs every case (benchmarks.runner): on the
2-core machine, BLAS threads on top of other load turned a 0.16 s KBR fit into seconds, which measures
the machine's scheduler rather than the code.

``speedup`` checks a fast path against its same-run baseline: medians of the two called alternately, so
that load on the shared machine hits both alike (only with ``--benchmark-enable``)."""
import time

import numpy as np
import pytest
from threadpoolctl import threadpool_limits


@pytest.fixture(autouse=True)
def one_blas_thread_per_benchmark():
    with threadpool_limits(limits=1):
        yield


def interleaved_medians(fast, slow, rounds: int = 9) -> tuple[float, float]:
    """Median seconds of ``fast()`` and ``slow()``, called alternately."""
    tf, ts = [], []
    for _ in range(rounds):
        for f, out in ((fast, tf), (slow, ts)):
            t0 = time.perf_counter()
            f()
            out.append(time.perf_counter() - t0)
    return float(np.median(tf)), float(np.median(ts))


@pytest.fixture
def speedup(benchmark):
    """``speedup(fast, slow, factor)``: with timings on, assert ``fast`` is at least ``factor`` times faster
    than ``slow`` (same-run interleaved medians) and record the ratio in the benchmark's extra_info."""
    def check(fast, slow, factor: float) -> None:
        if benchmark.disabled:
            return
        tf, ts = interleaved_medians(fast, slow)
        benchmark.extra_info["speedup_vs_baseline"] = round(ts / tf, 2)
        assert ts / tf >= factor, (f"only {ts / tf:.2f} times faster than the baseline ({tf * 1e3:.2f} vs "
                                   f"{ts * 1e3:.2f} ms; wanted {factor:g})")
    return check
