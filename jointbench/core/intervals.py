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


def segment_covariance(records: list[tuple[np.ndarray, np.ndarray]], P: np.ndarray,
                       columns: int | None = None) -> tuple[np.ndarray | None, int]:
    """Segment-robust (delete-one-segment jackknife) covariance of least-squares coefficients, ``G - 1`` dof.

    Each record's regression rows ``X`` (with their residuals ``e``) are cut into contiguous segments, the one
    rule: segments at least :data:`SEGMENT_COLUMNS` times the number of regressors (``columns``) long and at least
    ``1 / MAX_SEGMENTS`` of all rows (so at most :data:`MAX_SEGMENTS` in all), a record holding
    ``rows // length`` of them (covering every row). Segment ``g``'s influence on the coefficients is the
    change when it is left out, ``d_g = (I - P H_g)^-1 P s_g`` with ``H_g = X_g^T X_g`` and the score
    ``s_g = X_g^T e_g`` (with ``P`` the full inverse of the Gram matrix this is ``(X^T X - H_g)^-1 s_g``
    exactly; with a pseudo-inverse restricted to kept directions, the same within them). Then
    ``cov = (G - 1) / G (sum_g d_g d_g^T`` plus :data:`NEIGHBOUR_WEIGHT` times the products of neighbouring
    segments of a record, ``d_g d_{g+1}^T`` and its transpose: Newey & West's Bartlett window over segments,
    positive semidefinite).

    Unlike ``sigma^2 (X^T X)^-1`` it does not assume white residuals. Unlike the plain sandwich
    ``P (sum s_g s_g^T) P`` (CR1) it does not shrink where a segment's rows weigh much in the fit (a narrow-band
    input, many regressors per segment): the residuals of such a segment are pulled towards its own fit, so
    its scores understate its noise; the jackknife's ``(I - P H_g)^-1`` undoes that (pv_irf on issue 33's
    narrow-band record, 30 seeds: its pointwise band held K = 120 in 24 of 30 under CR1, 26 of 30 with it, at
    the default, 20 ms and 40 ms lags; the two-sided IRFs, whose segments weigh little, barely change).
    Solve in well-scaled coordinates (``P`` near the identity): in badly scaled ones a direction of huge
    variance swamps the others' in rounding.

    Parameters
    ----------
    records : list of (X, e)
        Each record's regression rows (N_r, p) and residuals (N_r,).
    P : ndarray (p, p)
        The pseudo-inverse of the Gram matrix of all rows the coefficients were solved with.
    columns : int, optional
        The number of regressors the segment length is counted in (default ``p``): a two-sided IRF solved in
        the coordinates of its kept directions counts its lags, the memory a segment must outlast.

    Returns
    -------
    (cov, dof)
        ``(None, 0)`` when fewer than :data:`MIN_SEGMENTS` segments fit.

    References
    ----------
    MacKinnon, J. G., Nielsen, M. O. & Webb, M. D. (2023), J. Econometrics 232(2), 272-299 (CR3, the cluster
    jackknife); Bell, R. M. & McCaffrey, D. F. (2002), Survey Methodology 28(2), 169-181; Newey, W. K. &
    West, K. D. (1987), Econometrica 55(3), 703-708 (the Bartlett window).
    """
    p = P.shape[0]
    counts = [len(e) for _, e in records]
    seg = max(SEGMENT_COLUMNS * (columns or p), int(np.ceil(sum(counts) / MAX_SEGMENTS)))
    if sum(r // seg for r in counts) < MIN_SEGMENTS:
        return None, 0
    eye = np.eye(p)
    deviations, neighbours = [], []
    for (X, e), nr in zip(records, counts):
        k = nr // seg
        edges = np.linspace(0, nr, k + 1).astype(int)       # k segments covering every row
        for i, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
            if i:
                neighbours.append(len(deviations))
            Xg = X[a:b]
            deviations.append(_left_out_change(eye - P @ (Xg.T @ Xg), P @ (Xg.T @ e[a:b])))
    D = np.array(deviations)
    G = len(D)
    meat = D.T @ D
    for j in neighbours:          # neighbouring segments of a record: slow residuals (voluntary torque)
        cross = np.outer(D[j - 1], D[j])   # times the angle's derivative leave opposite terms at their border
        meat += NEIGHBOUR_WEIGHT * (cross + cross.T)
    return meat * ((G - 1.0) / G), G - 1


def _left_out_change(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``A^-1 b`` for ``A = I - P H_g`` (segment ``g`` left out); least squares if a segment alone determines a
    direction (``A`` singular: the coefficients are then not estimable without it)."""
    try:
        return np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(A, b, rcond=None)[0]


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
