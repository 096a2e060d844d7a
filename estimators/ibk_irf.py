"""Inertia, damping and stiffness fitted to a two-sided IRF through discrete differentiators (Sec. V-B)."""
from __future__ import annotations

import dataclasses
from typing import Literal, NamedTuple

import numpy as np
import scipy.linalg

from jointbench.estimators import Estimator, register
from jointbench.estimators._band import band_of_trials
from jointbench.estimators._twosided import (Edges, LagSettings, fit_irf, input_output, irf_intervals, lag_samples,
                                             linear_covariance, regressor)
from jointbench.core import differentiators as dd
from jointbench.core.errors import InputError
from jointbench.core.estimate import IRFEstimate, Intervals, ParametricEstimate
from jointbench.core.intervals import LEVEL, t_quantile
from jointbench.core.schema import param
from jointbench.core.signal import bandlimit_fb
from jointbench.core.types import Trial


#: smallest ratio of the least to the largest singular value of the (column-scaled) differentiator regressors
#: in which I, B and K are told apart; below it the fit is refused (the data leave them undetermined)
CONDITION = 1e-6


def kept_derivative_irfs(pairs: list[tuple[np.ndarray, np.ndarray]], m1: int, m2: int, edges: Edges,
                         D: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pseudo-inverse IRFs (lags ``-m1 ... m2``, in the kept directions ``D``) of ``u''``, ``u'``, ``u``,
    and the weights of the IRF's residuals.

    Columns ``c_j = D (D^T U^T U D)^-1 D^T U^T y_j`` with ``y_j`` the ``j``-th derivative of each record's
    angle ``u`` (its DFT times ``(j w)^j``: the periodic differentiators of eqs. 12, 13 over the record) and
    ``U`` the regressors of the IRF fit. The IRF the pseudo-inverse estimates from the torque
    ``I u'' + B u' + K u + e`` is then ``I c_2 + B c_1 + K c_0`` plus noise, exactly: whatever the input
    leaves unexcited (a band-limited input's lag directions, the differentiators' tails beyond the lags),
    the model's columns lack as the IRF does.

    The weights ``W = C^T D^T`` (``C C^T = D^T U^T U D``, Cholesky) make ``|W (h - A x)|^2`` the torque's
    squared residual ``|U (h - A x)|^2``: a kept direction the input barely excites (the MDL keeps one now
    and then for its chance share of the torque) carries a large, noisy IRF component that the torque does
    not see, and must not carry the fit (unweighted, one seed in 20 gave K = 2844 +- 3e13 on a 12 Hz input).
    Under white torque noise this is the generalised least-squares fit of the IRF.
    """
    n_lags = m1 + m2 + 1
    G = np.zeros((n_lags, n_lags))
    b = np.zeros((n_lags, 3))
    block = max(n_lags, 2 ** 20 // n_lags)
    for u, _ in pairs:
        n = len(u)
        w = 2j * np.pi * np.fft.rfftfreq(n)          # per sample; fs enters the columns' scale only
        U_f = np.fft.rfft(u)
        d1 = w.copy()
        if n % 2 == 0:
            d1[-1] = 0.0                             # an odd real sequence cannot carry the Nyquist term
        Y = np.column_stack([np.fft.irfft(U_f * w ** 2, n), np.fft.irfft(U_f * d1, n), u])
        X, rows = regressor(u, m1, m2, edges)
        Y = Y[rows]
        for a in range(0, len(Y), block):
            Xa = np.ascontiguousarray(X[a:a + block])
            G += Xa.T @ Xa
            b += Xa.T @ Y[a:a + block]
    Dg = D.T @ G @ D
    return D @ np.linalg.solve(Dg, D.T @ b), np.linalg.cholesky(Dg).T @ D.T


def _bandlimited(h: np.ndarray, m1: int, m2: int, fs: float, cutoff: float, order: int) -> np.ndarray:
    """Lags ``-m1 ... m2`` of periodic ``h`` after zero-phase band-limiting.

    The window is widened by the filter's settling length (within one period of ``h``) before
    filtering and cropped afterwards, so that the crop of the slowly decaying (~1/n^2) differentiator
    tails does not leak into the band-limited values.
    """
    pad = max(64, int(20 * fs / cutoff))
    extra = max(0, min(pad, (len(h) - (m1 + m2 + 1)) // 2))
    _, wide = dd.two_sided(h, m1 + extra, m2 + extra)
    return bandlimit_fb(wide, fs, cutoff, order)[extra:extra + m1 + m2 + 1]


@register("ibk_irf", tags=("lti", "parametric", "irf"))
class IBKIRF(Estimator):
    """``I``, ``B``, ``K`` from a two-sided IRF: least squares ``h ~ I h2 + B h1 + K h0``.

    A nonparametric two-sided IRF ``h`` on lags ``-M1 ... M2`` is estimated from angle to torque with
    :class:`estimators.irf_ls.IRFLeastSquares` (``irf_method='ls'``, eq. 14) or
    :class:`estimators.irf_corr.IRFCorrelation` (``'corr'``, eq. 15). The discrete differentiator IRFs
    of an ``N``-point record, ``h0`` (eq. 10), ``h1`` (eq. 12) and ``h2`` (eq. 13, corrected ``n = 0``
    term, see :mod:`jointbench.core.differentiators`), are taken on the same lags. With ``bandlimit`` set,
    the IRF and the three differentiators are low-passed by the same Butterworth filter applied forward
    and backward (:func:`jointbench.core.signal.bandlimit_fb`); the differentiators are filtered on a window
    widened by the filter's settling length and then cropped. Finally ``I``, ``B``, ``K`` minimise
    ``sum_k (h(k) - I h2(k) - B h1(k) - K h0(k))^2``.

    Without band-limiting the fit uses the IRF up to the Nyquist frequency, where a band-limited
    perturbation leaves it undetermined and noisy; the paper band-limits to 20 Hz.

    The input's band (issue 20): when the pseudo-inverse (``pseudo_inverse = 'mdl'``) keeps fewer lag
    directions than lags, as it does for a band-limited input, the IRF holds the true IRF's part in those
    directions only, and the differentiators ``h2, h1, h0`` (which have it all) would bias I, B, K by
    whatever the input does not excite (K 113 [112, 114] for 120 on a 12 Hz multisine with the 20 Hz
    band-limit). The model's columns are then the pseudo-inverse IRFs, in the same directions, of the
    exact derivatives of the angle (:func:`kept_derivative_irfs`; ``differentiator_length`` does not
    apply), and the residuals are weighted as the torque weighs them; I, B, K are unbiased whatever the
    input's band. ``bandlimit`` is then not applied when it lies above the input's band (its top by
    :func:`jointbench.core.band.input_band`; below it, it is applied as without projection, restricting the fit
    to the band where the second-order model is meant to hold): the kept directions and the torque's weights already
    confine the fit to what the input excites (the generalised least-squares fit the band-limit stands in
    for), and a filter applied after the projection moves the IRF out of the kept directions, where the
    weights no longer hold: a direction kept for the coloured noise's chance share (coordinate ``c / s``,
    ``s`` 10^-8 of the largest) was smeared into the well-excited ones (issue 33: VAF down to -4e5 % and
    zero-width intervals on a 12 Hz input with torque noise low-passed at 30 Hz). When those columns cannot
    separate I, B and K (the singular values of the scaled columns below :data:`CONDITION`), the fit is
    refused in one line naming the input's band (Welch coherence, :mod:`estimators._band`) and the lag
    settings. The summary's ``band`` and the estimate's ``band_hz`` (CSV ``band_lo_hz``, ``band_hi_hz``) say
    the band the estimate rests on: 0 ... the lower of the band-limit (when applied) and the input's band.

    Parameters
    ----------
    settings : Settings
        ``irf_method`` ('ls' or 'corr', default 'ls'); ``lag_before``, ``lag_after`` (s, default 0.1);
        ``remove_mean`` (default True); ``edges`` ('zero' or 'valid', 'ls' only; default 'valid');
        ``differentiator_length`` (samples ``N``, default 0 = the first record's length, rounded up to even);
        ``bandlimit`` (Hz,
        default 20 Hz as in the paper; 'none' = off); ``bandlimit_order`` (Butterworth order, default 8).

    Notes
    -----
    :meth:`fit` returns a :class:`~jointbench.core.estimate.ParametricEstimate` whose ``basis`` is the
    nonparametric :class:`~jointbench.core.estimate.IRFEstimate` the parameters were fitted to (band-limited
    when ``bandlimit`` is set).

    Intervals (95 %): ``I``, ``B``, ``K`` are linear in the IRF (``x = A^+ F h``, ``F`` the band-limiting
    filter), so their covariance is ``A^+ F Cov(h) F^T A^+T`` with the IRF's segment-robust covariance
    (:func:`jointbench.core.intervals.segment_covariance`), t quantiles. They describe the noise, not the
    misfit of a second-order model (reflexes) or the bias of a band-limit above the input's band.

    References
    ----------
    Westwick, D. T. & Perreault, E. J. (2012). Estimates of acausal joint impedance models. IEEE Trans.
    Biomed. Eng. 59(10), doi:10.1109/TBME.2012.2213339, eqs. 10-15 and Sec. V-B (Table I, Fig. 7).

    Hunter, I. W. & Kearney, R. E. (1983). Two-sided linear filter identification. Med. Biol. Eng.
    Comput. 21, 203-209.
    """

    accepts = frozenset({"trial", "pooled"})      # every record given enters the fit

    @dataclasses.dataclass(frozen=True)
    class Settings(LagSettings):
        irf_method: Literal["ls", "corr"] = param("ls", doc="nonparametric IRF: 'ls' (eq. 14) or 'corr' (eq. 15)")
        edges: Edges | None = param(None, doc="regression rows at the record ends, irf_method 'ls' only "
                                              "(None = 'valid' for 'ls'; see irf2_ls)")
        differentiator_length: int = param(0, ge=0, doc="record length N (samples) of the differentiators; "
                                                        "0 = the first record's length; rounded up to even")
        bandlimit: float | None = param(20.0, unit="Hz", gt=0,
                                        doc="zero-phase Butterworth low-pass of IRF and differentiators "
                                            "(the paper's 20 Hz); keep it below the perturbation's band; "
                                            "not applied when the pseudo-inverse keeps fewer lag directions "
                                            "than lags (the fit is then weighted instead); none = off")
        bandlimit_order: int = param(8, ge=1, doc="order of the band-limiting Butterworth filter")

        def __post_init__(self):
            if self.irf_method == "corr" and self.edges is not None:
                raise ValueError("edges applies to irf_method = 'ls' only (the correlation method uses "
                                 "zero-padded correlations)")
            if 0 < self.differentiator_length < 4:
                raise ValueError(f"differentiator_length must be 0 (record length) or >= 4 samples, "
                                 f"got {self.differentiator_length}")

    def _fit(self, trials: list[Trial]) -> ParametricEstimate:
        s = self.settings
        fs = trials[0].fs
        m1, m2 = lag_samples(s, fs)
        fit = fit_irf(self.name, trials, s, s.irf_method, s.edges or "valid")
        irf = IRFEstimate(lags=np.arange(-m1, m2 + 1), h=fit.h, fs=fs, time=trials[0].time,
                          estimator=f"irf2_{s.irf_method}")
        n = s.differentiator_length or trials[0].n
        n += n % 2
        if n <= m1 + m2:
            raise InputError(f"{self.name}: differentiator_length N = {n} samples is not longer than the lag "
                             f"range M1+M2+1 = {m1 + m2 + 1} samples; the lags would wrap around")
        if s.bandlimit is not None and not s.bandlimit < fs / 2:
            raise InputError(f"{self.name}: bandlimit = {s.bandlimit:g} Hz must be below the Nyquist "
                             f"frequency {fs / 2:g} Hz")
        projected = fit.directions is not None and fit.kept < fit.n_lags
        band = band_of_trials(self.name, trials)
        # projected onto the kept directions, a band-limit above the input's band has nothing left to remove:
        # it only smears directions kept for the noise's chance share into the excited ones (class docstring)
        limited = s.bandlimit is not None and not (projected and (band is None or s.bandlimit >= band.hi))
        cols, Wr = self._columns(trials, fit, n, m1, m2, projected, limited)
        h, F = self._filtered(irf.h, fs) if limited else (irf.h, np.eye(len(irf.h)))
        ls = LeastSquares.of(np.column_stack(cols), h, F, Wr)
        I, B, K = self._solve(ls, band, fit, m1, m2)
        label = f"{irf.estimator}, band-limited to {s.bandlimit:g} Hz" if limited else irf.estimator
        basis = IRFEstimate(lags=irf.lags, h=h, fs=fs, time=irf.time, estimator=label)
        top = s.bandlimit if limited else fs / 2
        info = dict(fit.info)
        if band is not None and band.hi < top:
            top = band.hi
        unused = f"bandlimit {s.bandlimit:g} Hz not applied (above the input's band): " \
            if s.bandlimit is not None and not limited else (f"bandlimit {s.bandlimit:g} Hz; " if limited else "")
        info["band"] = (f"0 ... {top:g} Hz; the input's band " + (band.text() if band else "unknown")
                        + (f"; {unused}I, B, K fitted in the IRF's kept lag directions, weighted as the torque "
                           f"weighs them" if projected else
                           f"; bandlimit {s.bandlimit:g} Hz" if limited else "; no bandlimit"))
        est = ParametricEstimate(I=I, B=B, K=K, fs=fs, time=trials[0].time, estimator=self.name, basis=basis,
                                 band_hz=(0.0, top))
        est.fit_info = info
        if fit.cov is None:
            return est
        return _with_intervals(est, ls, fit)

    def _columns(self, trials: list[Trial], fit, n: int, m1: int, m2: int, projected: bool,
                 limited: bool) -> tuple[list[np.ndarray], np.ndarray | None]:
        """The model's columns ``h2, h1, h0`` on the lags ``-m1 ... m2`` (band-limited as the IRF) and the
        weights of the residuals: the pseudo-inverse IRFs of the angle's exact derivatives and the torque's
        weights when the IRF holds only its kept lag directions (``projected``, :func:`kept_derivative_irfs`),
        else the differentiators of an ``n``-point record (weights None)."""
        s = self.settings
        fs = trials[0].fs
        if projected:
            # the pseudo-inverse IRF holds the true IRF's part in the kept directions only: so must the model
            pairs = input_output(self.name, trials, s.remove_mean)
            edges = "zero" if s.irf_method == "corr" else (s.edges or "valid")
            c, Wr = kept_derivative_irfs(pairs, m1, m2, edges, fit.directions)
            cols = [c[:, 0] * fs ** 2, c[:, 1] * fs, c[:, 2]]
            if limited:
                cols = [bandlimit_fb(c, fs, s.bandlimit, s.bandlimit_order) for c in cols]
            return cols, Wr
        periodic = (dd.h2(n, fs), dd.h1(n, fs), dd.h0(n))
        if limited:
            return [_bandlimited(p, m1, m2, fs, s.bandlimit, s.bandlimit_order) for p in periodic], None
        return [dd.two_sided(p, m1, m2)[1] for p in periodic], None

    def _filtered(self, h: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
        """The IRF ``h`` band-limited (``bandlimit``; unchanged without) and the filter as a matrix ``F``."""
        s = self.settings
        if s.bandlimit is None:
            return h, np.eye(len(h))
        F = np.column_stack([bandlimit_fb(e, fs, s.bandlimit, s.bandlimit_order) for e in np.eye(len(h))])
        return bandlimit_fb(h, fs, s.bandlimit, s.bandlimit_order), F

    def _solve(self, ls: LeastSquares, band, fit, m1: int, m2: int) -> tuple[float, float, float]:
        """``I``, ``B``, ``K`` by least squares; :class:`InputError` when the columns cannot separate them (their
        scaled singular values below :data:`CONDITION`, or a rank below 3)."""
        s = self.settings
        sv = np.linalg.svd(ls.A / ls.scale, compute_uv=False)
        if len(sv) < 3 or sv[-1] <= CONDITION * sv[0]:     # (weighted: one row per kept direction)
            where = f"the input's band {band.lo:g} ... {band.hi:g} Hz" if band else "the angle"
            raise InputError(f"{self.name}: {where} and the lags -{m1} ... {m2} ({s.lag_before:g} s, "
                             f"{s.lag_after:g} s) leave {fit.kept} of {fit.n_lags} lag directions, too few to "
                             f"separate I, B and K; lengthen lag_before/lag_after or broaden the perturbation")
        x, _, rank, _ = scipy.linalg.lstsq(ls.A / ls.scale, ls.hw)
        if rank < 3:
            raise InputError(f"{self.name}: {m1 + m2 + 1} lag(s) cannot separate I, B and K; lengthen the lags")
        I, B, K = (float(v) for v in x / ls.scale)
        return I, B, K


class LeastSquares(NamedTuple):
    """The least-squares problem of ``I``, ``B``, ``K`` (:meth:`IBKIRF._solve`), weighted when ``Wr`` is set.

    Attributes
    ----------
    A : ndarray (rows, 3)
        The columns ``h2, h1, h0`` (times ``Wr``).
    hw : ndarray
        The band-limited IRF they fit (times ``Wr``).
    F : ndarray
        The band-limiting filter from the raw IRF to ``hw`` (times ``Wr``).
    Wr : ndarray or None
        The residuals' weights (:func:`kept_derivative_irfs`), or None.
    h : ndarray
        The band-limited IRF itself.
    scale : ndarray (3,)
        The norms of ``A``'s columns (zero ones as 1).
    """

    A: np.ndarray
    hw: np.ndarray
    F: np.ndarray
    Wr: np.ndarray | None
    h: np.ndarray
    scale: np.ndarray

    @classmethod
    def of(cls, A: np.ndarray, h: np.ndarray, F: np.ndarray, Wr: np.ndarray | None) -> "LeastSquares":
        """Columns ``A``, IRF ``h`` and filter ``F``, weighted by ``Wr`` (residuals weighted as the torque weighs
        them, see :func:`kept_derivative_irfs`) when it is not None."""
        hw = h
        if Wr is not None:
            A, hw, F = Wr @ A, Wr @ h, Wr @ F
        scale = np.linalg.norm(A, axis=0)
        scale[scale == 0] = 1.0
        return cls(A=A, hw=hw, F=F, Wr=Wr, h=h, scale=scale)


def _with_intervals(est: ParametricEstimate, ls: LeastSquares, fit) -> ParametricEstimate:
    """``est`` with the intervals of ``I``, ``B``, ``K`` (and its basis with the IRF's it was fitted to): linear
    in the IRF, ``x = G h_raw``, so their covariance is ``G Cov(h) G^T`` (t quantiles), worked out in the kept
    directions' coordinates (:func:`estimators._twosided.linear_covariance`)."""
    I, B, K = est.I, est.B, est.K
    G = (np.linalg.pinv(ls.A / ls.scale) / ls.scale[:, None]) @ ls.F       # x = G h_raw
    q = t_quantile(fit.dof)
    se = np.sqrt(np.maximum(np.diag(linear_covariance(fit, G)), 0.0))
    bounds = {k: (v - q * e, v + q * e) for k, v, e in zip("IBK", (I, B, K), se)}
    bounds["stiffness"] = bounds["K"]
    Fh = ls.F if ls.Wr is None else np.linalg.pinv(ls.Wr) @ ls.F            # the fitted IRF's own filter
    se_h = np.sqrt(np.maximum(np.diag(linear_covariance(fit, Fh)), 0.0))
    h = ls.h
    est.basis.with_intervals(Intervals(level=LEVEL, method=irf_intervals(fit).method, response={
        "h": (h - q * se_h, h + q * se_h)}))
    return est.with_intervals(Intervals(level=LEVEL, method=irf_intervals(fit).method, bounds=bounds,
                                        pointwise=False))
