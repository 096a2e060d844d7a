"""The time-varying IRF estimators at the sizes of issue 9, each beside a same-run baseline.

Sizes: ``ensemble_irf`` on 1000 samples x 50 realizations x 9 lags; ``guarin`` on 1000 x 10 realizations
with 21 Gaussian basis functions (9 lags); ``sds`` on 5 trials of 40 s at 100 Hz. Baselines, computing the
same estimate the direct way: a loop over times with ``numpy.linalg.pinv`` (``tv_ident``'s 'tvfil'
approach), the dense regression matrix of the basis expansion with ``numpy.linalg.lstsq``, and a loop
over SDS windows building each window's rows. ``make bench`` judges each fit's ratio to its baseline of
the same run. (The absolute targets of issues 9 and 22, ten and a hundred times the REKLAB toolbox's
time, are retired (issue 34): what counts is the time a user waits, results/benchmarks.md.)

Run with ``--benchmark-enable`` for timings (``make bench``); by default each runs once as a test.
"""
import numpy as np
import pytest
from numpy.lib.stride_tricks import sliding_window_view

from jointbench import estimators
from jointbench.estimators.guarin import time_basis
from jointbench.core.ensemble import Ensemble
from jointbench.core.estimate_tv import TVIRFEstimate

FS = 100.0
LAGS = np.arange(-4, 5)


def tv_ensemble(n: int, R: int, seed: int, noise: float = 0.05) -> tuple[Ensemble, np.ndarray]:
    """White inputs through an IRF whose gain varies sinusoidally; output noise ``noise`` of its std."""
    rng = np.random.default_rng(seed)
    h = np.array([0.3, -0.8, 1.5, -4.0, 20.0, 4.0, 2.0, 1.0, 0.5])
    g = 1.0 + 0.3 * np.sin(2 * np.pi * np.arange(n) / n)
    H = h[:, None] * g[None, :]
    tv = TVIRFEstimate(LAGS, H, FS, np.arange(n) / FS, np.ones(n, bool))
    U = rng.standard_normal((n, R))
    Y = np.column_stack([tv.predict(U[:, r]) for r in range(R)])
    Y += noise * Y.std() * rng.standard_normal(Y.shape)
    return Ensemble.from_arrays(U, Y, FS), H


# ------------------------------------------------------------------------------------ ensemble IRF
@pytest.fixture(scope="module")
def ens50():
    return tv_ensemble(1000, 50, seed=1992)


def pinv_loop(ens: Ensemble) -> np.ndarray:
    """Baseline: at every time the R x L matrix of lagged (ensemble-mean-removed) inputs, its pseudo-inverse."""
    U, Y = ens.inputs, ens.outputs
    U = U - U.mean(axis=1, keepdims=True)
    Y = Y - Y.mean(axis=1, keepdims=True)
    X = sliding_window_view(U, len(LAGS), axis=0)[..., ::-1]
    return np.array([np.linalg.pinv(X[i]) @ Y[i + 4] for i in range(len(X))]).T


@pytest.mark.benchmark(group="ensemble_irf-1000x50x9")
def test_bench_ensemble_irf(benchmark, ens50):
    ens, H = ens50
    fit = estimators.make("ensemble_irf").fit
    fit(ens)            # the process's first fit loads the compiled solver (numba's disk cache): not timed
    est = benchmark(fit, ens)
    v = est.valid
    assert np.median(np.abs(est.stiffness(est.time[v]) / H.sum(axis=0)[v] - 1)) < 0.05


@pytest.mark.benchmark(group="ensemble_irf-1000x50x9")
def test_bench_ensemble_irf_pinv_loop_baseline(benchmark, ens50):
    ens, _ = ens50
    h = benchmark(pinv_loop, ens)
    full = estimators.make("ensemble_irf", {"solver": "full"}).fit(ens)
    assert np.allclose(full.h[:, full.valid], h, rtol=1e-7, atol=1e-9)      # the same estimate


