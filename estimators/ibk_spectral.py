"""I, B, K fitted to the spectral impedance estimate (Westwick & Perreault 2012, Sec. V-A)."""
from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg
from scipy import stats

from estimators import Estimator, register
from estimators.spectral import LEVEL, WelchSettings, frf_estimate
from jointbench.errors import InputError
from jointbench.estimate import Intervals, ParametricEstimate
from jointbench.schema import param
from jointbench.types import Trial


@register("ibk_spectral", tags=("lti", "parametric", "frf"))
class IBKSpectral(Estimator):
    """Second-order impedance ``K + j w B - I w^2`` fitted to ``S_uy / S_uu`` by coherence-weighted least squares.

    The spectral estimate of :class:`estimators.spectral.Spectral` (eq. 16) is fitted at the Welch
    frequencies in ``[fmin, fmax]`` minimising ``sum_f gamma^2(f) |H(f) - (K + j w B - I w^2)|^2``
    with ``gamma^2`` the squared coherence: each frequency contributes a real row
    ``K - I w^2 = Re H`` and an imaginary row ``B w = Im H``, both scaled by ``gamma`` so that the
    squared residual carries the weight ``gamma^2``. Frequencies outside the band get zero weight
    (the paper: "points at frequencies above 20 Hz were assigned zero weight").

    Parameters
    ----------
    settings : Settings
        ``fmin``, ``fmax`` (Hz, default 0 and 20): fitted band, ``fmax > fmin``; and the Welch settings
        of :class:`estimators.spectral.Spectral`: ``segment`` (s, default 2.0), ``overlap`` (default
        0.5), ``window`` (default 'hann'), ``detrend`` (default 'constant').

    Notes
    -----
    :meth:`fit` returns a :class:`~jointbench.estimate.ParametricEstimate` whose ``basis`` is the
    :class:`~jointbench.estimate.FRFEstimate` the parameters were fitted to.

    Intervals (95 %): the covariance of the weighted least squares propagated from the variance of the
    spectral estimate (:func:`spectral_covariance`: ``E|H_hat - H|^2 = |H|^2 (1 - gamma^2) /
    (n gamma^2)`` with ``n`` effective averages, and the correlation of neighbouring frequencies that
    the taper causes), normal quantiles. They describe the noise, not a model that does not fit (e.g.
    reflexes, or an uncorrected sensor delay, which biases B).

    References
    ----------
    Westwick, D. T. & Perreault, E. J. (2012). Estimates of acausal joint impedance models. IEEE Trans.
    Biomed. Eng. 59(10), doi:10.1109/TBME.2012.2213339, eq. 16 and Sec. V-A (Fig. 6).
    """

    @dataclasses.dataclass(frozen=True)
    class Settings(WelchSettings):
        fmin: float = param(0.0, unit="Hz", ge=0, doc="lowest frequency given weight in the fit")
        fmax: float = param(20.0, unit="Hz", gt=0, doc="highest frequency given weight in the fit")

        def __post_init__(self):
            super().__post_init__()
            if self.fmax <= self.fmin:
                raise ValueError(f"fmax ({self.fmax:g} Hz) must be greater than fmin ({self.fmin:g} Hz)")

    def _fit(self, trials: list[Trial]) -> ParametricEstimate:
        s = self.settings
        fs = trials[0].fs
        frf = frf_estimate(self.name, trials, s, "spectral")
        f, H, coh = frf.freq, frf.H, frf.coherence
        sel = (f >= s.fmin) & (f <= s.fmax) & (coh > 0)
        if sel.sum() < 3:
            raise InputError(f"{self.name}: only {int(sel.sum())} frequency point(s) with nonzero coherence in "
                             f"fmin ... fmax = {s.fmin:g} ... {s.fmax:g} Hz (resolution {f[1]:g} Hz from "
                             f"segment = {s.segment:g} s); need at least 3: widen the band or lengthen 'segment'")
        w = 2 * np.pi * f[sel]
        g = np.sqrt(coh[sel])  # row scale gamma -> squared residual weighted by gamma^2
        zero = np.zeros_like(w)
        A = np.block([[(-w ** 2 * g)[:, None], zero[:, None], g[:, None]],
                      [zero[:, None], (w * g)[:, None], zero[:, None]]])
        b = np.concatenate([H.real[sel] * g, H.imag[sel] * g])
        scale = np.linalg.norm(A, axis=0)
        if np.any(scale == 0):
            raise InputError(f"{self.name}: the band {s.fmin:g} ... {s.fmax:g} Hz cannot separate I, B and K")
        x, _, rank, _ = scipy.linalg.lstsq(A / scale, b)
        if rank < 3:
            raise InputError(f"{self.name}: the band {s.fmin:g} ... {s.fmax:g} Hz cannot separate I, B and K")
        I, B, K = (float(v) for v in x / scale)
        est = ParametricEstimate(I=I, B=B, K=K, fs=fs, time=trials[0].time, estimator=self.name, basis=frf,
                                 band_hz=(s.fmin, s.fmax))
        cov = spectral_covariance(A / scale, g, H[sel], coh[sel], frf.n_averages, np.flatnonzero(sel),
                                  int(round(s.segment * fs)), s.window) / np.outer(scale, scale)
        z = float(stats.norm.ppf(0.5 + LEVEL / 2))
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
        bounds = {k: (v - z * e, v + z * e) for k, v, e in zip("IBK", (I, B, K), se)}
        bounds["stiffness"] = bounds["K"]
        return est.with_intervals(Intervals(level=LEVEL, method="weighted least-squares covariance from the "
                                            f"coherence ({frf.n_averages:.1f} effective averages)", bounds=bounds,
                                            pointwise=False))


