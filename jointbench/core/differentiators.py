"""Discrete-time differentiators: of a signal (:func:`central`), and the impulse responses and impedance IRF of
Westwick & Perreault (2012).

References
----------
Westwick, D. T. & Perreault, E. J. (2012). Estimates of acausal joint impedance models.
IEEE Trans. Biomed. Eng. 59(10), eqs. 10-13 and Sec. III-B.
Fornberg, B. (1988). Generation of finite difference formulas on arbitrarily spaced grids. Math. Comp. 51(184),
699-706 (central and one-sided difference formulas: :func:`numpy.gradient`'s).

Erratum recorded here (check W1): the printed eq. 13 gives ``h2(0) = -(ws/N)^2 (N^2/12 + 1)``. The
inverse DFT of ``-w_k^2`` over ``k = -N/2 ... N/2-1`` gives ``-(ws/N)^2 (N^2 + 2)/12``, i.e.
``N^2/12 + 1/6``; :func:`h2` uses the latter (``tests/test_differentiators.py`` shows the printed
value is off by ``(5/6)(ws/N)^2``). For ``h1`` the term at ``k = -N/2`` (Nyquist) would make the
inverse DFT complex; eq. 12 is the real part, i.e. the Nyquist term of ``jw`` taken as zero.
"""
from __future__ import annotations

import numpy as np


def central(x: np.ndarray, fs: float) -> np.ndarray:
    """The derivative of ``x`` (along axis 0) sampled at ``fs``: central differences ``(x[i+1] - x[i-1]) fs / 2``
    inside, first differences at the two ends (:func:`numpy.gradient`).

    Inside, its gain at frequency ``f`` is ``sin(2 pi f / fs) fs`` against the true ``2 pi f``: 1 % low at
    f / fs = 0.04 (40 Hz at 1 kHz), 23 % low at f / fs = 0.19 (19 Hz at 100 Hz). A derivative wanted up to a few
    tens of Hz is therefore best taken at the recorded rate, before decimation
    (:func:`jointbench.core.signal.resample_trial` keeps the angle's as a channel).
    """
    return np.gradient(np.asarray(x, float), 1.0 / fs, axis=0)


def _n(N: int) -> np.ndarray:
    if N < 4 or N % 2:
        raise ValueError(f"record length N must be even and >= 4, got {N}")
    return np.arange(1, N)


def h0(N: int) -> np.ndarray:
    """Zero-order 'differentiator' (eq. 10): a Kronecker delta, length ``N`` (n = 0 ... N-1)."""
    out = np.zeros(N)
    out[0] = 1.0
    return out


def h1(N: int, fs: float) -> np.ndarray:
    """First-order differentiator (eq. 12), periodic sequence ``n = 0 ... N-1``."""
    n = _n(N)
    ws = 2 * np.pi * fs
    x = 2 * np.pi * n / N
    out = np.zeros(N)
    out[1:] = ws / (2 * N) * (-1.0) ** n * np.sin(x) / (1 - np.cos(x))
    return out


def h2(N: int, fs: float) -> np.ndarray:
    """Second-order differentiator (eq. 13 with the corrected ``n = 0`` term), ``n = 0 ... N-1``."""
    n = _n(N)
    ws = 2 * np.pi * fs
    out = np.empty(N)
    out[0] = -(ws / N) ** 2 * (N ** 2 + 2) / 12.0
    out[1:] = (ws / N) ** 2 * (-1.0) ** (n + 1) / (1 - np.cos(2 * np.pi * n / N))
    return out


def h2_as_printed(N: int, fs: float) -> np.ndarray:
    """Eq. 13 exactly as printed (kept to document the erratum; do not use)."""
    out = h2(N, fs)
    out[0] = -(2 * np.pi * fs / N) ** 2 * (N ** 2 / 12.0 + 1.0)
    return out


def idft_derivative(N: int, fs: float, order: int) -> np.ndarray:
    """Reference: real inverse DFT of ``(j w_k)^order`` over ``k = -N/2 ... N/2-1``.

    For odd orders the Nyquist bin is set to zero (an odd real sequence cannot carry it).
    """
    k = np.fft.fftfreq(N) * N
    H = (1j * 2 * np.pi * fs * k / N) ** order
    if order % 2:
        H[N // 2] = 0.0
    return np.fft.ifft(H).real


def two_sided(h: np.ndarray, m1: int, m2: int) -> tuple[np.ndarray, np.ndarray]:
    """Lags ``-m1 ... m2`` and the matching values of a periodic sequence ``h`` (n = 0 ... N-1)."""
    lags = np.arange(-m1, m2 + 1)
    return lags, h[lags % len(h)]


def impedance_irf(I: float, B: float, K: float, fs: float, N: int) -> np.ndarray:
    """``h_s(n) = I h2(n) + B h1(n) + K h0(n)`` (Sec. III-B), periodic, ``n = 0 ... N-1``."""
    return I * h2(N, fs) + B * h1(N, fs) + K * h0(N)
