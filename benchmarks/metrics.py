"""Pure metric functions (hand-checkable; see ``tests/test_metrics.py``).

The VAF itself has one home, :func:`jointbench.core.scores.vaf`;
the metrics below that are VAFs (:func:`stiffness_vaf`) call it. :func:`vafm` and :func:`vafv` are Xu &
Hollerbach's scores, not a VAF: their denominators are floored at 1 (the paper's rule).
"""
from __future__ import annotations

import numpy as np

from jointbench.core.scores import vaf



def rmse(x: np.ndarray, xhat: np.ndarray) -> float:
    """Root-mean-square error."""
    x = np.asarray(x, float)
    xhat = np.asarray(xhat, float)
    if x.shape != xhat.shape:
        raise ValueError(f"rmse: shapes differ: {x.shape} vs {xhat.shape}")
    return float(np.sqrt(np.mean((x - xhat) ** 2)))


def relative_error(true: float, est: float) -> float:
    """Signed relative error ``(est - true) / true`` in percent."""
    if true == 0:
        raise ValueError("relative_error: true value is zero")
    return float(100.0 * (est - true) / true)


def _pair(name: str, x, xhat) -> tuple[np.ndarray, np.ndarray]:
    x = np.asarray(x, float)
    xhat = np.asarray(xhat, float)
    if x.shape != xhat.shape:
        raise ValueError(f"{name}: shapes differ: {x.shape} vs {xhat.shape}")
    if x.size == 0:
        raise ValueError(f"{name}: empty signals")
    return x, xhat


def vafm(x: np.ndarray, xhat: np.ndarray) -> float:
    """Variance accounted for of the mean, in percent (Xu & Hollerbach's VAFM).

    ``100 (1 - (mean(x) - mean(xhat))^2 / max(mean(x^2), 1))``: how well ``xhat`` predicts the mean of
    ``x``. The denominator is floored at 1 (in the squared units of ``x``), the paper's rule for
    denominators near zero; without it a parameter with a small mean square (e.g. an inertia of
    0.06 kg m^2) would score on a different scale.

    References
    ----------
    Xu & Hollerbach (1998), eq. 8 (VAFM) and the rule below it ("when the denominator is less than one,
    we should set it to one").
    """
    x, xhat = _pair("vafm", x, xhat)
    return float(100.0 * (1.0 - (np.mean(x) - np.mean(xhat)) ** 2 / max(float(np.mean(x * x)), 1.0)))


def vafv(x: np.ndarray, xhat: np.ndarray, dt: float | None = None) -> float:
    """Variance accounted for of the variation, in percent (Xu & Hollerbach's VAFV).

    ``100 (1 - D(x~ - xhat~) / max(D(x~), 1))`` with ``x~ = x - mean(x)``, ``xhat~ = xhat - mean(xhat)``.

    * ``dt`` given (the paper's reading, recommended): ``D(z) = sum(z^2) dt``, the time integral
      ``int_0^L z^2 dt`` of eq. 8 by the rectangle rule, so the floor of 1 applies to the integral
      (units of ``x`` squared times seconds): it takes effect when ``var(x) L < 1`` for a record of
      length ``L = n dt``.
    * ``dt=None``: ``D(z) = mean(z^2)``, the floor applied to the variance (as VAFM floors
      ``mean(x^2)``).

    Without the floor both give ``100 (1 - var(x~ - xhat~) / var(x))``. A constant ``x`` (e.g. the
    inertia) then scores ``100 (1 - D(xhat~))`` instead of dividing by zero.

    References
    ----------
    Xu & Hollerbach (1998), eq. 8 (VAFV, ``int_0^L (y~ - yhat~)^2 dt / int_0^L y~^2``) and the rule
    below it ("when the denominator is less than one, we should set it to one").
    """
    x, xhat = _pair("vafv", x, xhat)
    if dt is not None and not (np.isfinite(dt) and dt > 0):
        raise ValueError(f"vafv: dt must be > 0 s, got {dt}")
    xt = x - np.mean(x)
    err = xt - (xhat - np.mean(xhat))
    w = (1.0 / x.size) if dt is None else float(dt)
    return float(100.0 * (1.0 - w * np.sum(err * err) / max(w * float(np.sum(xt * xt)), 1.0)))


# ------------------------------------------------------------- the comparison framework (section D)
def _realizations(name: str, k, khats) -> tuple[np.ndarray, np.ndarray]:
    k = np.asarray(k, float)
    khats = np.atleast_2d(np.asarray(khats, float))
    if k.ndim != 1 or khats.shape[1:] != k.shape:
        raise ValueError(f"{name}: need k (T,) and estimates (R, T); got {k.shape} and {khats.shape}")
    if k.size == 0:
        raise ValueError(f"{name}: empty signals")
    return k, khats


def stiffness_vaf(k: np.ndarray, khat: np.ndarray) -> float:
    """VAF (%) of one estimated stiffness against the simulated one: ``100 (1 - sum (k_hat - k)^2 /
    sum (k - mean k)^2)``: :func:`jointbench.core.scores.vaf` with ``bias_counts=True``. Unlike the
    VAF, an offset counts as an error (a bias lowers it). A constant ``k`` raises ``InputError`` (its VAF
    is undefined).

    References
    ----------
    van de Ruit, Mugge, Cavallo, Lataire, Ludvig & Schouten, "Quantitative comparison of time-varying
    system identification methods to describe human joint impedance" (metric 1); ../shared/specs/studies.md D.
    """
    k, khat = _pair("stiffness_vaf", k, khat)
    return vaf(k, khat, bias_counts=True)


