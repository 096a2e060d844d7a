"""Protocols of Westwick & Perreault (2012), "Estimates of acausal joint impedance models".

References
----------
Westwick, D. T. & Perreault, E. J. (2012). IEEE Trans. Biomed. Eng. 59(10): 2913-2921.
Figs. 2-3 (eqs. 10-13), Fig. 4 (Sec. III-B), Fig. 5 (eq. 17), Fig. 6 (Sec. V-A), Table I and Fig. 7
(Sec. V-B), Fig. 8 (Sec. V-C).
"""
from __future__ import annotations

import dataclasses

import numpy as np
from scipy import signal as sps

from jointbench import sims
from jointbench.core.scores import vaf
from jointbench.benchmarks.protocols import Context, register
from jointbench.benchmarks.scoring import fit_gated
from jointbench.core import differentiators as d
from jointbench.core.schema import param
from jointbench.core.signal import bandlimit_fb, resample_trial


@dataclasses.dataclass(frozen=True)
class Joint:
    """A second-order joint given by its parameters (a file of ``configs/models``)."""

    model: str
    I: float = param(unit="kg.m2", gt=0)
    B: float = param(unit="N.m.s/rad", ge=0)
    K: float = param(unit="N.m/rad", gt=0)


def _joint(mapping) -> Joint:
    from jointbench.core.schema import parse

    return parse(Joint, mapping, "params.joint")


# --------------------------------------------------------------------------------------------- W1
@dataclasses.dataclass(frozen=True)
class DiffParams:
    order: int = param(1, ge=1, le=2, doc="1: differentiator (Fig. 2), 2: double differentiator (Fig. 3)")
    N: int = param(256, ge=4, doc="record length (even)")
    fs: float = param(500.0, unit="Hz", gt=0)
    zoom: int = param(10, ge=1, doc="lags either side of 0 in the lower panel")

    def __post_init__(self):
        if self.N % 2:
            raise ValueError(f"key 'N': must be even, got {self.N}")


