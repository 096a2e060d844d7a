"""Skirt decomposition on one 40 s record at 44 Hz (25 lines, N_p = 7), against a naive dense baseline.

Run with ``--benchmark-enable`` for timings; by default (``--benchmark-disable``) each runs once as a test.
"""
import numpy as np
import pytest

from jointbench import estimators
from jointbench.core.types import Trial

FS, T, NP, D = 44.0, 40.0, 7, 16
N = int(FS * T)
BINS = 4 + 32 * np.arange(25)          # 0.1 ... 19.3 Hz every 0.8 Hz (period 10 s, 4 periods)


def tv_basis(n: int) -> np.ndarray:
    """1, ramp, cos/sin of 1, 2, 3 cycles per record (eq. 14), written out again for the baseline."""
    x = np.arange(n) / n
    rows = [np.ones(n), 2 * x - 1]
    for m in (1, 2, 3):
        rows += [np.cos(2 * np.pi * m * x), np.sin(2 * np.pi * m * x)]
    return np.array(rows)


@pytest.fixture(scope="module")
def case():
    """y = sum_p b_p(t) (G_p u)(t) with G_1 = 0 (eq. 5, exactly representable) plus 1 % white noise."""
    rng = np.random.default_rng(2018)
    f = BINS / T
    amp = np.where(f <= 6, 1.0, 6 / f)
    X = np.zeros(N // 2 + 1, complex)
    X[BINS] = amp * np.exp(2j * np.pi * rng.uniform(size=len(BINS)))
    u = np.fft.irfft(X, N)
    u *= 0.02 / u.std()
    s = 2j * np.pi * np.fft.rfftfreq(N, 1 / FS)
    H = (10 * s + 100) * (0.003 * s ** 2 + 0.035 * s + 5.6) / (0.003 * s ** 2 + 10.035 * s + 105.6)
    Gp = np.array([H * c for c in (1, 0, 0.1, -0.05j, 0.03, 0.02, 0.01j, -0.01)])
    y = np.sum(tv_basis(N) * np.fft.irfft(Gp * np.fft.rfft(u), N, axis=1), axis=0)
    y += 0.01 * y.std() * rng.standard_normal(N)
    return Gp[:, BINS], Trial.from_arrays(u, y, FS)


def naive_dense(u: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Baseline: per band, the real time-domain regressors ``b_p(t) 2Re(U(l) e^{j w_l t} / N)`` (and the
    imaginary counterpart) for the three lines, transformed with an explicit DFT matrix of the band's
    bins, a constant transient term, and ``numpy.linalg.lstsq``; the centre line is kept."""
    n = np.arange(N)
    U, Y = np.fft.fft(u), np.fft.fft(y)
    b = tv_basis(N)
    P = len(b)
    out = np.empty((P, len(BINS)), complex)
    for c in range(1, len(BINS) - 1):
        trip = BINS[c - 1:c + 2]
        k = np.arange(max(1, trip[0] - D), trip[2] + D + 1)
        E = np.exp(-2j * np.pi * np.outer(k, n) / N)
        cols = []
        for part in (1, 1j):                                   # Re G, then Im G
            for l in trip:
                carrier = 2 * (part * U[l] * np.exp(2j * np.pi * l * n / N) / N).real
                cols += [E @ (bp * carrier) for bp in b]
        cols += [np.ones(len(k)), 1j * np.ones(len(k))]        # Re r0, Im r0
        A = np.array(cols).T
        sol = np.linalg.lstsq(np.vstack([A.real, A.imag]), np.concatenate([Y[k].real, Y[k].imag]), rcond=None)[0]
        z = (sol[:3 * P] + 1j * sol[3 * P:6 * P]).reshape(3, P).T
        out[:, c] = z[:, 1]
        if c == 1:
            out[:, 0] = z[:, 0]
        if c == len(BINS) - 2:
            out[:, -1] = z[:, 2]
    return out


@pytest.mark.benchmark(group="skirt-40s-44Hz")
def test_bench_skirt(benchmark, case):
    Gp, trial = case
    est = estimators.make("skirt")
    out = benchmark(est.fit, trial)
    assert (np.abs(out.Gp - Gp) / np.abs(Gp[0])).max() < 0.05   # 1 % output noise


@pytest.mark.benchmark(group="skirt-40s-44Hz")
def test_bench_naive_dense(benchmark, case):
    Gp, trial = case
    out = benchmark(naive_dense, trial.angle, trial.torque)
    fast = estimators.make("skirt").fit(trial)
    assert np.allclose(fast.Gp, out, rtol=0, atol=1e-8 * np.abs(out).max())  # the same estimate