def bias(k: np.ndarray, khats: np.ndarray) -> tuple[float, float]:
    """``(RMS, mean)`` over time of ``bias(t) = mean_r k_hat_r(t) - k(t)`` for R realizations (rows of
    ``khats``, shape (R, T)) of an estimate of the stiffness ``k`` (T,).

    References
    ----------
    van de Ruit et al., "Quantitative comparison ..." (metric 2); studies.md D.
    """
    k, khats = _realizations("bias", k, khats)
    b = khats.mean(axis=0) - k
    return float(np.sqrt(np.mean(b * b))), float(np.mean(b))


def random_error(khats: np.ndarray) -> float:
    """RMS over time of the standard deviation over the R realizations (ddof 1), shape (R, T); R >= 2.

    References
    ----------
    van de Ruit et al., "Quantitative comparison ..." (metric 3, the spread over realizations); studies.md D.
    """
    khats = np.atleast_2d(np.asarray(khats, float))
    if khats.shape[0] < 2:
        raise ValueError(f"random_error: needs at least 2 realizations, got {khats.shape[0]}")
    return float(np.sqrt(np.mean(np.var(khats, axis=0, ddof=1))))


def total_error(k: np.ndarray, khats: np.ndarray) -> float:
    """RMS over time and realizations of ``k_hat_r(t) - k(t)``; ``total^2 = bias_rms^2 + random^2 (R-1)/R``.

    References
    ----------
    van de Ruit et al., "Quantitative comparison ..." (metric 4); studies.md D.
    """
    k, khats = _realizations("total_error", k, khats)
    return float(np.sqrt(np.mean((khats - k) ** 2)))


def _crossing(t: np.ndarray, m: np.ndarray, i: int, level: float) -> float:
    """Time where ``m`` crosses ``level`` between samples ``i - 1`` and ``i`` (linear interpolation)."""
    if i == 0 or m[i] == m[i - 1]:
        return float(t[i])
    return float(t[i - 1] + (t[i] - t[i - 1]) * (level - m[i - 1]) / (m[i] - m[i - 1]))


def step_rise_time(t: np.ndarray, m: np.ndarray) -> float:
    """10-90 % rise time (s) of ``m``, a response normalised to go from 0 (old level) to 1 (new level)
    within the times ``t`` (the neighbourhood of one step): from the last upward crossing of 0.1 before
    ``m`` first reaches 0.9 to that first time (linear interpolation between samples). A linear ramp of
    duration D gives 0.8 D. Infinite when ``m`` never reaches 0.9, or never lies below 0.1 before it."""
    t, m = np.asarray(t, float), np.asarray(m, float)
    above = np.flatnonzero(m >= 0.9)
    if not len(above):
        return float("inf")
    i90 = int(above[0])
    below = np.flatnonzero(m[:i90] < 0.1)
    if not len(below):
        return float("inf")
    i10 = int(below[-1]) + 1
    return _crossing(t, m, i90, 0.9) - _crossing(t, m, i10, 0.1)


def steps(k: np.ndarray, threshold: float = 0.5) -> np.ndarray:
    """Indices of the samples where ``k`` jumps (first sample at the new level) by more than ``threshold``
    times its range: the steps of a square wave."""
    k = np.asarray(k, float)
    span = float(np.max(k) - np.min(k)) if k.size else 0.0
    if span == 0:
        return np.zeros(0, int)
    return np.flatnonzero(np.abs(np.diff(k)) > threshold * span) + 1


def rise_time(t: np.ndarray, k: np.ndarray, khat_mean: np.ndarray) -> tuple[float, int]:
    """``(mean rise time (s), number of steps)`` of the mean estimate ``khat_mean`` at the steps of the
    simulated square-wave stiffness ``k`` (both on the times ``t`` of the scored interval).

    Each step from level a to level b is judged on the samples half-way to the neighbouring steps (or to
    the ends of ``t``) with ``(khat_mean - a) / (b - a)`` (:func:`step_rise_time`); the levels are the
    medians of ``k`` over those halves. NaN with no step inside ``t``; infinite when one step is never
    followed from 10 % to 90 %. An ideal square wave rises in 0 s (sampled: 0.8 of a sample interval).

    References
    ----------
    van de Ruit et al., "Quantitative comparison ..." (metric 5, the rise time between two stiffness
    levels); studies.md D.
    """
    t, k, kh = (np.asarray(v, float) for v in (t, k, khat_mean))
    if not (t.shape == k.shape == kh.shape):
        raise ValueError(f"rise_time: shapes differ: {t.shape}, {k.shape}, {kh.shape}")
    idx = steps(k)
    if not len(idx):
        return float("nan"), 0
    edges = np.concatenate([[0], idx, [len(k)]])
    out = []
    for j, i in enumerate(idx):
        lo = (edges[j] + i) // 2
        hi = (i + edges[j + 2]) // 2
        a, b = float(np.median(k[lo:i])), float(np.median(k[i:hi]))
        out.append(step_rise_time(t[lo:hi], (kh[lo:hi] - a) / (b - a)))
    return float(np.mean(out)), len(idx)
