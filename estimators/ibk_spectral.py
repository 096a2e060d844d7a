"""I, B, K fitted to the spectral impedance estimate (Westwick & Perreault 2012, Sec. V-A)."""
from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg

from jointbench.estimators import Estimator, register
from jointbench.estimators._band import EDGE
from jointbench.estimators.spectral import WelchSettings, frf_estimate, segment_spectra
from jointbench.core.band import MAX_GAP, input_band
from jointbench.core.errors import InputError
from jointbench.core.estimate import Intervals, ParametricEstimate
from jointbench.core.intervals import LEVEL, t_quantile
from jointbench.core.schema import param
from jointbench.core.types import Trial


def weighted_ibk_fit(f: np.ndarray, H: np.ndarray, coh: np.ndarray, name: str = "ibk_spectral",
                     band: str = "the band") -> tuple[float, float, float]:
    """``(I, B, K)`` minimising ``sum gamma^2 |H - (K + j w B - I w^2)|^2`` over the given frequencies (Hz).

    Each frequency contributes a real row ``K - I w^2 = Re H`` and an imaginary row ``B w = Im H``,
    both scaled by ``gamma = sqrt(coh)``. Shared by :class:`IBKSpectral` and by predictions of what it
    returns (e.g. the apparatus study's expected spectra).
    """
    w = 2 * np.pi * np.asarray(f, float)
    g = np.sqrt(np.asarray(coh, float))  # row scale gamma -> squared residual weighted by gamma^2
    zero = np.zeros_like(w)
    A = np.block([[(-w ** 2 * g)[:, None], zero[:, None], g[:, None]],
                  [zero[:, None], (w * g)[:, None], zero[:, None]]])
    b = np.concatenate([np.real(H) * g, np.imag(H) * g])
    scale = np.linalg.norm(A, axis=0)
    if np.any(scale == 0):
        raise InputError(f"{name}: {band} cannot separate I, B and K")
    x, _, rank, _ = scipy.linalg.lstsq(A / scale, b)
    if rank < 3:
        raise InputError(f"{name}: {band} cannot separate I, B and K")
    I, B, K = (float(v) for v in x / scale)
    return I, B, K


#: the jackknife of :meth:`IBKSpectral._jackknife` uses at most / at least this many groups of segments
MAX_GROUPS = 20
MIN_GROUPS = 6


