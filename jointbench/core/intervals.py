"""Intervals: the confidence level, its quantiles, the segment-robust covariance and the PSD pseudo-inverse.

One home for what every interval-returning estimator shares (``tests/test_one_home.py`` fails on a second
definition): :data:`LEVEL` (the level of every interval JointBench reports), :func:`t_quantile` and
:func:`z_quantile` (two-sided), :func:`segment_covariance` (one rule for the segments) with
:func:`contrast_dof` (the degrees of freedom of one of its variances) and
:func:`psd_pinv` / :func:`psd_solve` (the pseudo-inverse of a symmetric positive semidefinite matrix such as
a Gram matrix ``X^T X``, from its eigen-decomposition).
"""
from __future__ import annotations

import numpy as np

__all__ = ["LEVEL", "MAX_SEGMENTS", "SEGMENT_COLUMNS", "MIN_SEGMENTS", "NEIGHBOUR_WEIGHT", "PINV_RCOND", "t_quantile",
           "z_quantile", "segment_covariance", "segment_shortfall", "segment_press", "contrast_dof", "eigen_pinv",
           "psd_pinv", "psd_solve"]

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


def t_quantile(dof, level: float = LEVEL):
    """Two-sided ``level`` quantile of Student's t with ``dof`` degrees of freedom (``t_{(1+level)/2}``): a float
    for a scalar ``dof``, an array for an array."""
    from scipy import stats

    q = stats.t.ppf(0.5 + level / 2, dof)
    return float(q) if np.ndim(q) == 0 else np.asarray(q, float)


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
    segments = _segments([len(e) for _, e in records], columns or p)
    if segments is None:
        return None, 0
    eye = np.eye(p)
    D = np.array([_left_out_change(eye - P @ (Xg.T @ Xg), P @ (Xg.T @ eg))
                  for (X, e), edges in zip(records, segments) for Xg, eg in _pieces(edges, X, e)])
    G = len(D)
    # neighbouring segments of a record (slow residuals, voluntary torque, times the angle's derivative leave
    # opposite terms at their border): the Bartlett window's weights
    meat = D.T @ _bartlett(segments) @ D
    return meat * ((G - 1.0) / G), G - 1


def contrast_dof(designs: list[np.ndarray], P: np.ndarray, contrasts: np.ndarray,
                 columns: int | None = None) -> np.ndarray:
    """Degrees of freedom of :func:`segment_covariance`'s variance of each contrast ``a^T c`` (Bell and
    McCaffrey's, by Satterthwaite's approximation), for the t quantile of its interval.

    The variance is a quadratic form in the noise: with the residuals ``e = M eps`` (``M = I - X P X^T``),
    ``a^T d_g = c_g^T e`` with ``c_g = X_g P (I - H_g P)^-1 a`` on segment ``g``'s rows, so the variance is
    ``eps^T M C W C^T M eps`` (``C`` the ``c_g`` as columns, ``W`` the segments' weights: 1, and
    :data:`NEIGHBOUR_WEIGHT` for neighbours). For white noise it is distributed as ``sum_i lambda_i chi^2_1``
    with ``lambda`` the eigenvalues of ``S W``, ``S = C^T M C`` (``G x G``), whose Satterthwaite degrees of
    freedom are ``tr(S W)^2 / tr(S W S W)``. They equal ``G - 1``-like counts when every segment informs the
    contrast alike, and fall to a few when a few segments carry it: a parameter-varying fit's value at one
    end of the visited range, learnt from the few segments that visit it, whose variance the ``G - 1`` of
    the whole covariance overstates the certainty of (pv_irf on issue 33's narrow-band record, 30 seeds at
    20 ms lags: its pointwise band missed K = 120 in 5 with ``G - 1``, 3 with these; medians about 12 of 35).

    Parameters
    ----------
    designs : list of ndarray
        Each record's regression rows ``X`` (N_r, p), as given to :func:`segment_covariance` (same segments).
    P : ndarray (p, p)
        The pseudo-inverse of the Gram matrix of all rows.
    contrasts : ndarray (k, p)
        The contrasts ``a`` (rows).
    columns : int, optional
        As :func:`segment_covariance`'s.

    Returns
    -------
    ndarray (k,)
        At most ``G - 1`` (the covariance's own) and at least 1; ``G - 1`` for a contrast the data do not
        inform (zero variance). An empty array when fewer than :data:`MIN_SEGMENTS` segments fit.

    References
    ----------
    Bell, R. M. & McCaffrey, D. F. (2002), Survey Methodology 28(2), 169-181 (the degrees of freedom, Sec. 3);
    Imbens, G. W. & Kolesar, M. (2016), Rev. Econ. Stat. 98(4), 701-712 (their use with few effective clusters);
    Satterthwaite, F. E. (1946), Biometrics Bulletin 2(6), 110-114.
    """
    p = P.shape[0]
    A = np.atleast_2d(np.asarray(contrasts, float))
    segments = _segments([len(X) for X in designs], columns or p)
    if segments is None:
        return np.empty(0)
    eye = np.eye(p)
    Z, diag = [], []      # per segment: X_g^T c_g (p, k) and ||c_g||^2 (k,)
    for X, edges in zip(designs, segments):
        for (Xg,) in _pieces(edges, X):
            Hg = Xg.T @ Xg
            V = P @ _left_out_change((eye - P @ Hg).T, A.T)          # c_g = X_g V, one column per contrast
            HV = Hg @ V
            Z.append(HV)
            diag.append(np.sum(V * HV, axis=0))
    Zk = np.ascontiguousarray(np.array(Z).transpose(2, 0, 1))   # (k, G, p)
    G = Zk.shape[1]
    S = -(Zk @ P) @ Zk.transpose(0, 2, 1)                        # C^T M C = C^T C - (X^T C)^T P (X^T C)
    S[:, np.arange(G), np.arange(G)] += np.array(diag).T
    SW = S @ _bartlett(segments)
    first = np.trace(SW, axis1=1, axis2=2)
    second = np.sum(SW * SW.transpose(0, 2, 1), axis=(1, 2))
    dof = np.divide(first * first, second, out=np.full(len(A), G - 1.0), where=second > 0)
    return np.clip(dof, 1.0, G - 1.0)


