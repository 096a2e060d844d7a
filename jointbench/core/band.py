"""The input's band: the one definition of an *excited* frequency, and of the band the excited ones span.

Every band check (the estimators' reported and refused bands, the ensemble spectral estimator's fitted
bins, a frequency response's prediction) reads it here (``tests/test_one_home.py`` fails on a second
definition of the coherence threshold).

* A frequency *has input power* when the angle's (the input's) power there is above :data:`POWER_FLOOR` of
  its strongest frequency's (:func:`has_power`): below it the input is the taper's leakage from its band or
  the sensor's floor, not a perturbation.
* Its squared coherence is *significant* when above :func:`coherence_threshold` (the level
  :data:`jointbench.core.intervals.LEVEL`; Carter, Knapp & Nuttall 1973).
* A frequency is *excited* when both hold (:func:`excited`).
* The *input's band* (:func:`input_band`) is the span of runs of at least :data:`MIN_RUN` adjacent excited
  frequencies (three by chance: 0.05^3, about 1 in 8000 per position), joined across gaps of at most
  :data:`MAX_GAP` frequencies (a dip of the coherence inside the band); of the joined groups, the one
  holding the most input power. (Not the most frequencies: a servo's broadband jitter of microradians,
  times ``I w^2``, is coherent with the torque over hundreds of hertz, more frequencies than a
  perturbation below 4 Hz has; fsewls once reported such a record's band as 235.5 ... 500 Hz.)
  Frequencies without input power are neither excited nor gaps: they are skipped.

References
----------
Carter, G. C., Knapp, C. H. & Nuttall, A. H. (1973). Estimation of the magnitude-squared coherence
function via overlapped fast Fourier transform processing. IEEE Trans. Audio Electroacoust. 21(4).

Westwick, D. T. & Perreault, E. J. (2012). Estimates of acausal joint impedance models. IEEE Trans.
Biomed. Eng. 59(10), doi:10.1109/TBME.2012.2213339 (the input's bandwidth and the fitted band).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Protocol

import numpy as np

from jointbench.core.intervals import LEVEL


class Spectrum(Protocol):
    """What the band is read from (a :class:`jointbench.core.estimate.FRFEstimate`): frequencies (Hz), the
    squared coherence, its effective averages and the input's power (None: unknown)."""

    freq: np.ndarray
    coherence: np.ndarray
    n_averages: float | None
    input_power: np.ndarray | None

#: a frequency has input power when its power is above this fraction of the strongest frequency's (-60 dB)
POWER_FLOOR = 1e-6
#: H and the coherence are formed only where the input's power is above this fraction of the largest (below:
#: rounding; H = 0 and coherence 0 there)
LIVE_FLOOR = 1e-14
#: fewest adjacent excited frequencies that count as a run of the input's band
MIN_RUN = 3
#: most unexcited frequencies inside the band between two runs (a dip of the coherence)
MAX_GAP = 2


def coherence_threshold(n_averages: float, level: float = LEVEL) -> float:
    """Squared coherence exceeded with probability ``1 - level`` under zero coherence for ``n_averages``
    independent averages: ``1 - (1 - level)^(1/(n - 1))``. Fewer than 2 averages: no test can be made and
    the threshold is 0 (every nonzero coherence counts, as with the averages unknown). Beware: the squared
    coherence of a single average is 1 at every frequency, so it then tells nothing about the input's band
    (kept so for the fits of one segment that the studies and tests make; issue 33's report).

    References
    ----------
    Carter, Knapp & Nuttall (1973), eq. 30 (the distribution of the squared coherence under zero coherence).
    """
    return 0.0 if n_averages <= 1 else 1.0 - (1.0 - level) ** (1.0 / (n_averages - 1.0))


def significant(coherence, n_averages: float | None) -> np.ndarray:
    """Frequencies whose squared coherence is above :func:`coherence_threshold`; with ``n_averages`` unknown
    (None) or below 2, every frequency with nonzero coherence."""
    coh = np.asarray(coherence, float)
    return coh > 0 if n_averages is None else coh > coherence_threshold(n_averages)


def has_power(power) -> np.ndarray:
    """Frequencies at which the input's power is above :data:`POWER_FLOOR` of its largest."""
    p = np.asarray(power, float)
    return p > POWER_FLOOR * p.max() if p.size else np.zeros(0, bool)


def powered(power, coherence) -> np.ndarray:
    """Frequencies with input power (:func:`has_power`) at which a coherence was formed (nonzero); ``power``
    None (unknown): every frequency with nonzero coherence."""
    coh = np.asarray(coherence, float)
    return coh > 0 if power is None else has_power(power) & (coh > 0)


