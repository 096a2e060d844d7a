"""What a study run does besides its cases (issue 22): the curves' frame, against the way it was done before
(the same-run baseline: one frame per curve, concatenated).

Run with ``--benchmark-enable`` for timings; by default (``--benchmark-disable``) each runs once as a test.
"""
import numpy as np
import pandas as pd
import pytest

from jointbench.benchmarks.harness.case import Case, CaseResult
from jointbench.benchmarks.tables import curves_frame

VARIATIONS, SNRS, METRICS, SEEDS = ("sine20", "square10", "square20", "square30"), (5.0, 10.0, np.inf), \
    ("vaf_self", "vaf_optim", "vaf_val", "rmse_k", "rmse_k_bound", "step_captured"), range(10)


@pytest.fixture(scope="module")
def results():
    """Results shaped like vanderuit2018_table1's: two kinds of curve per case, 400 points each (Python floats,
    as benchmarks.protocols.Context.curve records them)."""
    out = []
    x = np.linspace(-5.0, 35.0, 400).tolist()
    for v in VARIATIONS:
        for seed in range(3):
            case = Case(study="s", part="table1", protocol="p", params={}, sweep={"variation": v, "snr_db": 10.0},
                        experiment=None, estimators={}, seed=seed, where="w")
            curves = [{"curve": "stiffness", "series": s, "x": x, "y": [float(i) for i in range(400)]}
                      for s in ("truth", "kbr", "skirt")]
            curves += [{"curve": "tf_mag", "series": s, "freq_hz": f, "x": x, "y": x}
                       for s in ("truth", "kbr") for f in (0.5, 1.0, 2.0)]
            out.append(CaseResult(case, "ok", [], curves, 0.0))
    return out


def naive_curves_frame(results) -> pd.DataFrame:
    """Baseline: one frame per curve, concatenated (as tables.curves_frame did before)."""
    return pd.concat([pd.DataFrame({"x": c["x"], "y": c["y"], "part": r.case.part, "case_id": r.case.case_id,
                                    "seed": r.case.seed, **r.case.sweep,
                                    **{k: v for k, v in c.items() if k not in ("x", "y")}})
                      for r in results for c in r.curves], ignore_index=True)


@pytest.mark.benchmark(group="report-curves")
def test_bench_curves_frame(benchmark, results):
    got = benchmark(curves_frame, results)
    assert len(got) == 12 * 9 * 400


@pytest.mark.benchmark(group="report-curves")
def test_bench_naive_curves_frame(benchmark, results):
    got = benchmark(naive_curves_frame, results)
    pd.testing.assert_frame_equal(got, curves_frame(results))
