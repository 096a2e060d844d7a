"""I, B, K fitted to the spectral impedance estimate (Westwick & Perreault 2012, Sec. V-A)."""
from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg

from estimators import Estimator, register
from estimators.spectral import WelchSettings, welch_frf
from jointbench.errors import InputError
from jointbench.estimate import FRFEstimate, ParametricEstimate
from jointbench.schema import param
from jointbench.types import Trial


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
        f, H, coh = welch_frf(self.name, trials, s)
        frf = FRFEstimate(freq=f, H=H, coherence=coh, fs=fs, time=trials[0].time, estimator="spectral")
        sel = (f >= s.fmin) & (f <= s.fmax) & (coh > 0)
        if sel.sum() < 3:
            raise InputError(f"{self.name}: only {int(sel.sum())} frequency point(s) with nonzero coherence in "
                             f"fmin ... fmax = {s.fmin:g} ... {s.fmax:g} Hz (resolution {f[1]:g} Hz from "
                             f"segment = {s.segment:g} s); need at least 3: widen the band or lengthen 'segment'")
        I, B, K = weighted_ibk_fit(f[sel], H[sel], coh[sel], self.name, f"the band {s.fmin:g} ... {s.fmax:g} Hz")
        return ParametricEstimate(I=I, B=B, K=K, fs=fs, time=trials[0].time, estimator=self.name, basis=frf)
