"""The input's band: where the angle excites the joint measurably, for the estimators that fit over a band.

Private module (the leading underscore keeps it out of the estimator registry). Used by
:mod:`estimators.ibk_spectral` (the fitted band limited to it), :mod:`estimators.ibk_irf`,
:mod:`estimators.irf_ls`, :mod:`estimators.irf_corr` and :mod:`estimators.fsewls` (reported, and named in
their refusals; :func:`band_of_trials`; fsewls also its fitted band's share, :func:`excited_share`).

A frequency is *excited* when its squared coherence is significant at 95 % (the test of
:meth:`jointbench.core.estimate.FRFEstimate.significant`, Carter, Knapp & Nuttall 1973). Above the band of
a band-limited input, single frequencies pass that test by chance (5 % of them), with ``H`` there the
ratio of noise to the window's leakage (10^3 - 10^4 times the joint's impedance): one of them given the
weight of its coherence dominates a least-squares fit. The input's band is therefore the span of
*runs* of excited frequencies: runs of at least :data:`MIN_RUN` adjacent excited frequencies (three by
chance: 0.05^3, about 1 in 8000 per position), joined across gaps of at most :data:`MAX_GAP` frequencies
(a dip of the coherence inside the band), the joined group with the most excited frequencies kept.
Frequencies at which the angle has no power at all (numerically zero: between the lines of a periodic
input whose period divides the segment) are neither excited nor gaps: they are skipped.

References
----------
Westwick, D. T. & Perreault, E. J. (2012). Estimates of acausal joint impedance models. IEEE Trans.
Biomed. Eng. 59(10), doi:10.1109/TBME.2012.2213339 (the input's bandwidth and the fitted band).

Carter, G. C., Knapp, C. H. & Nuttall, A. H. (1973). Estimation of the magnitude-squared coherence
function via overlapped fast Fourier transform processing. IEEE Trans. Audio Electroacoust. 21(4).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from jointbench.core.errors import InputError
from jointbench.core.estimate import FRFEstimate
from jointbench.core.types import Trial

#: fewest adjacent excited frequencies that count as a run of the input's band
MIN_RUN = 3
#: most unexcited frequencies inside the band between two runs (a dip of the coherence)
MAX_GAP = 2
#: frequencies left out inside an edge of the input's band when it limits a fit: the half width of the
#: Hann window's main lobe (2 frequencies). There ``H`` is the leakage-weighted mean of ``H`` over the
#: excited side only, not ``H`` at the frequency (on a multisine to 12 Hz, 2 s Hann segments, keeping
#: them biased I and K of ibk_spectral by 2-3 interval half widths)
EDGE = 2


@dataclasses.dataclass(frozen=True)
class InputBand:
    """The input's band: ``lo ... hi`` (Hz), with ``excited`` of ``powered`` frequencies significant."""

    lo: float
    hi: float
    excited: int
    powered: int
    resolution: float

    def text(self) -> str:
        return (f"{self.lo:g} ... {self.hi:g} Hz (squared coherence significant at 95 % at {self.excited} "
                f"frequencies, resolution {self.resolution:g} Hz)")


def input_band(frf: FRFEstimate, lo: float = 0.0, hi: float = np.inf) -> InputBand | None:
    """The input's band of a Welch estimate (module docstring), or None when no run of :data:`MIN_RUN`
    adjacent excited frequencies exists; only the frequencies from ``lo`` to ``hi`` Hz when given."""
    f = np.asarray(frf.freq, float)
    res = float(f[1] - f[0]) if len(f) > 1 else 0.0
    inside = (f >= lo) & (f <= hi)
    f, sig, coh = f[inside], np.asarray(frf.significant(), bool)[inside], np.asarray(frf.coherence, float)[inside]
    powered = np.flatnonzero(coh > 0)
    if len(powered) == 0:
        return None
    s = sig[powered]
    runs, start = [], None          # runs of excited frequencies, as positions in `powered`
    for i, v in enumerate(np.append(s, False)):
        if v and start is None:
            start = i
        elif not v and start is not None:
            if i - start >= MIN_RUN:
                runs.append([start, i - 1, i - start])
            start = None
    if not runs:
        return None
    groups = [runs[0]]
    for a, b, n in runs[1:]:
        if a - groups[-1][1] - 1 <= MAX_GAP:
            groups[-1] = [groups[-1][0], b, groups[-1][2] + n]
        else:
            groups.append([a, b, n])
    a, b, n = max(groups, key=lambda g: g[2])       # ties: the lowest (max keeps the first)
    return InputBand(lo=float(f[powered[a]]), hi=float(f[powered[b]]), excited=int(n), powered=len(powered),
                     resolution=res)


def welch_of_trials(name: str, trials: list[Trial], segment: float = 2.0) -> FRFEstimate | None:
    """Welch estimate (angle to torque) of records from ``segment`` s segments (shorter when the records are:
    at least 8 per record), or None when it cannot be told (segments under 16 samples, no input power). The
    estimate of :mod:`estimators.spectral` without its confidence band (the band tests need the coherence and
    the number of averages only)."""
    from jointbench.estimators.spectral import WelchSettings, effective_averages, welch_frf

    fs = trials[0].fs
    seg = min(segment, min(t.n for t in trials) / fs / 8)
    if seg * fs < 16:
        return None
    s = WelchSettings(segment=seg)
    try:
        f, H, coh = welch_frf(name, trials, s)
    except InputError:
        return None
    return FRFEstimate(freq=f, H=H, coherence=coh, fs=fs, time=trials[0].time, estimator="spectral",
                       n_averages=effective_averages(trials, s))


def band_of_trials(name: str, trials: list[Trial], segment: float = 2.0) -> InputBand | None:
    """The input's band (:func:`input_band`) of records, from Welch spectra of ``segment`` s segments (shorter
    when the records are: at least 8 per record), or None when it cannot be told (segments under 16 samples)."""
    frf = welch_of_trials(name, trials, segment)
    return None if frf is None else input_band(frf)


def excited_share(frf: FRFEstimate, lo: float, hi: float) -> tuple[int, int]:
    """``(excited, powered)``: frequencies of ``lo ... hi`` Hz (inclusive) whose squared coherence is
    significant at 95 %, of those at which the angle has power."""
    f = np.asarray(frf.freq, float)
    sel = (f >= lo) & (f <= hi) & (np.asarray(frf.coherence, float) > 0)
    return int(np.count_nonzero(np.asarray(frf.significant(), bool) & sel)), int(np.count_nonzero(sel))


def chance(excited: int, powered: int, level: float = 0.95) -> float:
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
