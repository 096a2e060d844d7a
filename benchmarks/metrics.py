"""Pure metric functions (hand-checkable; see ``tests/test_metrics.py``)."""
from __future__ import annotations

import numpy as np


def vaf(y: np.ndarray, yhat: np.ndarray) -> float:
    """Variance accounted for, in percent: ``100 (1 - var(y - yhat) / var(y))``.

    References
    ----------
    van de Ruit et al. (2018), eq. 17; Westwick & Perreault (2012), Table I (%VAF).
    """
    y = np.asarray(y, float)
    yhat = np.asarray(yhat, float)
    if y.shape != yhat.shape:
        raise ValueError(f"vaf: shapes differ: {y.shape} vs {yhat.shape}")
    vy = np.var(y)
    if vy == 0:
        raise ValueError("vaf: the reference signal has zero variance")
    return float(100.0 * (1.0 - np.var(y - yhat) / vy))


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