@register("westwick2012.differentiators", DiffParams)
def differentiators(ctx: Context) -> None:
    """W1: closed forms (eqs. 12-13) against the inverse DFT of jw and -w^2, and their symmetry."""
    p = ctx.params
    closed = d.h1(p.N, p.fs) if p.order == 1 else d.h2(p.N, p.fs)
    ref = d.idft_derivative(p.N, p.fs, p.order)
    scale = (2 * np.pi * p.fs / p.N) ** p.order
    ctx.metric("idft_max_rel_err", np.max(np.abs(closed - ref)) / np.max(np.abs(ref)))
    lags, two = d.two_sided(closed, p.N // 2 - 1, p.N // 2 - 1)
    sign = -1.0 if p.order == 1 else 1.0       # h1 odd, h2 even
    ctx.metric("symmetry_max_rel_err", np.max(np.abs(two - sign * two[::-1])) / np.max(np.abs(two)))
    if p.order == 2:
        printed = d.h2_as_printed(p.N, p.fs)[0]
        ctx.metric("printed_h2_zero_lag_rel_err", abs(printed - ref[0]) / abs(ref[0]))
    n = np.arange(p.N)
    ctx.curve("periodic", n, closed / scale, series="closed form")
    ctx.curve("periodic", n, ref / scale, series="inverse DFT")
    zl, zv = d.two_sided(closed, p.zoom, p.zoom)
    ctx.curve("two_sided", zl, zv / scale, series="closed form")


# --------------------------------------------------------------------------------------------- W2
@dataclasses.dataclass(frozen=True)
class SamplingParams:
    joint: dict
    fs: tuple[float, ...] = param((500.0, 250.0, 100.0, 50.0), unit="Hz", gt=0)
    N: int = param(1024, ge=4, doc="record length of the discrete differentiators")
    zoom: int = param(10, ge=1, doc="lags shown and scored either side of 0")


@register("westwick2012.sampling_rate", SamplingParams)
def sampling_rate(ctx: Context) -> None:
    """W2: impedance IRFs of the ankle at several sampling rates, normalised by fs^2 (Fig. 4)."""
    p = ctx.params
    j = _joint(p.joint)
    ctx.metric("omega_n_rad_s", np.sqrt(j.K / j.I))
    ctx.metric("zeta", j.B / (2 * np.sqrt(j.K * j.I)))
    diffs = []
    for fs in p.fs:
        lags, h = d.two_sided(d.impedance_irf(j.I, j.B, j.K, fs, p.N), p.zoom, p.zoom)
        terms = [d.two_sided(c * g, p.zoom, p.zoom)[1] for c, g in
                 ((j.I, d.h2(p.N, fs)), (j.B, d.h1(p.N, fs)), (j.K, d.h0(p.N)))]
        energy = [np.sum(t ** 2) for t in terms]
        odd = 0.5 * (h - h[::-1])
        plus, minus = h[lags == 1][0], h[lags == -1][0]
        rel = abs(plus - minus) / (0.5 * (plus + minus))
        diffs.append(rel)
        ctx.metric("inertial_energy_share", energy[0] / sum(energy), fs_hz=fs)
        ctx.metric("odd_energy_share", np.sum(odd ** 2) / np.sum(h ** 2), fs_hz=fs)
        ctx.metric("peak_rel_difference", rel, fs_hz=fs)
        ctx.curve("irf_over_fs2", lags, h / fs ** 2, series=f"{fs:g} Hz", fs_hz=fs)
    order = np.argsort(p.fs)[::-1]                                   # falling sampling rate
    ctx.metric("peak_difference_grows_as_fs_falls", float(np.all(np.diff(np.asarray(diffs)[order]) > 0)))


# --------------------------------------------------------------------------------------------- W3
@dataclasses.dataclass(frozen=True)
class BandlimitParams:
    joint: dict
    fs: float = param(200.0, unit="Hz", gt=0)
    cutoff: float = param(5.0, unit="Hz", gt=0, doc="input low-pass cutoff")
    order: int = param(2, ge=1, doc="input low-pass order (Butterworth, analog prototype)")
    snr_db: tuple[float, ...] = param((60.0, 50.0, 40.0, 30.0), unit="dB")
    N: int = param(4096, ge=64, doc="DFT length of the eq. 17 filter")
    window: float = param(0.25, unit="s", gt=0, doc="lags either side of 0 scored and shown")
    visible: float = param(1.0, gt=0, doc="a deviation counts as visible above this percent of the peak")
    rule_snr_db: float = param(40.0, unit="dB", doc="SNR of the rule of thumb of Sec. III-D")


def rule_of_thumb_decades(cutoff: float, order: int, snr_db: float, fs: float | None = None) -> float:
    """Decades above ``cutoff`` at which the eq. 17 gain (the squared coherence) of a low-passed white-noise
    angle with white measurement noise falls to 1/2 (signal and noise spectra equal).

    ``fs=None``: the SNR refers to the pass-band density of the input (the reading under which Sec. III-D's
    arithmetic works: 40 dB against -40 dB/decade is one decade). With ``fs``: the SNR refers to the
    variance over 0 ... fs/2, as in Fig. 5 (reading R4); the crossing then depends on fs and may lie beyond
    Nyquist (the value is still the analytic crossing of the two spectra).

    References
    ----------
    Westwick & Perreault (2012), Sec. III-D (rule of thumb) and eq. 17.
    """
    density = 10 ** (-snr_db / 10)
    if fs is not None:   # mean of 1/(1 + (f/fc)^(2 order)) over 0 ... fs/2, on a fine grid
        f = np.linspace(0, fs / 2, 200001)
        density *= float(np.mean(1.0 / (1.0 + (f / cutoff) ** (2 * order))))
    return float(np.log10((1.0 / density - 1.0) ** (1.0 / (2 * order))))


def bandlimited_irf(j: Joint, fs: float, N: int, cutoff: float, order: int, snr_db: float) -> np.ndarray:
    """Expected impedance IRF after eq. 17: H(w_k) times the squared coherence of a low-passed
    white-noise angle with white measurement noise at ``snr_db`` (infinite: no noise)."""
    H = np.fft.fft(d.impedance_irf(j.I, j.B, j.K, fs, N))
    f = np.abs(np.fft.fftfreq(N, 1 / fs))
    s_th = 1.0 / (1.0 + (f / cutoff) ** (2 * order))       # analog Butterworth magnitude squared
    s_nn = np.mean(s_th) / 10 ** (snr_db / 10) if np.isfinite(snr_db) else 0.0
    return np.fft.ifft(H * s_th / (s_th + s_nn)).real


@register("westwick2012.input_bandlimit", BandlimitParams)
def input_bandlimit(ctx: Context) -> None:
    """W3: distortion and spread of the impedance IRF from input bandwidth and noise (Fig. 5)."""
    p = ctx.params
    j = _joint(p.joint)
    ctx.metric("omega_n_rad_s", np.sqrt(j.K / j.I))                 # Fig. 5 caption: 18.6 rad/s
    ctx.metric("zeta", j.B / (2 * np.sqrt(j.K * j.I)))               # Fig. 5 caption: 0.24
    ctx.metric("rule_of_thumb_decades", rule_of_thumb_decades(p.cutoff, p.order, p.rule_snr_db))
    ctx.metric("rule_of_thumb_decades_variance_snr", rule_of_thumb_decades(p.cutoff, p.order, p.rule_snr_db, p.fs))
    m = int(round(p.window * p.fs))
    ideal = d.two_sided(bandlimited_irf(j, p.fs, p.N, p.cutoff, p.order, np.inf), m, m)[1]
    lags = np.arange(-m, m + 1)
    t = lags / p.fs

    def duration(h):
        """Width (ms) of the IRF's central lobe between the zero crossings either side of lag 0."""
        c = m + int(np.argmax(np.abs(h[m - 1:m + 2]))) - 1
        sign = np.sign(h[c])
        right = c + int(np.argmax(np.sign(h[c:]) != sign))
        left = c - int(np.argmax(np.sign(h[c::-1]) != sign))
        # linear interpolation of the two crossings
        tr = t[right - 1] + (t[right] - t[right - 1]) * h[right - 1] / (h[right - 1] - h[right])
        tl = t[left + 1] - (t[left + 1] - t[left]) * h[left + 1] / (h[left + 1] - h[left])
        return 1e3 * (tr - tl)

    ctx.metric("central_lobe_ms", duration(ideal), snr_db=np.inf)
    ctx.curve("irf", t, ideal, series="no noise", snr_db=np.inf)
    durations = []
    for snr in p.snr_db:
        h = d.two_sided(bandlimited_irf(j, p.fs, p.N, p.cutoff, p.order, snr), m, m)[1]
        dev = 100 * np.max(np.abs(h - ideal)) / np.max(np.abs(ideal))
        ctx.metric("max_deviation_pct_of_peak", dev, snr_db=snr)
        ctx.metric("distortion_visible", float(dev > p.visible), snr_db=snr)
        ctx.metric("distortion_energy_pct", 100 * np.sum((h - ideal) ** 2) / np.sum(ideal ** 2), snr_db=snr)
        durations.append(duration(h))
        ctx.metric("central_lobe_ms", durations[-1], snr_db=snr)
        ctx.curve("irf", t, h, series=f"{snr:g} dB", snr_db=snr)
    order = np.argsort(p.snr_db)[::-1]                                # falling SNR
    ctx.metric("spreads_as_snr_falls", float(np.all(np.diff(np.asarray(durations)[order]) > 0)))


# --------------------------------------------------------------------------------------- W5 (Table I)
@dataclasses.dataclass(frozen=True)
class TableParams:
    fs: tuple[float, ...] = param((500.0, 250.0, 100.0, 50.0), unit="Hz", gt=0)
    bandlimit: float = param(20.0, unit="Hz", gt=0, doc="IRFs band-limited to this frequency")
    bandlimit_order: int = param(8, ge=1)
    nonparametric: str = param("irf2_ls", doc="estimator of the nonparametric IRF")
    parametric: str = param("ibk_irf", doc="estimator of I, B, K (fitted at the highest rate)")


@register("westwick2012.sampling_rate_experiment", TableParams)
def sampling_rate_experiment(ctx: Context) -> None:
    """W5: parametric vs nonparametric band-limited IRFs at several sampling rates (Table I, Fig. 7).

    The nonparametric IRF is estimated at each rate from the same simulated trial resampled; one set
    of I, B, K is fitted at the highest rate and turned into an IRF at every rate (eqs. 10, 12, 13);
    both are band-limited by the same zero-phase Butterworth and compared by %VAF over the lag window.
    Per trial, the rates' %VAF are also compared with each other (:func:`rate_invariance`: Sec. V-D,
    'virtually unchanged for sampling frequencies as low as 1.25 times the Nyquist rate').
    """
    p = ctx.params
    for key in (p.nonparametric, p.parametric):
        if key not in ctx.estimators:
            raise KeyError(f"estimator {key!r} must be listed in the part's estimators")
    trial = sims.simulate(ctx.experiment, ctx.seed)
    top = max(p.fs)
    if trial.fs != top:
        trial = resample_trial(trial, top)
    fit = fit_gated(ctx.estimators[p.parametric], trial)
    I, B, K = (float(np.mean(v)) for v in (fit.I, fit.B, fit.K))
    for name, v in (("I", I), ("B", B), ("K", K)):
        ctx.metric(name, v, p.parametric)
    top_irf, vafs = None, {}
    for fs in sorted(p.fs, reverse=True):
        tr = resample_trial(trial, fs)
        irf = fit_gated(ctx.estimators[p.nonparametric], tr)
        m1, m2 = -int(irf.lags[0]), int(irf.lags[-1])
        h_np = bandlimit_fb(irf.h, fs, p.bandlimit, p.bandlimit_order)
        n = tr.n + tr.n % 2
        h_p = bandlimit_fb(d.two_sided(d.impedance_irf(I, B, K, fs, n), m1, m2)[1], fs, p.bandlimit,
                           p.bandlimit_order)
        vafs[fs] = vaf(h_np, h_p)
        ctx.metric("vaf_parametric_irf", vafs[fs], p.parametric, fs_hz=fs)
        if top_irf is None:
            top_irf = (irf.lags, h_np, fs)
        ctx.metric("shape_diff_pct", shape_difference(top_irf, (irf.lags, h_np, fs)), p.nonparametric, fs_hz=fs)
        ctx.curve("irf_over_fs2", irf.lags, h_np / fs ** 2, series="nonparametric", fs_hz=fs)
        ctx.curve("irf_over_fs2", irf.lags, h_p / fs ** 2, series="parametric", fs_hz=fs)
    for name, v in rate_invariance(vafs, p.bandlimit).items():
        ctx.metric(name, v, p.parametric)


def rate_invariance(vafs: dict[float, float], bandlimit: float) -> dict[str, float]:
    """How much the parametric-fit %VAF of one trial changes with the sampling rate (Table I's rows).

    Parameters
    ----------
    vafs : dict
        Sampling rate (Hz) -> %VAF of the parametric against the nonparametric band-limited IRF.
    bandlimit : float
        The IRFs' band limit (Hz), whose Nyquist rate is ``2 bandlimit``.

    Returns
    -------
    dict
        ``vaf_parametric_irf_range``: largest minus smallest %VAF over the rates (points);
        ``residual_ratio_lowest_rate``: unexplained variance (100 - %VAF) at the lowest rate over that at
        the highest; ``lowest_rate_over_nyquist``: the lowest rate over the band's Nyquist rate (1.25 for
        50 Hz and a 20 Hz band).

    References
    ----------
    Westwick & Perreault (2012), Sec. V-D ('virtually unchanged for sampling frequencies as low as 1.25
    times the Nyquist rate (see Table I)'), Table I.
    """
    v = np.asarray(list(vafs.values()), float)
    lo, hi = min(vafs), max(vafs)
    return {"vaf_parametric_irf_range": float(v.max() - v.min()),
            "residual_ratio_lowest_rate": float((100.0 - vafs[lo]) / (100.0 - vafs[hi])),
            "lowest_rate_over_nyquist": float(lo / (2.0 * bandlimit))}


def shape_difference(ref: tuple, other: tuple) -> float:
    """Shape difference (%) of two band-limited IRFs at different rates: ``100 (1 - c^2)`` with ``c`` the
    cosine similarity of the two at the lag times they share (``ref``'s rate a whole multiple of
    ``other``'s). Scale-free, so the normalisation by the rate (``h / fs^2`` in Figs. 4 and 7) drops out.

    References
    ----------
    Westwick & Perreault (2012), Sec. V-B, Fig. 7 ('significant differences in the IRF shape are only
    evident at the lowest sampling rate').
    """
    (lr, hr, fr), (lo, ho, fo) = ref, other
    q = fr / fo
    if abs(q - round(q)) > 1e-9:
        raise ValueError(f"shape difference: {fr:g} Hz is not a whole multiple of {fo:g} Hz")
    idx = {int(v): k for k, v in enumerate(np.asarray(lr))}
    pairs = [(idx[int(round(v * q))], k) for k, v in enumerate(np.asarray(lo)) if int(round(v * q)) in idx]
    a = np.asarray([hr[i] for i, _ in pairs])
    b = np.asarray([ho[k] for _, k in pairs])
    c = float(a @ b) / float(np.linalg.norm(a) * np.linalg.norm(b))
    return 100.0 * (1.0 - c * c)


# --------------------------------------------------------------------------------------- W6 (Fig. 8)
@dataclasses.dataclass(frozen=True)
class NoiseParams:
    snr_db: float = param(25.0, unit="dB", doc="white noise added to the measured angle")
    segment: float = param(2.0, unit="s", gt=0, doc="Welch segment for the coherences")
    fall_db: float = param(3.0, gt=0, doc="'falls away': the noisy estimate this far below the original")
    beyond: float = param(1.25, ge=1, doc="prediction scored up to this multiple of the fall-away frequency")
    fmin: float = param(1.0, unit="Hz", ge=0, doc="lowest frequency scored")
    fmax_plot: float = param(100.0, unit="Hz", gt=0, doc="highest frequency shown")
    low_coherence: float = param(0.5, gt=0, lt=1, doc="'low coherence': the original squared coherence below this")
    estimator: str = param("irf2_ls")


@register("westwick2012.input_noise", NoiseParams)
def input_noise(ctx: Context) -> None:
    """W6: effect of 25 dB angle noise on the estimated impedance, predicted by eq. 17 (Fig. 8).

    As in the paper, the prediction is the original estimate times the ratio of the squared
    coherences after and before adding the noise (the experimental data were not noise free). The
    simulation also allows eq. 17 itself: the true impedance times the squared coherence between the
    noisy angle and the noise-free torque.
    """
    p = ctx.params
    trial = sims.simulate(ctx.experiment, ctx.seed)
    noise_sd = np.std(trial.angle) / 10 ** (p.snr_db / 20)
    noisy = trial.replace(angle=trial.angle + ctx.rng.normal(0.0, noise_sd, trial.n), name="noisy")
    est = ctx.estimators[p.estimator]
    h0, h1 = fit_gated(est, trial), fit_gated(est, noisy)
    nper = int(round(p.segment * trial.fs))
    f, c0 = sps.coherence(trial.angle, trial.torque, trial.fs, nperseg=nper)
    _, c1 = sps.coherence(noisy.angle, trial.torque, trial.fs, nperseg=nper)
    H0, H1 = h0.frequency_response(f), h1.frequency_response(f)
    pred = H0 * c1 / np.maximum(c0, 1e-12)
    tr = trial.truth
    w = 2 * np.pi * f
    ideal = tr.K + 1j * w * tr.B - tr.I * w ** 2
    _, ct = sps.coherence(noisy.angle, tr.signals["torque"], trial.fs, nperseg=nper)
    eq17 = ideal * ct
    ratio_db = 20 * np.log10(np.abs(H1) / np.abs(H0))
    band = f >= max(p.fmin, f[1])
    below = np.flatnonzero(band & (ratio_db < -p.fall_db))
    if len(below) == 0:
        raise RuntimeError(f"the noisy estimate never falls {p.fall_db} dB below the original up to "
                           f"{f[-1]:g} Hz")
    f_fall = f[below[0]]
    scored = band & (f <= p.beyond * f_fall)
    err = 20 * np.log10(np.abs(pred[scored]) / np.abs(H1[scored]))
    err17 = 20 * np.log10(np.abs(eq17[scored]) / np.abs(H1[scored]))
    ctx.metric("fall_away_hz", f_fall)
    ctx.metric("prediction_rms_err_db", np.sqrt(np.mean(err ** 2)))
    ctx.metric("prediction_max_err_db", np.max(np.abs(err)))
    ctx.metric("eq17_truth_rms_err_db", np.sqrt(np.mean(err17 ** 2)))
    low = (f > 0) & (c0 < p.low_coherence)     # where the original coherence is low (up to Nyquist)
    if low.any():
        errl = 20 * np.log10(np.abs(pred[low]) / np.abs(H1[low]))
        ctx.metric("prediction_rms_err_db_low_coherence", np.sqrt(np.mean(errl ** 2)))
        ctx.metric("low_coherence_from_hz", float(f[low][0]))
    show = (f > 0) & (f <= p.fmax_plot)
    for series, v in (("original", H0), ("with noise", H1), ("eq. 17 prediction", pred),
                      ("eq. 17 with true impedance", eq17), ("true impedance", ideal)):
        ctx.curve("magnitude", f[show], np.abs(v[show]), series=series)
    ctx.curve("coherence2", f[show], c0[show], series="before")
    ctx.curve("coherence2", f[show], c1[show], series="after")
