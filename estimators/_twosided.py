"""Shared pieces of the two-sided (acausal) IRF estimators: lag settings, checks, LS and Toeplitz solvers.

Private module (the leading underscore keeps it out of the estimator registry). Used by
:mod:`estimators.irf_ls`, :mod:`estimators.irf_corr` and :mod:`estimators.ibk_irf`.

References
----------
Westwick, D. T. & Perreault, E. J. (2012). Estimates of acausal joint impedance models.
IEEE Trans. Biomed. Eng. 59(10), doi:10.1109/TBME.2012.2213339, eqs. 14 and 15.

Hunter, I. W. & Kearney, R. E. (1983). Two-sided linear filter identification.
Med. Biol. Eng. Comput. 21, 203-209.
"""
from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np
import scipy.fft
import scipy.linalg
from numpy.lib.stride_tricks import sliding_window_view

from jointbench.errors import InputError
from jointbench.estimate import IRFEstimate
from jointbench.schema import param
from jointbench.types import Trial

Edges = Literal["zero", "valid"]

# Rows of the regression matrix handled per QR block (bounds memory at about 16 MB per block).
_BLOCK_VALUES = 2 ** 21


@dataclasses.dataclass(frozen=True)
class LagSettings:
    """Lag range and preprocessing shared by the two-sided IRF estimators."""

    lag_before: float = param(0.1, unit="s", ge=0,
                              doc="anticipatory memory: negative lags down to -M1, M1 = round(lag_before*fs)")
    lag_after: float = param(0.1, unit="s", ge=0,
                             doc="causal memory: positive lags up to M2 = round(lag_after*fs)")
    remove_mean: bool = param(True, doc="subtract each record's mean from angle and torque before fitting")


def lag_samples(settings: LagSettings, fs: float) -> tuple[int, int]:
    """``(M1, M2)``: the lag range in samples at sampling rate ``fs``."""
    return int(round(settings.lag_before * fs)), int(round(settings.lag_after * fs))


def check_lengths(name: str, trials: list[Trial], m1: int, m2: int, settings: LagSettings) -> None:
    """Raise :class:`InputError` when a record is not longer than the lag range ``M1 + M2 + 1``."""
    n_lags = m1 + m2 + 1
    fs = trials[0].fs
    for t in trials:
        if t.n <= n_lags:
            raise InputError(
                f"{name}: record '{t.name}' has {t.n} samples ({t.n / fs:g} s), not more than the lag range "
                f"M1+M2+1 = {n_lags} samples ({n_lags / fs:g} s) set by lag_before = {settings.lag_before:g} s "
                f"and lag_after = {settings.lag_after:g} s; shorten the lags or use longer records")


def input_output(name: str, trials: list[Trial], remove_mean: bool) -> list[tuple[np.ndarray, np.ndarray]]:
    """``(u, y)`` = (angle, torque) per record, optionally with each record's mean removed."""
    pairs = []
    for t in trials:
        u, y = t.angle.copy(), t.torque.copy()
        if remove_mean:
            u -= u.mean()
            y -= y.mean()
        pairs.append((u, y))
    scale = max(float(np.abs(t.angle).max()) for t in trials)
    if not any(np.abs(u).max() > 1e-12 * scale for u, _ in pairs):
        raise InputError(f"{name}: the angle (input) is identically zero"
                         + (" after removing its mean" if remove_mean else "") + "; nothing to identify")
    return pairs


def regressor(u: np.ndarray, m1: int, m2: int, edges: Edges) -> tuple[np.ndarray, slice]:
    """Rows of ``U(i, j) = u(i - j + M1)`` (lags ``k = j - M1``) and the matching slice of ``y``.

    ``edges="zero"`` takes ``u = 0`` outside the record (one row per sample); ``"valid"`` keeps only the
    rows whose lags all fall inside the record. The result is a read-only strided view (no copy).
    """
    n, n_lags = len(u), m1 + m2 + 1
    if edges == "zero":
        padded = np.concatenate([np.zeros(m2), u, np.zeros(m1)])
        return sliding_window_view(padded, n_lags)[:, ::-1], slice(0, n)
    return sliding_window_view(u, n_lags)[:, ::-1], slice(m2, n - m1)