@register("ibk_spectral", tags=("lti", "parametric", "frf"))
class IBKSpectral(Estimator):
    """Second-order impedance ``K + j w B - I w^2`` fitted to ``S_uy / S_uu`` by coherence-weighted least squares.

    The spectral estimate of :class:`estimators.spectral.Spectral` (eq. 16) is fitted at the Welch
    frequencies in ``[fmin, fmax]`` minimising ``sum_f gamma^2(f) |H(f) - (K + j w B - I w^2)|^2``
    with ``gamma^2`` the squared coherence: each frequency contributes a real row
    ``K - I w^2 = Re H`` and an imaginary row ``B w = Im H``, both scaled by ``gamma`` so that the
    squared residual carries the weight ``gamma^2``. Frequencies outside the band get zero weight
    (the paper: "points at frequencies above 20 Hz were assigned zero weight"). The band is first limited
    to the input's band (:mod:`estimators._band`): above a band-limited input's top, ``H`` is noise over
    the window's leakage and a few frequencies of chance coherence dominate the weighted fit (I, B, K off
    by factors, a negative VAF). The band used is printed (``band``) and is the estimate's
    :attr:`~jointbench.core.estimate.ParametricEstimate.band_hz` (the CSV's ``band_lo_hz``, ``band_hi_hz``).

    Parameters
    ----------
    settings : Settings
        ``fmin``, ``fmax`` (Hz, default 0 and 20): fitted band, ``fmax > fmin``, limited to the input's band
        unless ``input_band`` is false (:meth:`_band`, :mod:`estimators._band`); and the Welch settings
        of :class:`estimators.spectral.Spectral`: ``segment`` (s, default 2.0), ``overlap`` (default
        0.5), ``window`` (default 'hann'), ``detrend`` (default 'constant').

    Notes
    -----
    :meth:`fit` returns a :class:`~jointbench.core.estimate.ParametricEstimate` whose ``basis`` is the
    :class:`~jointbench.core.estimate.FRFEstimate` the parameters were fitted to.

    Intervals (95 %): a delete-a-group jackknife over the Welch segments (:meth:`_jackknife`), t
    quantiles. They describe the noise, not a model that does not fit (e.g. reflexes, or an uncorrected
    sensor delay, which biases B). (A covariance propagated from the coherence, with the taper's
    correlation of neighbouring frequencies, came out 1.5 times too narrow for K on simulated ankles
    with voluntary torque; the jackknife needs no noise model.)

    References
    ----------
    Westwick, D. T. & Perreault, E. J. (2012). Estimates of acausal joint impedance models. IEEE Trans.
    Biomed. Eng. 59(10), doi:10.1109/TBME.2012.2213339, eq. 16 and Sec. V-A (Fig. 6).
    """

    accepts = frozenset({"trial", "pooled"})      # every record given enters the fit

    @dataclasses.dataclass(frozen=True)
    class Settings(WelchSettings):
        fmin: float = param(0.0, unit="Hz", ge=0, doc="lowest frequency given weight in the fit")
        fmax: float = param(20.0, unit="Hz", gt=0, doc="highest frequency given weight in the fit")
        input_band: bool = param(True, doc="limit fmin ... fmax to the input's band (where the coherence is "
                                           "significant, estimators._band); false: the paper's rule, every "
                                           "frequency of fmin ... fmax with nonzero coherence")

        def __post_init__(self):
            super().__post_init__()
            if self.fmax <= self.fmin:
                raise ValueError(f"fmax ({self.fmax:g} Hz) must be greater than fmin ({self.fmin:g} Hz)")

    def _fit(self, trials: list[Trial]) -> ParametricEstimate:
        s = self.settings
        fs = trials[0].fs
        frf = frf_estimate(self.name, trials, s, "spectral")
        f, H, coh = frf.freq, frf.H, frf.coherence
        lo, hi, note = self._band(frf)
        sel = (f >= lo) & (f <= hi) & (coh > 0)
        if sel.sum() < 3:
            raise InputError(f"{self.name}: only {int(sel.sum())} frequency point(s) with nonzero coherence in "
                             f"fmin ... fmax = {s.fmin:g} ... {s.fmax:g} Hz (resolution {f[1]:g} Hz from "
                             f"segment = {s.segment:g} s); need at least 3: widen the band or lengthen 'segment'")
        I, B, K = weighted_ibk_fit(f[sel], H[sel], coh[sel], self.name, f"the band {lo:g} ... {hi:g} Hz")
        est = ParametricEstimate(I=I, B=B, K=K, fs=fs, time=trials[0].time, estimator=self.name, basis=frf,
                                 band_hz=(lo, hi))
        est.fit_info = {"band": note}
        jack = self._jackknife(trials, sel)
        if jack is None:
            return est
        cov, dof = jack
        q = t_quantile(dof)
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
        bounds = {k: (v - q * e, v + q * e) for k, v, e in zip("IBK", (I, B, K), se)}
        bounds["stiffness"] = bounds["K"]
        return est.with_intervals(Intervals(level=LEVEL, method=f"delete-a-group jackknife over the Welch segments "
                                            f"({dof + 1} groups; t quantile)", bounds=bounds, pointwise=False))

    def _band(self, frf) -> tuple[float, float, str]:
        """The fitted band ``(lo, hi, description)``: ``fmin ... fmax`` limited to the input's band.

        An edge of the input's band within ``MAX_GAP + 1`` frequencies of the asked edge counts as reaching
        it (the asked edge is kept); an edge of the input's band that limits the fit is moved
        :data:`~estimators._band.EDGE` frequencies inwards. Raises :class:`InputError` when the input has no
        band (no run of excited frequencies) or when its band and ``fmin ... fmax`` leave fewer than 3 frequencies.
        """
        s = self.settings
        asked = f"fmin ... fmax = {s.fmin:g} ... {s.fmax:g} Hz"
        if not s.input_band:
            return s.fmin, s.fmax, f"{asked} (input_band = false: not checked against the input)"
        band = input_band(frf)
        if band is None:
            raise InputError(f"{self.name}: the angle excites no band (no 3 adjacent frequencies of significant "
                             f"coherence at resolution {frf.freq[1]:g} Hz): nothing to fit; use a perturbation with "
                             f"more power, longer records, or set input_band = false to fit {asked} regardless")
        slack = (MAX_GAP + 1) * band.resolution
        lo = s.fmin if band.lo <= s.fmin + slack else band.lo + EDGE * band.resolution
        hi = s.fmax if band.hi >= s.fmax - slack else band.hi - EDGE * band.resolution
        n = int(np.sum((frf.freq >= lo) & (frf.freq <= hi) & (frf.coherence > 0)))
        if (lo, hi) != (s.fmin, s.fmax) and (hi <= lo or n < 3):
            raise InputError(f"{self.name}: {asked} lies outside the input's band {band.lo:g} ... {band.hi:g} Hz "
                             f"(significant coherence); set fmin and fmax inside it")
        if (lo, hi) == (s.fmin, s.fmax):          # (fewer than 3 frequencies: refused by the caller)
            return lo, hi, f"{lo:g} ... {hi:g} Hz ({asked}, within the input's band {band.text()})"
        return lo, hi, (f"{lo:g} ... {hi:g} Hz: {asked} limited to the input's band {band.text()} less {EDGE} "
                        f"frequencies at its edge (leakage); outside it H is noise (settings fmin, fmax, input_band)")

    def _jackknife(self, trials: list[Trial], sel: np.ndarray) -> tuple[np.ndarray, int] | None:
        """Covariance of (I, B, K) by the delete-a-group jackknife over the Welch segments, and its dof.

        The segments (in record order) are cut into ``G`` contiguous groups (at most
        :data:`MAX_GROUPS`, at least :data:`MIN_GROUPS`, else ``None``); the fit is repeated without
        each group, and ``Cov = (G - 1)/G sum_g (x_g - mean x)(x_g - mean x)^T``. Contiguous groups of
        overlapping segments are nearly independent (tapered spectra of Hann segments overlapping by half
        correlate by 0.03), so the jackknife needs no model of the noise (the
        voluntary torque, the taper's leakage and the overlap included).

        References
        ----------
        Efron, B. & Stein, C. (1981). The jackknife estimate of variance. Ann. Stat. 9(3), 586-596;
        Thomson, D. J. & Chave, A. D. (1991), jackknifed error estimates for spectra and coherences, in
        Advances in Spectrum Analysis and Array Processing, vol. 1, Prentice Hall.
        """
        f, uu, yy, uy = segment_spectra(trials, self.settings)
        n = len(uu)
        G = min(MAX_GROUPS, n)
        if G < MIN_GROUPS:
            return None
        edges = np.linspace(0, n, G + 1).astype(int)
        tot = uu.sum(0), yy.sum(0), uy.sum(0)
        xs = []
        for a, b in zip(edges[:-1], edges[1:]):
            suu, syy, suy = (t - x[a:b].sum(0) for t, x in zip(tot, (uu, yy, uy)))
            ok = suu > 1e-14 * suu.max()
            H = np.where(ok, suy / np.where(ok, suu, 1.0), 0.0)
            den = suu * syy
            coh = np.where(ok & (den > 0), np.abs(suy) ** 2 / np.where(den > 0, den, 1.0), 0.0)
            keep = sel & (coh > 0)
            xs.append(weighted_ibk_fit(f[keep], H[keep], np.clip(coh[keep], 0, 1), self.name))
        xs = np.array(xs)
        d = xs - xs.mean(axis=0)
        return (G - 1) / G * d.T @ d, G - 1
