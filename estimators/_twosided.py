"""Shared pieces of the two-sided (acausal) IRF estimators: lag settings, checks, LS and Toeplitz solvers.

Private module (out of the estimator registry), used by the IRF estimators and :mod:`estimators.ibk_irf`.

References
----------
Westwick, D. T. & Perreault, E. J. (2012). Estimates of acausal joint impedance models.
IEEE Trans. Biomed. Eng. 59(10), doi:10.1109/TBME.2012.2213339, eqs. 14 and 15.

Hunter, I. W. & Kearney, R. E. (1983). Two-sided linear filter identification.
Med. Biol. Eng. Comput. 21, 203-209.

Westwick, D. T. & Kearney, R. E. (2003). Identification of Nonlinear Physiological Systems. IEEE Press /
Wiley, Sec. 5.2.3 (pseudo-inverse IRF estimate, terms ordered by their contribution to the output, the
number kept chosen by the minimum description length, as in the REKLAB toolbox).

Liang, K.-Y. & Zeger, S. L. (1986), Biometrika 73(1), 13-22, and Cameron & Miller (2015), J. Human
Resources 50(2): cluster-robust ("sandwich") covariance, here with contiguous segments as clusters;
Newey, W. K. & West, K. D. (1987), Econometrica 55(3), 703-708: the Bartlett window over neighbours.
"""
from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np
import scipy.fft
import scipy.linalg
from numpy.lib.stride_tricks import sliding_window_view

from jointbench.core.errors import InputError
from jointbench.core.estimate import IRFEstimate, Intervals
from jointbench.core.intervals import LEVEL, segment_covariance, segment_shortfall, t_quantile, z_quantile
from jointbench.core.schema import param
from jointbench.core.types import Trial

Edges = Literal["zero", "valid"]
#: the regression rows of a fit: an :data:`Edges` setting, or "full" (internal, the correlation method's rows:
#: see :func:`regression_rows`)
Rows = Literal["zero", "valid", "full"]
PseudoInverse = Literal["mdl", "off"]


#: directions whose singular value is below this fraction of the largest are never kept by the MDL
#: pseudo-inverse: sqrt(eps), half the digits. The MDL ranks directions by their share of the torque only,
#: so a direction 10^-14 below the strongest (rounding error of the QR triangle: a band-limited input's
#: unexcited lags) could be kept for its chance share, its coordinate c / s then 10^13 times the noise
#: (issue 20: ibk_irf and irf2_ls intervals of +-0 or +-1e13 on a 12 Hz input at 250 Hz)
RCOND_MDL = float(np.sqrt(np.finfo(float).eps))

# Rows of the regression matrix handled per QR block (bounds memory at about 16 MB per block).
_BLOCK_VALUES = 2 ** 21


@dataclasses.dataclass(frozen=True)
class Lags:
    """The lag range of a two-sided IRF (the settings of an estimator that takes its own preprocessing, as
    :mod:`estimators.pv_irf`)."""

    lag_before: float = param(0.1, unit="s", ge=0,
                              doc="anticipatory memory: negative lags down to -M1, M1 = round(lag_before*fs)")
    lag_after: float = param(0.1, unit="s", ge=0,
                             doc="causal memory: positive lags up to M2 = round(lag_after*fs)")


@dataclasses.dataclass(frozen=True)
class LagSettings(Lags):
    """Lag range and preprocessing shared by the two-sided IRF estimators (:func:`fit_irf`)."""

    remove_mean: bool = param(True, doc="subtract each record's mean from angle and torque before fitting")
    pseudo_inverse: PseudoInverse = param("mdl", doc="'mdl': keep the singular vectors that explain the torque, "
                                                     "their number chosen by minimum description length "
                                                     "(REKLAB); 'off': plain least squares")


