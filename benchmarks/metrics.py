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