# ------------------------------------------------------------------------------------------- Guarin
@pytest.fixture(scope="module")
def ens10():
    return tv_ensemble(1000, 10, seed=2017)


def dense_basis_lstsq(ens: Ensemble, M: int) -> np.ndarray:
    """Baseline: the stacked regression matrix [phi_m(t) u_r(t - k)] of every realization, then lstsq."""
    U = ens.inputs - ens.inputs.mean(axis=0)
    Y = ens.outputs - ens.outputs.mean(axis=0)
    n, R = U.shape
    B = time_basis("gaussian", M, n)[4:n - 4]
    rows = []
    for r in range(R):
        X = sliding_window_view(U[:, r], len(LAGS))[:, ::-1]                 # (n - 8, 9): sample i + 4
        rows.append((B[:, :, None] * X[:, None, :]).reshape(len(X), -1))
    A = np.vstack(rows)
    c = np.linalg.lstsq(A, Y[4:n - 4].T.ravel(), rcond=None)[0]
    return (time_basis("gaussian", M, n) @ c.reshape(M, len(LAGS))).T


@pytest.mark.benchmark(group="guarin-1000x10x21")
def test_bench_guarin(benchmark, ens10):
    ens, H = ens10
    est = benchmark(estimators.make("guarin", {"n_basis": 21, "basis": "gaussian"}).fit, ens)
    v = est.valid
    assert np.max(np.abs(est.stiffness(est.time[v]) / H.sum(axis=0)[v] - 1)) < 0.05


@pytest.mark.benchmark(group="guarin-1000x10x21")
def test_bench_guarin_dense_lstsq_baseline(benchmark, ens10):
    ens, _ = ens10
    h = benchmark(dense_basis_lstsq, ens, 21)
    est = estimators.make("guarin", {"n_basis": 21}).fit(ens)
    assert np.allclose(est.h, h, rtol=1e-6, atol=1e-8 * np.abs(h).max())   # the same estimate


# ---------------------------------------------------------------------------------------------- SDS
@pytest.fixture(scope="module")
def ens5():
    return tv_ensemble(4000, 5, seed=2012)


def window_loop(ens: Ensemble, W: int = 100) -> np.ndarray:
    """Baseline: for every window, the rows of each trial's segment (mean removed) stacked, then lstsq."""
    U, Y = ens.inputs, ens.outputs
    n = U.shape[0]
    out = []
    for s in range(n - W + 1):
        seg_u = U[s:s + W] - U[s:s + W].mean(axis=0)
        seg_y = Y[s:s + W] - Y[s:s + W].mean(axis=0)
        X = sliding_window_view(seg_u, len(LAGS), axis=0)[..., ::-1]          # (W - 8, R, 9)
        A = X.transpose(1, 0, 2).reshape(-1, len(LAGS))
        b = seg_y[4:W - 4].T.ravel()
        out.append(np.linalg.lstsq(A, b, rcond=None)[0])
    return np.array(out).T


@pytest.mark.benchmark(group="sds-5x40s-100Hz")
def test_bench_sds(benchmark, ens5):
    ens, H = ens5
    fit = estimators.make("sds").fit
    fit(ens)            # as for ensemble_irf: the compiled solver loaded outside the timing
    est = benchmark(fit, ens)
    v = est.valid
    assert np.max(np.abs(est.stiffness(est.time[v]) / H.sum(axis=0)[v] - 1)) < 0.05


@pytest.mark.benchmark(group="sds-5x40s-100Hz")
def test_bench_sds_window_loop_baseline(benchmark, ens5):
    ens, _ = ens5
    h = benchmark.pedantic(window_loop, args=(ens,), rounds=3, iterations=1)
    est = estimators.make("sds", {"solver": "full"}).fit(ens)
    assert np.allclose(est.h[:, est.valid], h, rtol=1e-6, atol=1e-8 * np.abs(h).max())   # the same estimate
