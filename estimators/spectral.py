"""Nonparametric impedance frequency response by Welch spectral averaging (Westwick & Perreault 2012, eq. 16)."""
from __future__ import annotations

import dataclasses
from typing import Literal

import numpy as np
import scipy.fft
from scipy import signal as sps

from jointbench.estimators import Estimator, register
from jointbench.core.band import frf_and_coherence
from jointbench.core.errors import InputError
from jointbench.core.estimate import FRFEstimate, Intervals
from jointbench.core.intervals import LEVEL
from jointbench.core.schema import param
from jointbench.core.types import Trial



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


def welch_frf(name: str, trials: list[Trial],
              s: WelchSettings) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Frequencies (Hz), ``H = S_uy / S_uu``, squared coherence (:func:`jointbench.core.band.frf_and_coherence`)
    and the input's power ``S_uu``, spectra averaged over all records.

    ``u`` is the angle and ``y`` the torque. :func:`scipy.signal.csd` ``(u, y)`` averages
    ``conj(U) Y``, so for ``y = h * u`` the ratio is ``H`` itself (not its conjugate). Each record's
    spectra are weighted by its number of segments, i.e. every segment of every record counts once.
    The segments' FFTs are computed once per signal and all three spectra formed from them: the numbers
    of three :func:`scipy.signal.csd` calls, bit for bit (same taper, detrending, products and means).
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
    # scipy.signal.csd's segmenting: its taper scaled to a density, its frequencies
    sft = sps.ShortTimeFFT(sps.get_window(s.window, nseg), nseg - nover, fs, fft_mode="onesided", mfft=nseg,
                           scale_to="psd")
    f, win = sft.f, sft.win

    suu = syy = suy = 0.0
    count = 0
    for t in trials:
        w = 1 + (t.n - nseg) // (nseg - nover)  # segments in this record
        FU = _segment_ffts(t.angle, nseg, nseg - nover, w, win, s.detrend)
        FY = _segment_ffts(t.torque, nseg, nseg - nover, w, win, s.detrend)
        suu = suu + w * _onesided_mean(FU.real ** 2 + FU.imag ** 2, nseg)
        syy = syy + w * _onesided_mean(FY.real ** 2 + FY.imag ** 2, nseg)
        suy = suy + w * _onesided_mean(FY * FU.conj(), nseg)
        count += w
    suu, syy, suy = suu / count, syy / count, suy / count
    if not (np.all(np.isfinite(suu)) and np.all(np.isfinite(syy)) and np.all(np.isfinite(np.abs(suy)))):
        raise InputError(f"{name}: the spectra overflow (values too large for double precision); rescale the data")
    scale = max(float(np.mean(t.angle ** 2)) for t in trials)
    if not suu.max() > 1e-20 * scale:
        raise InputError(f"{name}: the angle (input) has no power after detrending; nothing to identify")
    H, coh = frf_and_coherence(suu, syy, suy)
    return f, H, coh, suu


def _segment_ffts(x: np.ndarray, nseg: int, step: int, count: int, win: np.ndarray, detrend: str) -> np.ndarray:
    """FFTs of the ``count`` detrended, tapered segments of ``x`` (frequencies x segments, C order): what
    :func:`scipy.signal.csd` computes one segment at a time, here all at once (bit for bit the same numbers)."""
    seg = np.lib.stride_tricks.sliding_window_view(x, nseg)[:step * count:step].copy()
    if detrend == "constant":     # scipy.signal.detrend's 'constant', in place
        seg -= np.mean(seg, axis=-1, keepdims=True)
    elif detrend == "linear":     # one segment at a time: a least-squares fit over many gives other last bits
        seg = np.array([sps.detrend(r, type="linear") for r in seg])
    seg *= win
    return scipy.fft.rfft(seg, axis=-1).T.copy()


def _onesided_mean(P: np.ndarray, nfft: int) -> np.ndarray:
    """Mean over segments (last axis) of a one-sided density of ``nfft``-point FFTs, its rows doubled but
    DC (and Nyquist for even ``nfft``), as :func:`scipy.signal.csd` does, in the same order of operations."""
    P[1:-1 if nfft % 2 == 0 else None] *= 2
    return P.mean(axis=-1)


