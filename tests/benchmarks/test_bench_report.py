"""What a study run does besides its cases (issue 22): the checks' selections of the tidy rows and the curves'
frame, each against the way it was done before (the same-run baseline: a selection comparing the frame's
columns one by one; one frame per curve, concatenated).

Run with ``--benchmark-enable`` for timings; by default (``--benchmark-disable``) each runs once as a test.
"""
import numpy as np
import pandas as pd
import pytest

from jointbench.benchmarks.harness.case import Case, CaseResult
from jointbench.benchmarks.selection import Selection
from jointbench.benchmarks.tables import curves_frame

VARIATIONS, SNRS, METRICS, SEEDS = ("sine20", "square10", "square20", "square30"), (5.0, 10.0, np.inf), \
    ("vaf_self", "vaf_optim", "vaf_val", "rmse_k", "rmse_k_bound", "step_captured"), range(10)


@pytest.fixture(scope="module")
def rows():
    """Tidy rows shaped like vanderuit2018_table1's (parts, sweeps, estimators, text and number columns)."""
    rng = np.random.default_rng(2018)
    recs = [{"part": part, "status": "ok", "case_id": f"{part}-{v}-{s}-{seed}", "estimator": est, "metric": m,
             "variation": v, "snr_db": s, "seed": seed, "value": float(rng.normal(90, 5))}
            for part in ("table1", "table1_np7") for v in VARIATIONS for s in SNRS for seed in SEEDS
            for est in ("kbr", "skirt") for m in METRICS]
    frame = pd.DataFrame(recs)
    for i in range(12):                                 # the other label columns a study carries
        frame[f"label{i}"] = frame["variation"] + str(i)
    return frame


@pytest.fixture(scope="module")
def wheres():
    return [{"metric": m, "estimator": e, "variation": v, "snr_db": s}
            for m in METRICS[:4] for e in ("kbr", "skirt") for v in VARIATIONS for s in SNRS][:120]


def naive_selections(rows: pd.DataFrame, wheres) -> list[np.ndarray]:
    """Baseline: each selection cuts the frame column by column (as tables.select did before)."""
    out = []
    for where in wheres:
        sel = rows[(rows["part"] == "table1") & (rows["status"] == "ok")]
        for k, v in where.items():
            col = sel[k]
            if isinstance(v, float) and k != "metric":
                ok = pd.Series(np.isclose(pd.to_numeric(col, errors="coerce").astype(float), v, rtol=1e-9, atol=0),
                               index=col.index)
            else:
                ok = col.astype(str) == str(v)
            sel = sel[ok]
        out.append(sel.index.to_numpy())
    return out


def selections(rows: pd.DataFrame, wheres) -> list[np.ndarray]:
    s = Selection(rows)
    return [rows.index.to_numpy()[s.positions("table1", where)] for where in wheres]


@pytest.mark.benchmark(group="report-selections")
def test_bench_selection(benchmark, rows, wheres):
    got = benchmark(selections, rows, wheres)
    assert [len(g) for g in got] == [len(SEEDS)] * len(wheres)


@pytest.mark.benchmark(group="report-selections")
def test_bench_naive_selections(benchmark, rows, wheres):
    got = benchmark(naive_selections, rows, wheres)
    assert all(np.array_equal(a, b) for a, b in zip(got, selections(rows, wheres)))


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