def lag_samples(settings: Lags, fs: float) -> tuple[int, int]:
    """``(M1, M2)``: the lag range in samples at sampling rate ``fs``.

    Raises :class:`InputError` when a nonzero lag setting is less than half a sample (it would round to
    no lag at all: a silent zero-lag IRF), e.g. a time column in milliseconds read as seconds.
    """
    m1, m2 = int(round(settings.lag_before * fs)), int(round(settings.lag_after * fs))
    for key, v, m in (("lag_before", settings.lag_before, m1), ("lag_after", settings.lag_after, m2)):
        if v > 0 and m == 0:
            raise InputError(f"{key} = {v:g} s is less than half a sample at {fs:g} Hz (sample {1 / fs:g} s), so "
                             f"the IRF would have no lag there; the sampling rate is too low for these lags "
                             f"(too much decimation? a time column in milliseconds read as seconds?): "
                             f"use a rate above {1 / (2 * v):g} Hz, or set {key} = 0 explicitly")
    return m1, m2


def check_lengths(name: str, trials: list[Trial], m1: int, m2: int, settings: Lags) -> None:
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


def regression_rows(u: np.ndarray, y: np.ndarray, m1: int, m2: int, rows: Rows) -> tuple[np.ndarray, np.ndarray]:
    """The regression rows ``U`` and the torque ``y`` they fit, for a row set ``rows``.

    ``"zero"`` and ``"valid"`` are those of :func:`regressor`. ``"full"`` is the complete zero-padded
    convolution: rows ``r = -M1 ... N-1+M2`` (``N + M1 + M2`` rows), ``y = 0`` outside the record. Its
    ``U^T U`` is the Toeplitz matrix of the biased autocorrelation and its ``U^T y`` the biased
    cross-correlation, so the correlation method (eq. 15) is exactly least squares on these rows: the
    ``M1 + M2`` rows past the record's ends are fitted to a torque of zero.
    """
    if rows != "full":
        U, sl = regressor(u, m1, m2, rows)
        return U, y[sl]
    n_lags = m1 + m2 + 1
    padded = np.concatenate([np.zeros(n_lags - 1), u, np.zeros(n_lags - 1)])
    return sliding_window_view(padded, n_lags)[:, ::-1], np.concatenate([np.zeros(m1), y, np.zeros(m2)])


def ls_triangle(name: str, pairs: list[tuple[np.ndarray, np.ndarray]], m1: int, m2: int,
                edges: Edges) -> tuple[np.ndarray, int]:
    """The ``(L+1) x (L+1)`` triangle ``[[R, z], [0, rho]]`` of ``[U | y]`` (records' rows stacked) by blockwise
    Householder QR, and the row count: ``cond(U)`` enters once, not squared as in the normal equations."""
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
    if len(tri) < n_lags + 1:
        tri = np.vstack([tri, np.zeros((n_lags + 1 - len(tri), n_lags + 1))])
    return tri, n_rows


def corr_irf(name: str, pairs: list[tuple[np.ndarray, np.ndarray]], m1: int, m2: int) -> np.ndarray:
    """Correlation (Hunter & Kearney) two-sided IRF, eq. 15: ``h = Phi_uu^{-1} phi_uy``.

    Biased (un-normalised) linear correlations by zero-padded FFT, summed over records, then the
    symmetric Toeplitz system is solved by Levinson recursion (:func:`scipy.linalg.solve_toeplitz`).
    """
    n_lags = m1 + m2 + 1
    phi_uu, phi_uy = corr_normal(pairs, m1, m2)
    try:
        h = scipy.linalg.solve_toeplitz(phi_uu, phi_uy, check_finite=False)
    except np.linalg.LinAlgError:
        h = np.full(n_lags, np.nan)
    if not np.all(np.isfinite(h)):
        raise InputError(f"{name}: the input autocorrelation matrix ({n_lags} lags) is singular; the angle "
                         f"does not excite all lags: use a broader-band perturbation or fewer lags")
    return h


def corr_normal(pairs: list[tuple[np.ndarray, np.ndarray]], m1: int, m2: int) -> tuple[np.ndarray, np.ndarray]:
    """``phi_uu`` (first column of the Toeplitz matrix) and ``phi_uy`` of eq. 15, summed over records."""
    n_lags = m1 + m2 + 1
    phi_uu = np.zeros(n_lags)
    phi_uy = np.zeros(n_lags)
    for u, y in pairs:
        nfft = scipy.fft.next_fast_len(len(u) + m1 + m2, real=True)
        fu = scipy.fft.rfft(u, nfft)
        phi_uu += scipy.fft.irfft(np.abs(fu) ** 2, nfft)[:n_lags]
        r_uy = scipy.fft.irfft(np.conj(fu) * scipy.fft.rfft(y, nfft), nfft)  # sum_s u(s) y(s + k)
        phi_uy += np.concatenate([r_uy[nfft - m1:], r_uy[:m2 + 1]])         # lags -M1 ... M2
    return phi_uu, phi_uy