def ls_irf(name: str, pairs: list[tuple[np.ndarray, np.ndarray]], m1: int, m2: int, edges: Edges) -> np.ndarray:
    """Least-squares two-sided IRF (eq. 14) pooled over records by stacking their regression rows.

    The rows ``[U | y]`` are reduced block by block with Householder QR to an (L+1)x(L+1) triangle
    ``[[R, z], [0, rho]]``, so ``R h = z`` solves ``min ||U h - y||`` with the accuracy of a QR least-squares
    solver (the condition number of ``U`` enters once, not squared as in the normal equations) while
    memory stays bounded for long or many records. ``R h = z`` is then solved by
    :func:`scipy.linalg.lstsq` (SVD): directions that the input does not excite to machine precision
    (very narrow-band perturbations) get the minimum-norm solution instead of overflowing.
    """
    n_lags = m1 + m2 + 1
    block = max(n_lags + 1, _BLOCK_VALUES // (n_lags + 1))
    tri = np.zeros((0, n_lags + 1))
    n_rows = 0
    for u, y in pairs:
        U, rows = regressor(u, m1, m2, edges)
        y = y[rows]
        n_rows += len(y)
        for start in range(0, len(y), block):
            stop = min(start + block, len(y))
            aug = np.empty((len(tri) + stop - start, n_lags + 1), order="F")
            aug[:len(tri)] = tri
            aug[len(tri):, :n_lags] = U[start:stop]
            aug[len(tri):, n_lags] = y[start:stop]
            raw = scipy.linalg.qr(aug, mode="raw", overwrite_a=True, check_finite=False)[0][0]
            tri = np.triu(raw[:n_lags + 1])
    if n_rows < n_lags:
        raise InputError(f"{name}: {n_rows} usable samples (edges = 'valid') for {n_lags} lags; the fit is "
                         f"underdetermined: use edges = 'zero', shorter lags or longer records")
    return scipy.linalg.lstsq(tri[:n_lags, :n_lags], tri[:n_lags, n_lags], check_finite=False)[0]


def corr_irf(name: str, pairs: list[tuple[np.ndarray, np.ndarray]], m1: int, m2: int) -> np.ndarray:
    """Correlation (Hunter & Kearney) two-sided IRF, eq. 15: ``h = Phi_uu^{-1} phi_uy``.

    Biased (un-normalised) linear correlations by zero-padded FFT, summed over records, then the
    symmetric Toeplitz system is solved by Levinson recursion (:func:`scipy.linalg.solve_toeplitz`).
    """
    n_lags = m1 + m2 + 1
    phi_uu = np.zeros(n_lags)
    phi_uy = np.zeros(n_lags)
    for u, y in pairs:
        nfft = scipy.fft.next_fast_len(len(u) + m1 + m2, real=True)
        fu = scipy.fft.rfft(u, nfft)
        r_uu = scipy.fft.irfft(np.abs(fu) ** 2, nfft)
        r_uy = scipy.fft.irfft(np.conj(fu) * scipy.fft.rfft(y, nfft), nfft)  # sum_s u(s) y(s + k)
        phi_uu += r_uu[:n_lags]
        phi_uy += np.concatenate([r_uy[nfft - m1:], r_uy[:m2 + 1]])  # lags -M1 ... M2
    try:
        h = scipy.linalg.solve_toeplitz(phi_uu, phi_uy, check_finite=False)
    except np.linalg.LinAlgError:
        h = np.full(n_lags, np.nan)
    if not np.all(np.isfinite(h)):
        raise InputError(f"{name}: the input autocorrelation matrix ({n_lags} lags) is singular; the angle "
                         f"does not excite all lags: use a broader-band perturbation or fewer lags")
    return h


def estimate_irf(name: str, trials: list[Trial], settings: LagSettings, method: Literal["ls", "corr"],
                 edges: Edges, estimator: str) -> IRFEstimate:
    """Check the records, fit the two-sided IRF with ``method`` and wrap it in an :class:`IRFEstimate`."""
    fs = trials[0].fs
    m1, m2 = lag_samples(settings, fs)
    check_lengths(name, trials, m1, m2, settings)
    pairs = input_output(name, trials, settings.remove_mean)
    h = ls_irf(name, pairs, m1, m2, edges) if method == "ls" else corr_irf(name, pairs, m1, m2)
    return IRFEstimate(lags=np.arange(-m1, m2 + 1), h=h, fs=fs, time=trials[0].time, estimator=estimator)
