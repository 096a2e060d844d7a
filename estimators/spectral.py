"""Nonparametric impedance frequency response by Welch spectral averaging (Westwick & Perreault 2012, eq. 16)."""
from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np
from scipy import signal as sps

from estimators import Estimator, register
from jointbench.errors import InputError
from jointbench.estimate import FRFEstimate
from jointbench.schema import param
from jointbench.types import Trial


@dataclasses.dataclass(frozen=True)
class WelchSettings:
    """Segmenting of the Welch spectral estimates (shared with :mod:`estimators.ibk_spectral`)."""

    segment: float = param(2.0, unit="s", gt=0, doc="Welch segment length (frequency resolution 1/segment)")
    overlap: float = param(0.5, ge=0, lt=1, doc="fraction of a segment shared with the next one, in [0, 1)")
    window: str = param("hann", doc="taper applied to each segment (a scipy.signal.get_window name)")
    detrend: Literal["constant", "linear", "none"] = param("constant", doc="trend removed from each segment")

    def __post_init__(self):
        try:
            sps.get_window(self.window, 16)
        except (ValueError, TypeError) as exc:
            raise ValueError(f"window: {self.window!r} is not a scipy.signal.get_window name ({exc})") from None


def welch_frf(name: str, trials: list[Trial], s: WelchSettings) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frequencies (Hz), ``H = S_uy / S_uu`` and squared coherence, spectra averaged over all records.

    ``u`` is the angle and ``y`` the torque. :func:`scipy.signal.csd` ``(u, y)`` averages
    ``conj(U) Y``, so for ``y = h * u`` the ratio is ``H`` itself (not its conjugate). Each record's
    spectra are weighted by its number of segments, i.e. every segment of every record counts once.
    """
    fs = trials[0].fs
    nseg = int(round(s.segment * fs))
    shortest = min(trials, key=lambda t: t.n)
    if nseg < 4:
        raise InputError(f"{name}: segment = {s.segment:g} s is {nseg} samples at {fs:g} Hz; need at least 4")
    if nseg > shortest.n:
        raise InputError(f"{name}: segment = {s.segment:g} s ({nseg} samples) is longer than record "
                         f"'{shortest.name}' ({shortest.n} samples, {shortest.n / fs:g} s); shorten 'segment'")
    nover = min(int(round(s.overlap * nseg)), nseg - 1)
    detrend = False if s.detrend == "none" else s.detrend

    def cross(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return sps.csd(a, b, fs=fs, window=s.window, nperseg=nseg, noverlap=nover, detrend=detrend)

    suu = syy = suy = 0.0
    count = 0
    for t in trials:
        w = 1 + (t.n - nseg) // (nseg - nover)  # segments in this record
        f, puy = cross(t.angle, t.torque)
        suu = suu + w * cross(t.angle, t.angle)[1].real
        syy = syy + w * cross(t.torque, t.torque)[1].real
        suy = suy + w * puy
        count += w
    suu, syy, suy = suu / count, syy / count, suy / count
    scale = max(float(np.mean(t.angle ** 2)) for t in trials)
    if not suu.max() > 1e-20 * scale:
        raise InputError(f"{name}: the angle (input) has no power after detrending; nothing to identify")
    tiny = np.finfo(float).tiny
    ok = suu > 1e-14 * suu.max()
    H = np.where(ok, suy / np.where(ok, suu, 1.0), 0.0)
    den = suu * syy
    coh = np.where(ok & (den > tiny), np.abs(suy) ** 2 / np.where(den > tiny, den, 1.0), 0.0)
    return f, H, np.clip(coh, 0.0, 1.0)


@register("spectral", tags=("lti", "nonparametric", "frf"))
class Spectral(Estimator):
    """Impedance frequency response ``H = S_uy / S_uu`` with the squared coherence.

    Auto- and cross-spectra of angle ``u`` and torque ``y`` are Welch averages
    (:func:`scipy.signal.welch`, :func:`scipy.signal.csd`, identical segmenting); several records are
    pooled by averaging their segment spectra. The squared coherence is
    ``|S_uy|^2 / (S_uu S_yy)``. The convention is that of the impedance: for
    ``y = I u'' + B u' + K u``, ``H(f) = K + j w B - I w^2`` with ``w = 2 pi f``. Frequencies at which
    the input has no power get ``H = 0`` and coherence 0.

    Parameters
    ----------
    settings : Settings
        ``segment`` (s, default 2.0): Welch segment length; ``overlap`` (fraction in [0, 1), default
        0.5); ``window`` (scipy window name, default 'hann'); ``detrend`` ('constant', 'linear' or
        'none', default 'constant').

    Notes
    -----
    :meth:`fit` returns a :class:`~jointbench.estimate.FRFEstimate` at the Welch frequencies
    ``0 ... fs/2`` (resolution ``1/segment``). Unlike the IRF estimates (eqs. 14, 15) it does not
    depend on a memory length.

    References
    ----------
    Westwick, D. T. & Perreault, E. J. (2012). Estimates of acausal joint impedance models. IEEE Trans.
    Biomed. Eng. 59(10), doi:10.1109/TBME.2012.2213339, Sec. III-C, eq. 16 (and eq. 17 for the coherence).
    """

    @dataclasses.dataclass(frozen=True)
    class Settings(WelchSettings):
        pass

    def _fit(self, trials: list[Trial]) -> FRFEstimate:
        f, H, coh = welch_frf(self.name, trials, self.settings)
        return FRFEstimate(freq=f, H=H, coherence=coh, fs=trials[0].fs, time=trials[0].time,
                           estimator=self.name)
