"""Inertia, damping and stiffness fitted to a two-sided IRF through discrete differentiators (Sec. V-B)."""
from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np
import scipy.linalg

from jointbench.estimators import Estimator, register
from jointbench.estimators._twosided import LEVEL, Edges, LagSettings, fit_irf, irf_intervals, lag_samples, t_quantile
from jointbench import differentiators as dd
from jointbench.errors import InputError
from jointbench.estimate import IRFEstimate, Intervals, ParametricEstimate
from jointbench.schema import param
from jointbench.signal import bandlimit_fb
from jointbench.types import Trial


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
    term, see :mod:`jointbench.differentiators`), are taken on the same lags. With ``bandlimit`` set,
    the IRF and the three differentiators are low-passed by the same Butterworth filter applied forward
    and backward (:func:`jointbench.signal.bandlimit_fb`); the differentiators are filtered on a window
    widened by the filter's settling length and then cropped. Finally ``I``, ``B``, ``K`` minimise
    ``sum_k (h(k) - I h2(k) - B h1(k) - K h0(k))^2``.

    Without band-limiting the fit uses the IRF up to the Nyquist frequency, where a band-limited
    perturbation leaves it undetermined and noisy; the paper band-limits to 20 Hz.

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
    :meth:`fit` returns a :class:`~jointbench.estimate.ParametricEstimate` whose ``basis`` is the
    nonparametric :class:`~jointbench.estimate.IRFEstimate` the parameters were fitted to (band-limited
    when ``bandlimit`` is set).

    Intervals (95 %): ``I``, ``B``, ``K`` are linear in the IRF (``x = A^+ F h``, ``F`` the band-limiting
    filter), so their covariance is ``A^+ F Cov(h) F^T A^+T`` with the IRF's segment-robust covariance
    (:func:`estimators._twosided.segment_covariance`), t quantiles. They describe the noise, not the
    misfit of a second-order model (reflexes) or the bias of a band-limit above the input's band.

    References
    ----------
    Westwick, D. T. & Perreault, E. J. (2012). Estimates of acausal joint impedance models. IEEE Trans.
    Biomed. Eng. 59(10), doi:10.1109/TBME.2012.2213339, eqs. 10-15 and Sec. V-B (Table I, Fig. 7).

    Hunter, I. W. & Kearney, R. E. (1983). Two-sided linear filter identification. Med. Biol. Eng.
    Comput. 21, 203-209.
    """

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
                                            "none = off")
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
        periodic = (dd.h2(n, fs), dd.h1(n, fs), dd.h0(n))
        h = irf.h
        if s.bandlimit is not None:
            if not s.bandlimit < fs / 2:
                raise InputError(f"{self.name}: bandlimit = {s.bandlimit:g} Hz must be below the Nyquist "
                                 f"frequency {fs / 2:g} Hz")
            h = bandlimit_fb(h, fs, s.bandlimit, s.bandlimit_order)
            cols = [_bandlimited(p, m1, m2, fs, s.bandlimit, s.bandlimit_order) for p in periodic]
            F = np.column_stack([bandlimit_fb(e, fs, s.bandlimit, s.bandlimit_order) for e in np.eye(len(h))])
        else:
            cols = [dd.two_sided(p, m1, m2)[1] for p in periodic]
            F = np.eye(len(h))
        A = np.column_stack(cols)
        scale = np.linalg.norm(A, axis=0)
        scale[scale == 0] = 1.0
        x, _, rank, _ = scipy.linalg.lstsq(A / scale, h)
        if rank < 3:
            raise InputError(f"{self.name}: {m1 + m2 + 1} lag(s) cannot separate I, B and K; lengthen the lags")
        I, B, K = (float(v) for v in x / scale)
        label = irf.estimator if s.bandlimit is None else f"{irf.estimator}, band-limited to {s.bandlimit:g} Hz"
        basis = IRFEstimate(lags=irf.lags, h=h, fs=fs, time=irf.time, estimator=label)
        band = None if s.bandlimit is None else (0.0, s.bandlimit)
        est = ParametricEstimate(I=I, B=B, K=K, fs=fs, time=trials[0].time, estimator=self.name, basis=basis,
                                 band_hz=band)
        est.fit_info = fit.info
        if fit.cov is None:
            return est
        G = (np.linalg.pinv(A / scale) / scale[:, None]) @ F       # x = G h_raw
        cov = G @ fit.cov @ G.T
        q = t_quantile(fit.dof)
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
        bounds = {k: (v - q * e, v + q * e) for k, v, e in zip("IBK", (I, B, K), se)}
        bounds["stiffness"] = bounds["K"]
        se_h = np.sqrt(np.maximum(np.diag(F @ fit.cov @ F.T), 0.0))
        basis.with_intervals(Intervals(level=LEVEL, method=irf_intervals(fit).method, response={
            "h": (h - q * se_h, h + q * se_h)}))
        return est.with_intervals(Intervals(level=LEVEL, method=irf_intervals(fit).method, bounds=bounds,
                                            pointwise=False))
