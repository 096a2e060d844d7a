"""The input's band of records, for the estimators that fit over a band: their Welch estimate, read by the
one definition of an excited frequency and of the input's band (:mod:`jointbench.core.band`).

Private module (the leading underscore keeps it out of the estimator registry). Used by
:mod:`estimators.ibk_spectral` (the fitted band limited to it), :mod:`estimators.ibk_irf`,
:mod:`estimators.irf_ls`, :mod:`estimators.irf_corr` and :mod:`estimators.fsewls` (reported, and named in
their refusals; :func:`band_of_trials`).

References
----------
Westwick, D. T. & Perreault, E. J. (2012). Estimates of acausal joint impedance models. IEEE Trans.
Biomed. Eng. 59(10), doi:10.1109/TBME.2012.2213339 (the input's bandwidth and the fitted band).
"""
from __future__ import annotations


from jointbench.core.band import InputBand, input_band
from jointbench.core.errors import InputError
from jointbench.core.estimate import FRFEstimate
from jointbench.core.types import Trial

#: frequencies left out inside an edge of the input's band when it limits a fit: the half width of the
#: Hann window's main lobe (2 frequencies). There ``H`` is the leakage-weighted mean of ``H`` over the
#: excited side only, not ``H`` at the frequency (on a multisine to 12 Hz, 2 s Hann segments, keeping
#: them biased I and K of ibk_spectral by 2-3 interval half widths)
EDGE = 2


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
        f, H, coh, suu = welch_frf(name, trials, s)
    except InputError:
        return None
    return FRFEstimate(freq=f, H=H, coherence=coh, fs=fs, time=trials[0].time, estimator="spectral",
                       n_averages=effective_averages(trials, s), input_power=suu)


def band_of_trials(name: str, trials: list[Trial], segment: float = 2.0) -> InputBand | None:
    """The input's band (:func:`input_band`) of records, from Welch spectra of ``segment`` s segments (shorter
    when the records are: at least 8 per record), or None when it cannot be told (segments under 16 samples)."""
    frf = welch_of_trials(name, trials, segment)
    return None if frf is None else input_band(frf)
