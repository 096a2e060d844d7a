"""Benchmarks run with one BLAS thread, as the harness runs every case (benchmarks.runner): on the
2-core machine, BLAS threads on top of other load turned a 0.16 s KBR fit into seconds, which measures
the machine's scheduler rather than the code."""
import pytest
from threadpoolctl import threadpool_limits


@pytest.fixture(autouse=True)
def one_blas_thread():
    with threadpool_limits(limits=1):
        yield