@dataclasses.dataclass(frozen=True)
class IRFFit:
    """A two-sided IRF with what is known of its accuracy.

    Attributes
    ----------
    h : ndarray
        The IRF on lags ``-M1 ... M2``.
    cov : ndarray or None
        Its segment-robust covariance (:func:`irf_covariance`), None when the records are too short
        for :data:`jointbench.core.intervals.MIN_SEGMENTS` segments.
    dof : int
        Degrees of freedom of the covariance (segments - 1), for t quantiles.
    kept, n_lags : int
        Singular vectors kept by the pseudo-inverse, and lags.
    info : dict
        Numbers for the summary.
    directions : ndarray or None
        The kept singular vectors (columns, ``n_lags x kept``): the lag directions the IRF is estimated in
        (the others are set to zero by the pseudo-inverse); :mod:`estimators.ibk_irf` fits in them.
    end_effect : ndarray or None
        The correlation method's (eq. 15) IRF minus the least-squares IRF of the valid rows of the same
        records with the same pseudo-inverse (:func:`correlation_end_effect`); None for least squares.
    singular, coord_cov : ndarray or None
        The kept singular values ``s_k``; the covariance of the torque coordinates ``diag(s_k) V_k^T h``, from
        which any linear function of ``h`` is worked out (:func:`linear_covariance`), never from ``cov``: a
        barely excited direction's variance swamps the others' digits there (issue 33: zero-width intervals).
    """

    h: np.ndarray
    cov: np.ndarray | None
    dof: int
    kept: int
    n_lags: int
    info: dict
    directions: np.ndarray | None = None
    end_effect: np.ndarray | None = None
    singular: np.ndarray | None = None
    coord_cov: np.ndarray | None = None


def linear_covariance(fit: IRFFit, G: np.ndarray) -> np.ndarray:
    """Covariance of ``G h`` (``G``: rows of linear functions of the IRF, or one row) from the kept directions'
    coordinate covariance (:attr:`IRFFit.coord_cov`): ``M C M^T`` with ``M = G V_k diag(1/s_k)``."""
    M = np.atleast_2d(G) @ (fit.directions / fit.singular)
    return M @ fit.coord_cov @ M.T


def mdl_pseudo_inverse(s: np.ndarray, V: np.ndarray, c: np.ndarray, rss0: float,
                       n_rows: int) -> tuple[np.ndarray, np.ndarray]:
    """Pseudo-inverse solution with the number of terms chosen by minimum description length.

    The least-squares problem is written in the singular basis of the regression matrix,
    ``U = W diag(s) V^T``: term ``i`` has output coordinate ``c_i = w_i^T y`` and removes ``c_i^2``
    from the residual. Terms are ranked by ``c_i^2`` (their contribution to the output, not their
    singular value), and the first ``M`` are kept, ``M`` minimising
    ``MDL(M) = RSS(M) (1 + M ln(N) / N)`` with ``RSS(M) = rss0 + sum of the dropped c_i^2`` and ``N``
    regression rows; numerically null directions (``s_i <= sqrt(eps) s_max``, :data:`RCOND_MDL`) are never
    kept.

    Returns
    -------
    h : ndarray
        ``sum_{kept} v_i c_i / s_i``.
    kept : ndarray of int
        Indices of the kept terms.

    References
    ----------
    Westwick & Kearney (2003), Sec. 5.2.3.4 (pseudo-inverse, MDL); Rissanen (1978), Automatica 14.
    """
    L = len(s)
    usable = s > max(L * np.finfo(float).eps, RCOND_MDL) * max(s.max(), np.finfo(float).tiny)
    contrib = np.where(usable, c * c, -1.0)
    order = np.argsort(-contrib, kind="stable")[:int(usable.sum())]
    total = float(np.sum(c[usable] ** 2)) + rss0
    rss = total - np.concatenate([[0.0], np.cumsum(c[order] ** 2)])
    rss = np.maximum(rss, 0.0)
    M = np.arange(len(rss))
    mdl = rss * (1.0 + M * np.log(n_rows) / n_rows)
    best = int(np.argmin(mdl[1:]) + 1) if len(mdl) > 1 else 0
    kept = np.sort(order[:best])
    return V[:, kept] @ (c[kept] / s[kept]), kept


