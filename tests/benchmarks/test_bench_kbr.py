"""KBR on one 40 s trial at 44 Hz (the paper's analysis window), with a dense explicit-kernel baseline.

Run with ``--benchmark-enable`` for timings; by default (``--benchmark-disable``) each runs once as a test.

Baseline: one weighted solve of eq. B.1 (``sigma_E^2 = 1``) in the dual form with the full kernel
matrices (:func:`tests.test_kbr.dense_solve`), on a 10 s trial because the dense solve grows like
``N^3`` (the ``S = sum_p gamma_p B_p K_0 B_p^T`` products, ``B_p`` of ``2 N_band x N`` with
``N_band`` proportional to ``N``): at 40 s expect about 64 times the 10 s time. The same single solve
by the low-rank estimator is benchmarked beside it; its cost grows like ``N`` (one FFT of an
``N x r`` matrix per coefficient, a QR with ``2 N_band`` rows).
"""
import tracemalloc

import numpy as np
import pytest

from jointbench import estimators
from jointbench.core.types import Trial
from tests.test_kbr import FS, dense_solve, filtered_noise, ltv_record, multisine, sine_k, wrist_frf

ONE_SOLVE = {"relax_iterations": 1, "refine": False}


def noisy_trial(duration: float) -> tuple[Trial, np.ndarray]:
    """Sinusoidal stiffness (period 20 s), output noise at SNR 10 dB."""
    u, y, k = ltv_record(multisine(2018), sine_k, duration=duration)
    y = y + filtered_noise(len(y), y.std() / np.sqrt(10.0), seed=1)
    return Trial.from_arrays(u, y, FS, name=f"{duration:g}s"), k


@pytest.fixture(scope="module")
def trial40():
    return noisy_trial(40.0)


@pytest.fixture(scope="module")
def trial10():
    return noisy_trial(10.0)[0]


@pytest.mark.benchmark(group="kbr-44Hz")
def test_bench_kbr_40s(benchmark, trial40):
    trial, k = trial40
    est = benchmark(estimators.make("kbr").fit, trial)
    sel = trial.time <= 30.0
    rmse = np.sqrt(np.mean((est.stiffness(trial.time)[sel] - np.abs(wrist_frf(est.f1, k[sel]))) ** 2))
    assert rmse < 1.0
    tracemalloc.start()
    estimators.make("kbr").fit(trial)
    peak = tracemalloc.get_traced_memory()[1] / 2 ** 20
    tracemalloc.stop()
    benchmark.extra_info["peak_mib"] = round(peak, 2)
    benchmark.extra_info["rmse_k"] = round(float(rmse), 3)
    benchmark.extra_info.update({k_: v for k_, v in est.info.items() if isinstance(v, int)})
    print(f"\nKBR 40 s at 44 Hz: peak traced memory {peak:.2f} MiB, RMSE_k {rmse:.3f} N m/rad, {est.info}")
    assert peak < 64


@pytest.mark.benchmark(group="kbr-44Hz")
def test_bench_kbr_one_solve_10s(benchmark, trial10):
    est = benchmark(estimators.make("kbr", ONE_SOLVE).fit, trial10)
    assert est.a.shape == (2, trial10.n)


@pytest.mark.benchmark(group="kbr-44Hz")
def test_bench_dense_one_solve_10s_baseline(benchmark, trial10):
    sigma = 20.0
    exact = {**ONE_SOLVE, "kernel_points": trial10.n, "eig_threshold": 1e-13, "max_rank": trial10.n}
    kbr = estimators.make("kbr", exact)
    pb = kbr.problem(trial10)
    dense = benchmark(dense_solve, pb, np.ones(len(pb.band)), FS, sigma)
    low = kbr.fit(trial10)
    for got, want in zip(np.vstack([low.a, low.b]), dense):   # the same estimate
        assert np.abs(got - want).max() < 1e-8 * np.abs(want).max()