def segment_spectra(trials: list[Trial], s: WelchSettings) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Frequencies and each Welch segment's ``conj(U) U``, ``conj(Y) Y``, ``conj(U) Y`` (segments in record
    order, shape ``(segments, frequencies)``), with the segmenting, taper and detrending of
    :func:`welch_frf` (whose spectra are their means, up to a common scale)."""
    fs = trials[0].fs
    nseg = int(round(s.segment * fs))
    step = nseg - min(int(round(s.overlap * nseg)), nseg - 1)
    w = sps.get_window(s.window, nseg)
    uu, yy, uy = [], [], []
    for t in trials:
        count = 1 + (t.n - nseg) // step
        idx = np.arange(nseg)[None, :] + step * np.arange(count)[:, None]
        U, Y = t.angle[idx], t.torque[idx]
        if s.detrend != "none":
            U = sps.detrend(U, axis=-1, type=s.detrend)
            Y = sps.detrend(Y, axis=-1, type=s.detrend)
        FU, FY = np.fft.rfft(U * w, axis=-1), np.fft.rfft(Y * w, axis=-1)
        uu.append(np.abs(FU) ** 2)
        yy.append(np.abs(FY) ** 2)
        uy.append(np.conj(FU) * FY)
    return np.fft.rfftfreq(nseg, 1.0 / fs), np.vstack(uu), np.vstack(yy), np.vstack(uy)


def segment_count(trials: list[Trial], s: WelchSettings) -> int:
    """Welch segments over all records (as averaged by :func:`welch_frf`)."""
    nseg = int(round(s.segment * trials[0].fs))
    nover = min(int(round(s.overlap * nseg)), nseg - 1)
    return sum(1 + (t.n - nseg) // (nseg - nover) for t in trials)


def effective_averages(trials: list[Trial], s: WelchSettings) -> float:
    """Independent averages equivalent to the overlapping Welch segments.

    ``K / (1 + 2 sum_{j >= 1} (1 - j/K) rho_j^2)`` with ``rho_j`` the correlation of the taper with
    itself shifted by ``j`` segment steps (Welch 1967, eq. 11; 1.06 for Hann at 50 % overlap).

    References
    ----------
    Welch, P. D. (1967). The use of fast Fourier transform for the estimation of power spectra. IEEE
    Trans. Audio Electroacoust. 15(2), 70-73.
    """
    fs = trials[0].fs
    nseg = int(round(s.segment * fs))
    step = nseg - min(int(round(s.overlap * nseg)), nseg - 1)
    w = sps.get_window(s.window, nseg)
    K = segment_count(trials, s)
    factor = 1.0
    for j in range(1, nseg // step + 1):
        if j >= K:
            break
        rho = float(w[j * step:] @ w[:nseg - j * step]) / float(w @ w)
        factor += 2.0 * (1.0 - j / K) * rho * rho
    return K / factor


def taper_spread(taper: np.ndarray, fs: float) -> float:
    """Second moment ``sigma_w^2`` (rad^2/s^2) of the taper's spectral window ``|W(w)|^2``:
    ``int |w'(t)|^2 dt / int w(t)^2 dt``, by differences (``4 pi^2 / (3 T^2)`` for a Hann window of ``T`` s).

    The ensemble cross-spectrum of a window is the ``|W|^2``-weighted average of ``H`` around each bin
    (for an input spectrum flat across the spectral window), so a quadratic term ``-I w^2`` comes out as
    ``-I (w^2 + sigma_w^2)``: the resolution bias of spectral estimates, ``H'' B_e^2``-type (Bendat &
    Piersol 2010, Sec. 8.5.1), here exact because the impedance is a polynomial of degree two in ``w``.
    """
    d = np.diff(np.asarray(taper, float)) * fs
    return float(d @ d / fs) / float(taper @ taper / fs)


def frf_band(H: np.ndarray, coh: np.ndarray, n_avg: float, level: float = LEVEL) -> dict[str, tuple]:
    """Confidence band of ``H`` from the squared coherence: a circle of radius ``r`` around ``H``.

    For ``n`` independent averages and output noise independent of the input,
    ``|H - H_hat|^2 n S_uu / sigma_hat^2`` follows ``F(2, 2(n - 1))`` with the residual spectrum
    ``sigma_hat^2 = S_yy (1 - gamma^2) n / (n - 1)``, so
    ``r^2 = F_level(2, 2(n - 1)) (1 - gamma^2) / ((n - 1) gamma^2) |H_hat|^2``. Returned as the limits
    of the gain (``mag``: ``|H| -+ r``, floored at 0) and of the phase (``phase_rad``:
    ``-+ asin(r / |H|)``, or ``-+ pi`` when the circle holds the origin). Frequencies without coherence
    get an unbounded band (``mag`` 0 ... inf).

    References
    ----------
    Bendat, J. S. & Piersol, A. G. (2010). Random Data, 4th ed., Wiley, Sec. 9.2.5 (confidence region of
    the frequency response function from the coherence).
    """
    from scipy import stats

    mag = np.abs(H)
    dof = max(n_avg - 1.0, 1.0)
    F = float(stats.f.ppf(level, 2, 2 * dof))
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(coh > 0, mag * np.sqrt(F * (1 - coh) / (dof * np.where(coh > 0, coh, 1.0))), np.inf)
        dphi = np.where(r < mag, np.arcsin(np.clip(r / np.where(mag > 0, mag, 1.0), 0.0, 1.0)), np.pi)
    phase = np.angle(H)
    return {"mag": (np.maximum(mag - r, 0.0), mag + r), "phase_rad": (phase - dphi, phase + dphi)}


def frf_estimate(name: str, trials: list[Trial], s: WelchSettings, estimator: str) -> FRFEstimate:
    """:func:`welch_frf` as an :class:`FRFEstimate` with its effective averages and coherence band."""
    f, H, coh, suu = welch_frf(name, trials, s)
    n_avg = effective_averages(trials, s)
    est = FRFEstimate(freq=f, H=H, coherence=coh, fs=trials[0].fs, time=trials[0].time, estimator=estimator,
                      n_averages=n_avg, input_power=suu)
    band = frf_band(H, coh, n_avg)
    i = int(np.argmax(f > 0))
    k = {"stiffness": (band["mag"][0][i], band["mag"][1][i])}
    est.fit_info = {"averages": f"{segment_count(trials, s)} segments, {n_avg:.1f} effective",
                    "significant_coherence": f"{int(est.significant().sum())} of {len(f)} frequencies"}
    return est.with_intervals(Intervals(level=LEVEL, method=f"coherence (F distribution, {n_avg:.1f} effective "
                                                           f"averages)", bounds=k, response=band))


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
    :meth:`fit` returns a :class:`~jointbench.core.estimate.FRFEstimate` at the Welch frequencies
    ``0 ... fs/2`` (resolution ``1/segment``). Unlike the IRF estimates (eqs. 14, 15) it does not
    depend on a memory length. Its intervals are the coherence band of :func:`frf_band` (gain and phase,
    with the overlap's effective number of averages, :func:`effective_averages`); it predicts (for its
    VAF) only with ``H`` at the frequencies whose coherence is significant
    (:meth:`~jointbench.core.estimate.FRFEstimate.significant`).

    References
    ----------
    Westwick, D. T. & Perreault, E. J. (2012). Estimates of acausal joint impedance models. IEEE Trans.
    Biomed. Eng. 59(10), doi:10.1109/TBME.2012.2213339, Sec. III-C, eq. 16 (and eq. 17 for the coherence).
    """

    accepts = frozenset({"trial", "pooled"})      # every record given enters the fit

    @dataclasses.dataclass(frozen=True)
    class Settings(WelchSettings):
        pass

    def _fit(self, trials: list[Trial]) -> FRFEstimate:
        return frf_estimate(self.name, trials, self.settings, self.name)