def irf_covariance(pairs: list[tuple[np.ndarray, np.ndarray]], m1: int, m2: int, rows: Rows,
                   h: np.ndarray, to_coordinates: np.ndarray) -> tuple[np.ndarray | None, int]:
    """Segment-robust covariance (:func:`jointbench.core.intervals.segment_covariance`) of the coordinates
    ``z = diag(s_k) V_k^T h`` of a least-squares IRF ``h`` in its kept directions (``V_k``, singular values
    ``s_k`` of the regression), from each record's regression rows (:func:`regression_rows`: those of the fit,
    ``rows``) and residuals ``e = y - U h``. ``to_coordinates = V_k diag(1/s_k)`` maps the rows ``U`` to those of
    ``z``, ``U V_k diag(1/s_k)``, whose Gram matrix is the identity; segments are counted in lags (the IRF's memory).

    Unlike ``sigma^2 (U^T U)^-1`` it does not assume white residuals (the torque noise, voluntary torque and
    the lags the IRF leaves out are coloured). The neighbours' products matter: a slow residual (voluntary
    torque) times the angle's derivative sums to border terms of opposite sign in adjacent segments, which
    the segments alone count twice (B's intervals were 1.8 times the spread of the estimates on simulated
    ankles, 1.35 with the neighbours). ``(None, 0)`` when fewer than
    :data:`jointbench.core.intervals.MIN_SEGMENTS` segments fit.
    """
    fitted = [regression_rows(u, y, m1, m2, rows) for u, y in pairs]
    return segment_covariance([(U @ to_coordinates, yy - U @ h) for U, yy in fitted],
                              np.eye(to_coordinates.shape[1]), columns=len(h))


def fit_irf(name: str, trials: list[Trial], settings: LagSettings, method: Literal["ls", "corr"],
            edges: Edges, covariance: bool = True) -> IRFFit:
    """Check the records and fit the two-sided IRF with ``method`` (eq. 14 or 15), with its covariance
    (unless ``covariance`` is False) and, for eq. 15, its end effect (:func:`correlation_end_effect`)."""
    fs = trials[0].fs
    m1, m2 = lag_samples(settings, fs)
    check_lengths(name, trials, m1, m2, settings)
    pairs = input_output(name, trials, settings.remove_mean)
    n_lags = m1 + m2 + 1
    mode = getattr(settings, "pseudo_inverse", "off")
    rows: Rows = edges
    if method == "ls":
        tri, n_rows = ls_triangle(name, pairs, m1, m2, edges)
        R, z, rho = tri[:n_lags, :n_lags], tri[:n_lags, n_lags], tri[n_lags, n_lags]
        W, s, Vt = scipy.linalg.svd(R, check_finite=False)
        V, c, rss0 = Vt.T, W.T @ z, float(rho * rho)
    else:
        rows = "full"             # eq. 15 is least squares on the full convolution's rows (regression_rows)
        phi_uu, phi_uy = corr_normal(pairs, m1, m2)
        lam, V = scipy.linalg.eigh(scipy.linalg.toeplitz(phi_uu), check_finite=False)
        lam, V = lam[::-1], V[:, ::-1]
        s = np.sqrt(np.maximum(lam, 0.0))
        c = np.where(s > 0, (V.T @ phi_uy) / np.where(s > 0, s, 1.0), 0.0)
        n_rows = sum(len(y) for _, y in pairs)
        rss0 = max(0.0, sum(float(y @ y) for _, y in pairs) - float(c @ c))
    if mode == "mdl":
        h, kept = mdl_pseudo_inverse(s, V, c, rss0, n_rows)
    else:
        null = int(np.sum(s <= RCOND_MDL * s.max()))
        if null:
            raise InputError(unexcited_lags(name, trials, settings, m1, m2, null))
        if method == "ls":
            h = scipy.linalg.lstsq(R, z, check_finite=False)[0]
        else:
            h = corr_irf(name, pairs, m1, m2)
        kept = np.flatnonzero(s > n_lags * np.finfo(float).eps * s.max())
    if not np.all(np.isfinite(h)):
        raise InputError(f"{name}: the IRF is not finite: the angle does not excite all {n_lags} lags; use "
                         f"pseudo_inverse = mdl, fewer lags or a broader-band perturbation")
    V_k, s_k = V[:, kept], s[kept]
    # in the kept directions' coordinates diag(s_k) V_k^T h, whose Gram matrix is the identity (U^T U =
    # V diag(s^2) V^T for both methods): in h itself a direction excited 1e-8 of the strongest swamps the others'
    # variances in rounding
    coord_cov, dof = irf_covariance(pairs, m1, m2, rows, h, V_k / s_k) if covariance else (None, 0)
    cov = None if coord_cov is None else (V_k / s_k) @ coord_cov @ (V_k / s_k).T
    end_effect = correlation_end_effect(name, trials, settings, h) if method == "corr" and cov is not None else None
    info = {}
    if covariance and coord_cov is None:
        counts = [len(regression_rows(u, y, m1, m2, rows)[1]) for u, y in pairs]
        info["intervals"] = "none: " + segment_shortfall(counts, n_lags)
    if mode == "mdl":
        info["pseudo_inverse"] = f"{len(kept)} of {n_lags} singular vectors kept (MDL)"
        if len(kept) < n_lags / 2:
            info["advice"] = (f"the angle excites only {len(kept)} of the {n_lags} lag directions: fewer lags or "
                              f"decimation (--decimate) give the same information in a better-conditioned fit")
    return IRFFit(h=h, cov=cov, dof=dof, kept=len(kept), n_lags=n_lags, info=info, directions=V_k,
                  end_effect=end_effect, singular=s_k, coord_cov=coord_cov)


