"""Intervals: the confidence level, its quantiles, the segment-robust covariance and the PSD pseudo-inverse.

One home for what every interval-returning estimator shares (``tests/test_one_home.py`` fails on a second
definition): :data:`LEVEL` (the level of every interval JointBench reports), :func:`t_quantile` and
:func:`z_quantile` (two-sided), :func:`segment_covariance` (one rule for the segments) and
:func:`psd_pinv` / :func:`psd_solve` (the pseudo-inverse of a symmetric positive semidefinite matrix such as
a Gram matrix ``X^T X``, from its eigen-decomposition).
"""
from __future__ import annotations

import numpy as np

__all__ = ["LEVEL", "MAX_SEGMENTS", "SEGMENT_COLUMNS", "MIN_SEGMENTS", "NEIGHBOUR_WEIGHT", "PINV_RCOND", "t_quantile",
           "z_quantile", "segment_covariance", "eigen_pinv", "psd_pinv", "psd_solve"]

#: confidence level of every interval JointBench reports
LEVEL = 0.95

#: at most this many segments (clusters) for the segment-robust covariance ...
MAX_SEGMENTS = 40
#: ... each at least this many times the number of regressors long; fewer than MIN_SEGMENTS: no covariance
SEGMENT_COLUMNS = 4
MIN_SEGMENTS = 8
#: weight of the neighbouring segments' products in the segment-robust covariance (Bartlett: 1/2)
NEIGHBOUR_WEIGHT = 0.5
#: default cut-off of :func:`psd_pinv` relative to the largest eigenvalue (numpy's ``pinv`` default)
PINV_RCOND = 1e-15


def t_quantile(dof: float, level: float = LEVEL) -> float:
    """Two-sided ``level`` quantile of Student's t with ``dof`` degrees of freedom (``t_{(1+level)/2}``)."""
    from scipy import stats

    return float(stats.t.ppf(0.5 + level / 2, dof))


def z_quantile(level: float = LEVEL) -> float:
    """Two-sided ``level`` quantile of the standard normal distribution (1.96 at 95 %)."""
    from scipy import stats

    return float(stats.norm.ppf(0.5 + level / 2))


def segment_covariance(records: list[tuple[np.ndarray, np.ndarray]], P: np.ndarray) -> tuple[np.ndarray | None, int]:
    """Segment-robust covariance of least-squares coefficients: ``P Omega P G / (G - 1)``, ``G - 1`` dof.

    Each record's regression rows ``X`` (with their residuals ``e``) are cut into contiguous segments, the one
    rule: segments at least :data:`SEGMENT_COLUMNS` times the number of regressors long and at least
    ``1 / MAX_SEGMENTS`` of all rows (so at most :data:`MAX_SEGMENTS` in all), a record holding
    ``rows // length`` of them (covering every row). ``s_g = X_g^T e_g`` is segment ``g``'s score and
    ``Omega = sum_g s_g s_g^T`` plus :data:`NEIGHBOUR_WEIGHT` times the products of neighbouring segments of a
    record (``s_g s_{g+1}^T`` and its transpose: Newey & West's Bartlett window over segments, positive
    semidefinite). ``P`` is the (pseudo-)inverse of ``X^T X`` the coefficients were solved with.

    Unlike ``sigma^2 (X^T X)^-1`` it does not assume white residuals: it is the large-sample form of a
    (moving) block bootstrap over the segments.

    Parameters
    ----------
    records : list of (X, e)
        Each record's regression rows (N_r, p) and residuals (N_r,).
    P : ndarray (p, p)
        The pseudo-inverse of the Gram matrix of all rows.

    Returns
    -------
    (cov, dof)
        ``(None, 0)`` when fewer than :data:`MIN_SEGMENTS` segments fit.

    References
    ----------
    Newey, W. K. & West, K. D. (1987), Econometrica 55(3), 703-708 (the Bartlett window); Cameron, A. C. &
    Miller, D. L. (2015), J. Human Resources 50(2), 317-372 (cluster-robust covariance, the ``G/(G-1)``
    factor).
    """
    p = P.shape[0]
    counts = [len(e) for _, e in records]
    seg = max(SEGMENT_COLUMNS * p, int(np.ceil(sum(counts) / MAX_SEGMENTS)))
    if sum(r // seg for r in counts) < MIN_SEGMENTS:
        return None, 0
    scores, neighbours = [], []
    for (X, e), nr in zip(records, counts):
        k = nr // seg
        edges = np.linspace(0, nr, k + 1).astype(int)       # k segments covering every row
        for i, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
            if i:
                neighbours.append(len(scores))
            scores.append(X[a:b].T @ e[a:b])
    S = np.array(scores)
    G = len(S)
    meat = S.T @ S
    for j in neighbours:          # neighbouring segments of a record: slow residuals (voluntary torque)
        cross = np.outer(S[j - 1], S[j])   # times the angle's derivative leave opposite terms at their border
        meat += NEIGHBOUR_WEIGHT * (cross + cross.T)
    return P @ meat @ P * (G / (G - 1.0)), G - 1


def eigen_pinv(w: np.ndarray, V: np.ndarray, keep) -> np.ndarray:
    """``sum_k v_k v_k^T / w_k`` over the kept eigenpairs ``(w_k, v_k)`` (columns of ``V``): the pseudo-inverse
    of ``V diag(w) V^T`` restricted to the directions ``keep`` (a boolean mask or indices)."""
    return (V[:, keep] / w[keep]) @ V[:, keep].T


def psd_pinv(G: np.ndarray, rcond: float) -> np.ndarray:
    """Pseudo-inverse of a symmetric positive semidefinite ``G`` (e.g. a Gram matrix ``X^T X``): its
    eigen-decomposition, the eigenvalues at most ``rcond`` times the largest left out.

    References
    ----------
    Golub, G. H. & Van Loan, C. F. (2013), Matrix Computations, 4th ed., Sec. 5.5.2 (the pseudo-inverse).
    """
    w, V = np.linalg.eigh(G)
    return eigen_pinv(w, V, w > rcond * w[-1])


def psd_solve(G: np.ndarray, b: np.ndarray, rcond: float) -> tuple[np.ndarray, int]:
    """Minimum-norm ``c`` of ``G c = b`` for a symmetric positive semidefinite ``G`` (normal equations), and
    the number of directions kept: :func:`psd_pinv` of the unit-diagonal scaled matrix
    ``D^-1 G D^-1`` (``D = sqrt(diag G)``), directions below ``rcond`` times the largest left out."""
    scale = np.sqrt(np.maximum(np.diag(G), 1e-300))
    w, V = np.linalg.eigh(G / scale[:, None] / scale[None, :])
    keep = w > rcond * w[-1]
    return (V[:, keep] @ ((V[:, keep].T @ (b / scale)) / w[keep])) / scale, int(keep.sum())
