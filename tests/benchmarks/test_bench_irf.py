"""Two-sided IRF solvers on 30 s at 500 Hz with +-50 lags, against a naive dense least-squares baseline.

Run with ``--benchmark-enable`` for timings; by default (``--benchmark-disable``) each runs once as a test.
"""
import numpy as np
import pytest
from numpy.lib.stride_tricks import sliding_window_view

from jointbench import estimators
from jointbench.core.estimate import IRFEstimate
from jointbench.core.types import Trial

FS, DURATION, M = 500.0, 30.0, 50
SETTINGS = {"lag_before": M / FS, "lag_after": M / FS, "remove_mean": False, "pseudo_inverse": "off"}  # plain LS
LS_SETTINGS = {**SETTINGS, "edges": "zero"}   # same rows as the naive dense baseline


@pytest.fixture(scope="module")
def case():
    rng = np.random.default_rng(2012)
    n = int(DURATION * FS)
    lags = np.arange(-M, M + 1)
    h = np.exp(-np.abs(lags) / 10.0) * np.cos(lags / 3.0)
    u = np.convolve(rng.standard_normal(n), np.ones(5) / 5, mode="same")  # mildly coloured input
    y = IRFEstimate(lags, h, FS, np.arange(n) / FS).predict(u) + 0.01 * rng.standard_normal(n)
    return h, Trial.from_arrays(u, y, FS)


def naive_dense_lstsq(u: np.ndarray, y: np.ndarray, m1: int, m2: int) -> np.ndarray:
    """Baseline: explicit N x (M1+M2+1) matrix U(i, j) = u(i - j + M1), then numpy.linalg.lstsq."""
    padded = np.concatenate([np.zeros(m2), u, np.zeros(m1)])
    U = np.ascontiguousarray(sliding_window_view(padded, m1 + m2 + 1)[:, ::-1])
    return np.linalg.lstsq(U, y, rcond=None)[0]


@pytest.mark.benchmark(group="irf-30s-500Hz")
def test_bench_irf2_ls(benchmark, case):
    h, trial = case
    est = estimators.make("irf2_ls", LS_SETTINGS)
    out = benchmark(est.fit, trial)
    assert np.linalg.norm(out.h - h) / np.linalg.norm(h) < 0.01


@pytest.mark.benchmark(group="irf-30s-500Hz")
def test_bench_irf2_corr(benchmark, case):
    h, trial = case
    est = estimators.make("irf2_corr", SETTINGS)
    out = benchmark(est.fit, trial)
    assert np.linalg.norm(out.h - h) / np.linalg.norm(h) < 0.01


@pytest.mark.benchmark(group="irf-30s-500Hz")
def test_bench_naive_dense_lstsq(benchmark, case):
    h, trial = case
    out = benchmark(naive_dense_lstsq, trial.angle, trial.torque, M, M)
    assert np.linalg.norm(out - h) / np.linalg.norm(h) < 0.01
    ls = estimators.make("irf2_ls", LS_SETTINGS).fit(trial)
    assert np.allclose(ls.h, out, rtol=1e-8, atol=1e-10)  # same estimate as irf2_ls (edges='zero')