def correlation_end_effect(name: str, trials: list[Trial], settings: LagSettings, h: np.ndarray) -> np.ndarray | None:
    """The end effect of the correlation method (eq. 15): its IRF ``h`` minus the least-squares IRF (eq. 14,
    same pseudo-inverse) of the rows whose lags lie inside the records ('valid', no end effect).

    The biased correlations are least squares on the full convolution's rows (:func:`regression_rows`): the
    zero padding puts a step into the angle at each end of a record, and the torque the IRF predicts for it
    (mostly inertial) is fitted to zero past the ends. A band-limited input excites little besides those
    steps in the lag directions above its band, so there the coordinates are pulled towards zero, and the
    pseudo-inverse then drops them more often: on a multisine to 12 Hz (10 s at 250 Hz, +-40 ms) the fifth
    direction, with 2-5 N m/rad of the stiffness, was dropped in 25 of 100 records (irf2_ls: 6), and the
    stiffness was 1.5 N m/rad high on average, half an interval's width; the noise-only intervals missed
    the truth 22-23 times in 100. None when the valid rows are too few for the least-squares fit.
    """
    try:
        ref = fit_irf(name, trials, settings, "ls", "valid", covariance=False)
    except InputError:
        return None
    return h - ref.h


def unexcited_lags(name: str, trials: list[Trial], settings: LagSettings, m1: int, m2: int, null: int) -> str:
    """The one-line refusal of plain least squares (``pseudo_inverse = 'off'``) when ``null`` of the lag
    directions are numerically unexcited (singular value at most sqrt(eps) of the largest,
    :data:`RCOND_MDL`): their coordinates would be rounding error times 10^8 or more (issue 20: intervals of
    +-1e13 on a 12 Hz input), naming the input's band (:func:`estimators._band.band_of_trials`)."""
    from jointbench.estimators._band import band_of_trials

    band = band_of_trials(name, trials)
    where = f"the input's band {band.lo:g} ... {band.hi:g} Hz" if band else "the angle"
    return (f"{name}: {where} leaves {null} of the {m1 + m2 + 1} lag directions of -{m1} ... {m2} "
            f"(lag_before {settings.lag_before:g} s, lag_after {settings.lag_after:g} s) unexcited, so plain least "
            f"squares (pseudo_inverse = off) is rounding error there; set pseudo_inverse = mdl, shorten the lags, "
            f"decimate or broaden the perturbation")