def window_correlation(nseg: int, window: str, most: int) -> np.ndarray:
    """``rho_m = |sum w^2 e^{j 2 pi m n / N}|^2 / (sum w^2)^2``, ``m = 0 ... most``: the correlation of the
    spectral estimates ``m`` frequencies apart that the taper ``w`` causes (4/9 and 1/36 for Hann)."""
    from scipy import signal as sps

    w2 = sps.get_window(window, nseg) ** 2
    n = np.arange(nseg)
    c = np.array([abs(np.sum(w2 * np.exp(2j * np.pi * m * n / nseg))) for m in range(most + 1)]) / w2.sum()
    return c * c


def spectral_covariance(A: np.ndarray, g: np.ndarray, H: np.ndarray, coh: np.ndarray, n_avg: float,
                        bins: np.ndarray, nseg: int, window: str) -> np.ndarray:
    """Covariance of ``x`` in the weighted least squares ``A x ~ b`` of :class:`IBKSpectral`.

    ``A`` (rows: real parts, then imaginary parts, each scaled by ``g = gamma``) and ``b`` scaled
    alike; ``x = (A^T A)^-1 A^T b``, so ``Cov x = M A^T diag(g) C diag(g) A M`` with ``M = (A^T A)^-1``
    and ``C`` the covariance of the unscaled real and imaginary parts of ``H_hat``: variance
    ``v_k / 2`` each, ``v_k = |H|^2 (1 - gamma^2) / (n gamma^2)`` (Bendat & Piersol 2010, Sec. 9.2.5),
    correlated between frequencies ``m`` apart by :func:`window_correlation`.
    """
    v = np.abs(H) ** 2 * (1 - coh) / (max(n_avg, 1.0) * np.maximum(coh, 1e-300)) / 2.0
    rho = window_correlation(nseg, window, 4)
    d = np.abs(bins[:, None] - bins[None, :])
    P = np.where(d <= 4, rho[np.minimum(d, 4)], 0.0)
    Ck = np.sqrt(np.outer(v, v)) * P
    nk = len(H)
    C = np.zeros((2 * nk, 2 * nk))
    C[:nk, :nk] = Ck
    C[nk:, nk:] = Ck
    gg = np.concatenate([g, g])
    M = np.linalg.pinv(A.T @ A)
    Ag = A * gg[:, None]
    return M @ Ag.T @ C @ Ag @ M