def excited(power, coherence, n_averages: float | None) -> np.ndarray:
    """THE excited frequencies: input power (:func:`powered`) and significant coherence (:func:`significant`)."""
    return powered(power, coherence) & significant(coherence, n_averages)


def frf_and_coherence(suu: np.ndarray, syy: np.ndarray, suy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The H1 estimate ``S_uy / S_uu`` and the squared coherence ``|S_uy|^2 / (S_uu S_yy)`` (clipped to 0 ... 1)
    from averaged spectra (any shape); both 0 where the input's power is at most :data:`LIVE_FLOOR` of its
    largest (over all of ``suu``) or the denominator underflows.

    References
    ----------
    Bendat, J. S. & Piersol, A. G. (2010), Random Data, 4th ed., eqs. 9.62 and 9.72 (H1 and the coherence).
    """
    tiny = np.finfo(float).tiny
    live = suu > LIVE_FLOOR * suu.max()
    H = np.where(live, suy / np.where(live, suu, 1.0), 0.0)
    den = suu * syy
    coh = np.where(live & (den > tiny), np.abs(suy) ** 2 / np.where(den > tiny, den, 1.0), 0.0)
    return H, np.clip(coh, 0.0, 1.0)


@dataclasses.dataclass(frozen=True)
class InputBand:
    """The input's band: ``lo ... hi`` (Hz), with ``excited`` of ``powered`` frequencies excited."""

    lo: float
    hi: float
    excited: int
    powered: int
    resolution: float

    def text(self) -> str:
        return (f"{self.lo:g} ... {self.hi:g} Hz (squared coherence significant at {100 * LEVEL:g} % at "
                f"{self.excited} frequencies, resolution {self.resolution:g} Hz)")


def input_band(frf: Spectrum, lo: float = 0.0, hi: float = np.inf) -> InputBand | None:
    """The input's band of a frequency response (module docstring), or None when no run of :data:`MIN_RUN`
    adjacent excited frequencies exists; only the frequencies from ``lo`` to ``hi`` Hz when given. Groups are
    ranked by their input power (``input_power``; when unknown, by their count)."""
    f = np.asarray(frf.freq, float)
    res = float(f[1] - f[0]) if len(f) > 1 else 0.0
    inside = (f >= lo) & (f <= hi)
    at = np.flatnonzero(powered(frf.input_power, frf.coherence) & inside)
    if len(at) == 0:
        return None
    s = excited(frf.input_power, frf.coherence, frf.n_averages)[at]
    weight = (np.ones(len(f)) if frf.input_power is None else np.asarray(frf.input_power, float))[at]
    runs, start = [], None          # runs of excited frequencies, as positions in `at`
    for i, v in enumerate(np.append(s, False)):
        if v and start is None:
            start = i
        elif not v and start is not None:
            if i - start >= MIN_RUN:
                runs.append([start, i - 1, i - start, float(np.sum(weight[start:i]))])
            start = None
    if not runs:
        return None
    groups = [runs[0]]
    for a, b, n, w in runs[1:]:
        if a - groups[-1][1] - 1 <= MAX_GAP:
            groups[-1] = [groups[-1][0], b, groups[-1][2] + n, groups[-1][3] + w]
        else:
            groups.append([a, b, n, w])
    a, b, n, _ = max(groups, key=lambda g: g[3])       # ties: the lowest (max keeps the first)
    return InputBand(lo=float(f[at[a]]), hi=float(f[at[b]]), excited=int(n), powered=len(at), resolution=res)


def excited_share(frf: Spectrum, lo: float, hi: float) -> tuple[int, int]:
    """``(excited, powered)``: frequencies of ``lo ... hi`` Hz (inclusive) that are excited (:func:`excited`),
    of those at which the input has power."""
    f = np.asarray(frf.freq, float)
    sel = (f >= lo) & (f <= hi)
    ex = excited(frf.input_power, frf.coherence, frf.n_averages)
    return int(np.count_nonzero(ex & sel)), int(np.count_nonzero(powered(frf.input_power, frf.coherence) & sel))


def chance(excited: int, powered: int, level: float = LEVEL) -> float:
    """Probability that ``excited`` or more of ``powered`` frequencies pass the coherence test by chance (each
    at ``1 - level`` without input: the binomial tail), i.e. how well a band's count is explained without an
    input. ``chance(0, n) == 1``."""
    p = 1.0 - level
    if excited <= 0:
        return 1.0
    if excited > powered:
        return 0.0
    logs = [math.lgamma(powered + 1) - math.lgamma(j + 1) - math.lgamma(powered - j + 1)
            + j * math.log(p) + (powered - j) * math.log1p(-p) for j in range(excited, powered + 1)]
    top = max(logs)                 # the terms summed relative to the largest (no underflow)
    return float(min(1.0, math.exp(top) * sum(math.exp(v - top) for v in logs)))