def bias_aware_quantile(bias: np.ndarray, se: np.ndarray, dof: int, level: float = LEVEL) -> np.ndarray:
    """Half widths over ``se`` of ``level`` intervals that hold the truth under a bias up to ``|bias|``.

    The quantile ``c`` with ``P(|Z + b| <= c) = level`` for ``Z`` standard normal and ``b = |bias| / se``
    (the critical value ``cv_alpha(b)``), scaled by Student's t quantile over the normal one for the
    covariance's ``dof``: Student's t quantile when the bias is 0, about ``|bias| / se + 1.645`` when it is
    large.

    References
    ----------
    Armstrong, T. B. & Kolesar, M. (2020). Simple and honest confidence intervals in nonparametric
    regression. Quantitative Economics 11(1), 1-39 (the critical value ``cv_alpha``).
    """
    from scipy import optimize, stats

    z = z_quantile(level)
    b = np.abs(np.asarray(bias, float)) / np.where(np.asarray(se, float) > 0, se, np.inf)
    out = np.full(b.shape, z)
    for i in np.flatnonzero(b > 0):
        bi = float(b.flat[i])

        def miss(c, bi=bi):
            return stats.norm.cdf(c - bi) - stats.norm.cdf(-c - bi) - level
        out.flat[i] = bi + stats.norm.ppf(level) if bi > 10 else optimize.brentq(miss, z, z + bi + 1.0)
    return out * (t_quantile(dof, level) / z)


def irf_intervals(fit: IRFFit, level: float = LEVEL) -> Intervals | None:
    """Pointwise intervals of ``h`` and of the stiffness ``sum(h)`` from :attr:`IRFFit.cov`, for the
    correlation method widened by its end effect (:attr:`IRFFit.end_effect`, :func:`bias_aware_quantile`)."""
    if fit.cov is None:
        return None
    se_h = np.sqrt(np.maximum(np.diag(fit.cov), 0.0))
    se_k = float(np.sqrt(max(float(linear_covariance(fit, np.ones(fit.n_lags))[0, 0]), 0.0)))
    k = float(np.sum(fit.h))
    method = f"segment-robust covariance ({fit.dof + 1} segments; t quantile)"
    if fit.end_effect is None:
        q_h = np.full(len(se_h), t_quantile(fit.dof, level))
        q_k = float(q_h[0]) if len(q_h) else t_quantile(fit.dof, level)
    else:
        q_h = bias_aware_quantile(fit.end_effect, se_h, fit.dof, level)
        q_k = float(bias_aware_quantile(np.array([np.sum(fit.end_effect)]), np.array([se_k]), fit.dof, level)[0])
        method += (f"; widened by the end effect of the zero-padded correlations (stiffness "
                   f"{float(np.sum(fit.end_effect)):+.3g} against least squares on the valid rows; bias-aware "
                   f"quantile, Armstrong & Kolesar 2020)")
    return Intervals(level=level, method=method, bounds={"stiffness": (k - q_k * se_k, k + q_k * se_k)},
                     response={"h": (fit.h - q_h * se_h, fit.h + q_h * se_h)})


def estimate_irf(name: str, trials: list[Trial], settings: LagSettings, method: Literal["ls", "corr"],
                 edges: Edges, estimator: str) -> IRFEstimate:
    """Check the records, fit the two-sided IRF with ``method`` and wrap it in an :class:`IRFEstimate`
    (with its intervals and the pseudo-inverse's order in :attr:`~IRFEstimate.info`)."""
    fs = trials[0].fs
    m1, m2 = lag_samples(settings, fs)
    fit = fit_irf(name, trials, settings, method, edges)
    est = IRFEstimate(lags=np.arange(-m1, m2 + 1), h=fit.h, fs=fs, time=trials[0].time, estimator=estimator)
    from jointbench.estimators._band import band_of_trials

    band = band_of_trials(name, trials)
    est.fit_info = {**fit.info, "band": "the input's band " + (band.text() if band else "unknown") + (
        f"; the IRF estimated in {fit.kept} of its {fit.n_lags} lag directions (MDL pseudo-inverse)"
        if fit.kept < fit.n_lags else f"; all {fit.n_lags} lag directions estimated")}
    est.band_hz = None if band is None else (band.lo, band.hi)     # the CSV's band_lo_hz, band_hi_hz
    return est.with_intervals(irf_intervals(fit))
