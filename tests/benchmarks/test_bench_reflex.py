"""The parallel cascade on 60 s at 100 Hz and pv_irf on 100 s at 100 Hz (issue 21: under 0.2 s and 0.5 s),
each against a same-run baseline.

Run with ``--benchmark-enable`` for timings; by default (``--benchmark-disable``) each runs once as a test.

- ``parallel_cascade`` against the obvious dense implementation of the same procedure
  (:func:`naive_parallel_cascade`: an explicit regression matrix and ``numpy.linalg.lstsq`` for every
  candidate delay and for each pathway at every iteration): the estimator must be at least 3 times faster
  (it scans every delay on one set of normal equations and iterates on them).
- ``pv_irf`` against one dense least-squares solve of its own regression (``numpy.linalg.lstsq`` on the
  explicit N x (M L + M + 1) matrix): the whole fit (slow angle, checks, fit, segment-robust covariance)
  may take at most 4 times that one solve.
"""
import numpy as np
import pytest

from jointbench import estimators, sims
from jointbench.estimators import _reflex as rx
from jointbench.estimators._twosided import regressor

PRALDS = {"kind": "pralds", "rms": 0.02, "min_hold": "20 ms", "max_hold": "200 ms", "smoothing": "20 Hz"}


@pytest.fixture(scope="module")
def reflex_trial():
    j = {"model": "second_order", "I": 0.01, "B": 0.8, "K": 140, "reflex": {"gain": 8, "delay": "40 ms"}}
    e = sims.Experiment.from_mapping({"joint": j, "apparatus": {"kind": "position_servo", "damping": 30},
                                      "perturbation": PRALDS, "sensors": {"torque": {"noise_variance_ratio": 0.03}},
                                      "fs_sim": 1000, "duration": 62, "acquisition": {"fs": "100 Hz", "trim": "1 s"}})
    return sims.simulate(e, 0)


@pytest.fixture(scope="module")
def lpv_trial():
    j = {"model": "position_dependent", "I": 0.01, "B": 0.8, "K": {"polynomial": [100, 150, 200]},
         "angle_range": [-0.6, 0.4]}
    pert = {"kind": "moving", "movement": {"shape": "sine", "mean": -0.105, "amplitude": 0.305, "frequency": 0.1},
            "perturbation": PRALDS}
    e = sims.Experiment.from_mapping({"joint": j, "apparatus": {"kind": "position_servo", "damping": 30},
                                      "perturbation": pert, "sensors": {"torque": {"noise_rms": 0.2}},
                                      "fs_sim": 1000, "duration": 102,
                                      "acquisition": {"detrend": False, "fs": "100 Hz", "trim": "1 s"}})
    return sims.simulate(e, 0)


def naive_parallel_cascade(trial, m=4, window=50, delays=range(2, 11), iterations=5):
    """Baseline: the same procedure written plainly (dense matrices, ``lstsq`` for every fit)."""
    u = trial.angle - trial.angle.mean()
    y = trial.torque - trial.torque.mean()
    x = np.maximum(rx.velocity(u, trial.fs), 0.0)
    U = np.ascontiguousarray(regressor(u, m, m, "zero")[0])
    rows = slice(window, len(u) - m)
    best = None
    for d in delays:
        X = np.ascontiguousarray(rx.lag_matrix(x - x[rows].mean(), d, window - d + 1))
        Z = np.hstack([U, X])[rows]
        c, res, *_ = np.linalg.lstsq(Z, y[rows], rcond=None)
        if best is None or res[0] < best[0]:
            best = (res[0], d, X)
    _, d, X = best
    tqR = np.zeros(len(y))
    for _ in range(iterations):
        hI = np.linalg.lstsq(U[rows], (y - tqR)[rows], rcond=None)[0]
        tqI = U @ hI
        hR = np.linalg.lstsq(X[rows], (y - tqI)[rows], rcond=None)[0]
        tqR = X @ hR
    return hI, d


@pytest.mark.benchmark(group="reflex-parallel-cascade-60s-100Hz")
def test_bench_parallel_cascade(benchmark, reflex_trial, speedup):
    est = estimators.make("parallel_cascade")
    out = benchmark(est.fit, reflex_trial)
    assert out.reflex_h is not None and abs(out.reflex_delay - 4) <= 1
    speedup(lambda: est.fit(reflex_trial), lambda: naive_parallel_cascade(reflex_trial), 3.0)


@pytest.mark.benchmark(group="reflex-parallel-cascade-60s-100Hz")
def test_bench_naive_parallel_cascade(benchmark, reflex_trial):
    hI, d = benchmark(naive_parallel_cascade, reflex_trial)
    assert abs(d - 4) <= 2 and abs(hI.sum() / 140.0 - 1) < 0.1


def dense_pv_lstsq(trial, n_basis=4, m=4, cutoff=0.5):
    """Baseline: one dense least-squares solve of pv_irf's regression."""
    from numpy.polynomial import chebyshev

    from jointbench.estimators.pv_irf import slow_part

    s = slow_part(trial.angle, trial.fs, cutoff)
    rows = slice(m, trial.n - m)
    x = 2 * (s[rows] - s[rows].min()) / np.ptp(s[rows]) - 1
    T1 = chebyshev.chebvander(x, n_basis)
    U = regressor(trial.angle - s, m, m, "zero")[0][rows]
    X = np.hstack([(T1[:, :n_basis, None] * U[:, None, :]).reshape(len(x), -1), T1])
    return np.linalg.lstsq(X, (trial.torque - trial.torque.mean())[rows], rcond=None)[0]


@pytest.mark.benchmark(group="reflex-pv-irf-100s-100Hz")
def test_bench_pv_irf(benchmark, lpv_trial, speedup):
    est = estimators.make("pv_irf")
    out = benchmark(est.fit, lpv_trial)
    grid = np.linspace(-0.3, 0.1, 5)
    assert np.max(np.abs(out.stiffness_at(grid) - (100 + 150 * grid + 200 * grid ** 2))) < 10
    speedup(lambda: est.fit(lpv_trial).intervals, lambda: dense_pv_lstsq(lpv_trial), 0.25)


@pytest.mark.benchmark(group="reflex-pv-irf-100s-100Hz")
def test_bench_dense_pv_lstsq(benchmark, lpv_trial):
    c = benchmark(dense_pv_lstsq, lpv_trial)
    assert np.all(np.isfinite(c))