def segment_press(records: list[tuple[np.ndarray, np.ndarray]], P: np.ndarray,
                  columns: int | None = None) -> float:
    """The least-squares fit's leave-one-segment-out prediction error (blocked cross-validation, with the segments
    of :func:`segment_covariance`): ``sum_g ||e_g + X_g d_g||^2``, each segment predicted by the coefficients
    fitted without it (``c - d_g``, the same left-out change ``d_g``). Unlike the residual sum of squares it does
    not fall when a regressor fits the noise, coloured or not (a criterion such as the minimum description length
    counts a regressor as one white-noise degree of freedom; the contiguous segments keep the noise's correlation
    inside each). NaN when fewer than :data:`MIN_SEGMENTS` segments fit.

    References
    ----------
    Allen, D. M. (1974), Technometrics 16(1), 125-127 (PRESS); Burman, P., Chow, E. & Nolan, D. (1994),
    Biometrika 81(2), 351-358 (cross-validation of dependent data by blocks).
    """
    p = P.shape[0]
    segments = _segments([len(e) for _, e in records], columns or p)
    if segments is None:
        return float("nan")
    eye = np.eye(p)
    total = 0.0
    for (X, e), edges in zip(records, segments):
        for Xg, eg in _pieces(edges, X, e):
            out = eg + Xg @ _left_out_change(eye - P @ (Xg.T @ Xg), P @ (Xg.T @ eg))
            total += float(out @ out)
    return total


def segment_shortfall(counts: list[int], columns: int) -> str:
    """Why :func:`segment_covariance` gives no covariance for records of ``counts`` rows and ``columns``
    regressors (the one segment rule), in words a user can act on."""
    seg = _segment_length(counts, columns)
    have = sum(r // seg for r in counts)
    return (f"the fitted rows hold {have} segments of {seg} rows ({SEGMENT_COLUMNS} per unknown of {columns}); "
            f"the segment-robust covariance needs {MIN_SEGMENTS}: shorten the lags or use a longer record")


def _segments(counts: list[int], columns: int) -> list[np.ndarray] | None:
    """The one rule (:func:`segment_covariance`): each record's segment edges (``rows // length + 1`` indices,
    the segments covering every row), or None when fewer than :data:`MIN_SEGMENTS` fit."""
    seg = _segment_length(counts, columns)
    if sum(r // seg for r in counts) < MIN_SEGMENTS:
        return None
    return [np.linspace(0, r, r // seg + 1).astype(int) for r in counts]


def _segment_length(counts: list[int], columns: int) -> int:
    """Rows per segment: :data:`SEGMENT_COLUMNS` times the regressors, and at least ``1 / MAX_SEGMENTS`` of all
    rows."""
    return max(SEGMENT_COLUMNS * columns, int(np.ceil(sum(counts) / MAX_SEGMENTS)))


def _pieces(edges: np.ndarray, *arrays: np.ndarray):
    """The segments (``edges``) of each of ``arrays``' rows, as tuples."""
    for a, b in zip(edges[:-1], edges[1:]):
        yield tuple(x[a:b] for x in arrays)


def _bartlett(segments: list[np.ndarray]) -> np.ndarray:
    """The segments' weights (G x G): 1 on the diagonal, :data:`NEIGHBOUR_WEIGHT` between neighbouring segments
    of a record (Newey & West's Bartlett window over segments), 0 elsewhere."""
    sizes = [len(e) - 1 for e in segments]
    W = np.eye(sum(sizes))
    start = 0
    for k in sizes:
        i = np.arange(start, start + k - 1)
        W[i, i + 1] = W[i + 1, i] = NEIGHBOUR_WEIGHT
        start += k
    return W


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
