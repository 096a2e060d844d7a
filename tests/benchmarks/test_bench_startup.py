"""Start-up of ``jointbench estimate --list`` as a whole process, against a same-run baseline (issue 13:
under 0.5 s; it imported scipy, pandas and every estimator before, 2.7 s).

Run with ``--benchmark-enable`` for timings; by default each runs once as a test. The baseline is the
interpreter importing numpy alone, which ``--list`` cannot avoid (the core types use it).
"""
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
LIST = "from benchmarks.cli import main; main(['estimate', '--list'])"


def python(code: str) -> None:
    subprocess.run([sys.executable, "-c", code], cwd=REPO, check=True, capture_output=True)


@pytest.mark.benchmark(group="estimate-list-startup")
def test_bench_estimate_list(benchmark):
    benchmark(python, LIST)


@pytest.mark.benchmark(group="estimate-list-startup")
def test_bench_import_numpy_baseline(benchmark):
    benchmark(python, "import numpy")
