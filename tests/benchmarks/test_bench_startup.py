"""Start-up of the command line as whole processes, against a same-run baseline: ``jointbench estimate
--list`` (issue 13: under 0.5 s; it imported scipy, pandas and every estimator before, 2.7 s),
``jointbench list`` and the import of the study module, which every ``jointbench run`` pays (issue 22:
protocols, figure makers, scipy.signal and scipy.stats are imported on first use; 1.05 and 1.45 CPU-s
before).

Run with ``--benchmark-enable`` for timings; by default each runs once as a test. The baseline is the
interpreter importing numpy alone, which none of them can avoid (the core types use it).
"""
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
LIST = "from jointbench.cli import main; main(['estimate', '--list'])"


def python(code: str) -> None:
    subprocess.run([sys.executable, "-c", code], cwd=REPO, check=True, capture_output=True)


@pytest.mark.benchmark(group="estimate-list-startup")
def test_bench_estimate_list(benchmark):
    benchmark(python, LIST)


@pytest.mark.benchmark(group="estimate-list-startup")
def test_bench_jointbench_list(benchmark):
    """``jointbench list``: studies, estimators and protocols, none of them imported."""
    benchmark(python, "from jointbench.cli import main; main(['list'])")


@pytest.mark.benchmark(group="estimate-list-startup")
def test_bench_import_study_module(benchmark):
    """The import of ``jointbench.benchmarks.study`` (the start of every ``jointbench run``)."""
    benchmark(python, "import jointbench.benchmarks.study")


@pytest.mark.benchmark(group="estimate-list-startup")
def test_bench_import_numpy_baseline(benchmark):
    benchmark(python, "import numpy")
