"""Signal-processing steps shared by the simulators, the estimators and the harness."""
from __future__ import annotations

import numpy as np
from jointbench.core.lazy import scipy_signal as sps   # imported on first use: 0.6 CPU-s with scipy.stats

import dataclasses
import functools
from typing import Callable, Literal

from jointbench.core import differentiators
from jointbench.core.errors import InputError
from jointbench.core.types import Trial, Truth

#: the anti-alias filter of :func:`decimate`: JointBench's linear-phase FIR, or the zero-phase Chebyshev IIR of
#: MATLAB's and Octave's ``decimate`` (which the REKLAB toolbox's ``PC_stiffnessID`` uses)
DecimationFilter = Literal["fir", "chebyshev"]
DECIMATION_FILTERS: tuple[str, ...] = ("fir", "chebyshev")
#: the channel :func:`resample_trial` adds to a decimated trial: the angle's velocity (rad/s), taken by
#: :func:`jointbench.core.differentiators.central` at the rate the trial had before decimation, then decimated
#: with the angle (read by :func:`velocity`)
VELOCITY = "velocity_before_decimation"
#: where an estimator that differentiates the angle takes the derivative (its ``differentiate`` setting)
Differentiate = Literal["before_decimation", "after_decimation"]


def _map_truth(truth: Truth | None, on_signal: Callable[[np.ndarray], np.ndarray],
               on_param: Callable[[np.ndarray], np.ndarray]) -> Truth | None:
    """Apply ``on_signal`` to the truth's signals and ``on_param`` to its time-varying parameters."""
    if not isinstance(truth, Truth):        # none, or hidden while an estimator fits (stays hidden)
        return truth
    par = {k: (v if np.ndim(v) < (2 if k in ("num", "den") else 1) else on_param(np.asarray(v)))
           for k, v in (("I", truth.I), ("B", truth.B), ("K", truth.K), ("num", truth.num),
                        ("den", truth.den)) if v is not None}
    return dataclasses.replace(truth, signals={k: on_signal(v) for k, v in truth.signals.items()}, **par)


def decimate(x: np.ndarray, q: int, cutoff: float = 0.8, filter: DecimationFilter = "fir") -> np.ndarray:
    """Zero-phase anti-alias filter and keep every ``q``-th sample (the first kept), along axis 0.

    Parameters
    ----------
    x : ndarray
        Signal, or signals as columns.
    q : int
        Decimation factor (1 returns a copy).
    cutoff : float
        Pass band edge as a fraction of the new Nyquist frequency.
    filter : {'fir', 'chebyshev'}
        'fir': a linear-phase FIR of ``20 q + 1`` taps (Hamming window), applied by
        :func:`scipy.signal.resample_poly`: -6 dB at ``cutoff``, -0.7 dB at 0.875 ``cutoff`` (at q = 10,
        ``cutoff`` = 0.8: 40 and 35 Hz of a 1 kHz record), -52 dB at the new Nyquist frequency. 'chebyshev':
        the filter of MATLAB's and Octave's ``decimate``, an 8th-order Chebyshev type I low-pass with 0.05 dB
        of ripple up to ``cutoff``, run forward and backward (:func:`scipy.signal.sosfiltfilt`, second-order
        sections): within 0.1 dB up to ``cutoff``, -46 dB at the new Nyquist frequency (q = 10).

    References
    ----------
    The MathWorks, Signal Processing Toolbox, ``decimate`` (default IIR filter); GNU Octave signal package
    1.4.3, ``decimate.m`` (``cheby1(8, 0.05, 0.8/q)``, ``filtfilt``).
    """
    if q < 1 or int(q) != q:
        raise InputError(f"decimation factor must be a whole number >= 1, got {q}")
    if filter not in DECIMATION_FILTERS:
        raise InputError(f"decimation filter must be one of {', '.join(DECIMATION_FILTERS)}, got {filter!r}")
    x = np.asarray(x, float)
    if q == 1:
        return x.copy()
    if filter == "chebyshev":
        sos = _chebyshev(int(q), float(cutoff)).copy()        # scipy's sosfilt takes a writable array only
        return np.ascontiguousarray(sps.sosfiltfilt(sos, x, axis=0)[::q])
    if x.ndim == 2:   # signals as rows of a contiguous copy: the same numbers (and layout), faster than axis 0
        y = sps.resample_poly(np.ascontiguousarray(x.T), 1, q, window=_taps(int(q), float(cutoff)), padtype="line",
                              axis=-1)
        return np.ascontiguousarray(y.T)
    return sps.resample_poly(x, 1, q, window=_taps(int(q), float(cutoff)), padtype="line")


@functools.lru_cache(maxsize=32)
def _taps(q: int, cutoff: float) -> np.ndarray:
    """The anti-alias FIR of :func:`decimate`, designed once per factor and cutoff (read-only)."""
    taps = sps.firwin(20 * q + 1, cutoff / q)
    taps.flags.writeable = False
    return taps


@functools.lru_cache(maxsize=32)
def _chebyshev(q: int, cutoff: float) -> np.ndarray:
    """The anti-alias IIR of :func:`decimate` (``filter='chebyshev'``), second-order sections (read-only)."""
    sos = sps.cheby1(8, 0.05, cutoff / q, output="sos")
    sos.flags.writeable = False
    return sos


def resample_trial(trial: Trial, fs_new: float, cutoff: float = 0.8, filter: DecimationFilter = "fir") -> Trial:
    """Decimate a trial to ``fs_new`` (an integer divisor of its rate) with :func:`decimate`; truth signals and
    channels follow. The decimated trial carries the angle's velocity taken before decimation, at the trial's
    rate, as the channel :data:`VELOCITY` (kept from an earlier decimation: the recorded rate's)."""
    q = trial.fs / fs_new
    if abs(q - round(q)) > 1e-9 or round(q) < 1:
        raise InputError(f"trial '{trial.name}': can only decimate {trial.fs:g} Hz by a whole factor; "
                         f"{fs_new:g} Hz is not {trial.fs:g}/q")
    q = int(round(q))
    if q == 1:
        return trial
    # signals are filtered like the measurements; time-varying parameters are sampled
    def dec(v):
        return decimate(v, q, cutoff, filter)

    truth = _map_truth(trial.truth, dec, lambda v: v[::q])
    a = dec(trial.angle)
    channels = dict(trial.channels)
    channels.setdefault(VELOCITY, differentiators.central(trial.angle, trial.fs))
    return Trial(time=trial.time[0] + np.arange(len(a)) / fs_new, angle=a, torque=dec(trial.torque), fs=fs_new,
                 imposed=trial.imposed, truth=truth, name=trial.name, channels={k: dec(v) for k, v in channels.items()})


def velocity(trial: Trial, where: Differentiate = "before_decimation") -> np.ndarray:
    """The velocity (rad/s) of ``trial``'s angle, for an estimator that differentiates it: 'before_decimation',
    the channel :data:`VELOCITY` when the trial has it (it was decimated by :func:`resample_trial`: the
    derivative at the recorded rate, then decimated), otherwise, and for 'after_decimation', central
    differences at the trial's rate (:func:`jointbench.core.differentiators.central`)."""
    if where == "before_decimation" and VELOCITY in trial.channels:
        return np.asarray(trial.channels[VELOCITY], float)
    return differentiators.central(trial.angle, trial.fs)


def trim(trial: Trial, start_s: float, end_s: float) -> Trial:
    """Drop ``start_s`` seconds at the start and ``end_s`` at the end (filter transients)."""
    i0 = int(round(start_s * trial.fs))
    i1 = trial.n - int(round(end_s * trial.fs))
    if i1 - i0 < 2:
        raise InputError(f"trial '{trial.name}': trimming {start_s} s + {end_s} s leaves no data "
                         f"of a {trial.duration:g} s record")
    sl = slice(i0, i1)
    truth = _map_truth(trial.truth, lambda v: v[sl], lambda v: v[sl])
    return Trial(time=trial.time[sl], angle=trial.angle[sl], torque=trial.torque[sl], fs=trial.fs,
                 imposed=trial.imposed, truth=truth, name=trial.name)


def bandlimit_fb(h: np.ndarray, fs: float, cutoff_hz: float, order: int = 8,
                 pad: int | None = None) -> np.ndarray:
    """Butterworth low-pass applied forward and backward to a finite sequence (zero phase).

    The sequence is taken as zero outside its window: it is zero-padded by ``pad`` samples on each
    side (default: enough for the filter's impulse response to decay), filtered forward, reversed,
    filtered again, and cut back to its window. Used to band-limit IRFs (Westwick & Perreault 2012,
    Sec. V-B: "eighth-order Butterworth ... applied twice, once in each direction").
    """
    if not 0 < cutoff_hz < fs / 2:
        raise InputError(f"band-limit cutoff must lie in (0, {fs / 2:g}) Hz at fs = {fs:g} Hz, "
                         f"got {cutoff_hz:g} Hz")
    sos = sps.butter(order, cutoff_hz, fs=fs, output="sos")
    if pad is None:
        pad = max(64, int(20 * fs / cutoff_hz))
    x = np.concatenate([np.zeros(pad), np.asarray(h, float), np.zeros(pad)])
    y = sps.sosfilt(sos, sps.sosfilt(sos, x)[::-1])[::-1]
    return y[pad:pad + len(h)]


def decimate_fft(x: np.ndarray, n_out: int) -> np.ndarray:
    """Decimate in the frequency domain: keep the DFT bins below the new Nyquist frequency.

    The record (length N, along axis 0) is treated as one period: its DFT is cut to the bins
    ``|k| < n_out / 2`` and inverted on ``n_out`` points, so the new rate is ``fs * n_out / N`` and
    the record length in seconds is unchanged. Frequencies on the DFT grid below the new Nyquist rate
    pass unchanged (no filter ripple or phase); the price is that the record's ends are joined, so a
    record that does not start and end at rest must have its ends discarded afterwards.

    Parameters
    ----------
    x : ndarray
        Signal(s), time along axis 0.
    n_out : int
        Number of output samples (< N).

    References
    ----------
    van de Ruit et al. 2018, Sec. IV-E ("decimated in the frequency domain to about 44 Hz").
    """
    x = np.asarray(x, float)
    n = x.shape[0]
    if int(n_out) != n_out or not 2 <= n_out <= n:
        raise InputError(f"frequency-domain decimation: output length must be a whole number in "
                         f"[2, {n}], got {n_out}")
    n_out = int(n_out)
    if n_out == n:
        return x.copy()
    X = np.fft.rfft(x, axis=0)
    keep = n_out // 2 + 1
    Y = X[:keep].copy()
    if n_out % 2 == 0:
        Y[-1] = Y[-1].real  # the new Nyquist bin of a real signal: keep its real part only (symmetric)
    return np.fft.irfft(Y, n_out, axis=0) * (n_out / n)


@dataclasses.dataclass(frozen=True)
class Gate:
    """Where a perturbation is on in a record that starts and/or ends quiet (see :func:`find_gate`).

    Attributes
    ----------
    on, off : int
        First sample of the perturbation and the sample after its last one.
    period : int or None
        Samples per period when the perturbation repeats (a periodic multisine), else None.
    start, stop : int
        The longest span of whole periods inside ``on ... off`` (centred), or ``on, off`` without a period.
    """

    on: int
    off: int
    period: int | None
    start: int
    stop: int

    @property
    def periods(self) -> int:
        return 0 if not self.period else (self.stop - self.start) // self.period


def find_gate(x: np.ndarray, fs: float, window_s: float = 0.25, quiet_ratio: float = 0.1) -> Gate | None:
    """The part of a record where the perturbation is on, when the record starts or ends without it.

    The moving standard deviation over ``window_s`` seconds marks the perturbed samples (above 0.2 of
    its 90th percentile); the record is *gated* when a part of at least two windows at the start or the
    end is quiet: its standard deviation below ``quiet_ratio`` times that of the perturbed part. The
    onset and offset are then refined to the samples leaving the quiet level by more than five times
    its noise. A repeating perturbation (autocorrelation above 0.9 at a lag past its first zero
    crossing) gets its period and the centred span of whole periods (when the perturbation lasts
    whole periods only, the start near the detected onset whose window puts the least power off the
    harmonics of the period: filtering blurs the onset).

    Returns
    -------
    Gate or None
        None when the perturbation runs through the whole record (or there is none).

    References
    ----------
    van de Ruit et al. (2018), Sec. IV-C: the multisine is off for the first and last 5 s of each trial.
    """
    x = np.asarray(x, float)
    n = len(x)
    w = max(4, int(round(window_s * fs)))
    if n < 8 * w:
        return None
    perturbed = _perturbed_span(x, w, quiet_ratio)
    if perturbed is None:
        return None
    a, b, sb = perturbed
    head, tail = x[:max(a, 0)], x[min(b, n):]
    on = _edge(x, head, sb, max(0, a - w), min(n, a + 2 * w), True) if len(head) >= 2 * w else 0
    off = _edge(x, tail, sb, max(0, b - 2 * w), min(n, b + w), False) if len(tail) >= 2 * w else n
    period = _period(x[on:off] - np.mean(x[on:off]))
    gate = _whole_periods(x, on, off, period, w) if period else None
    return Gate(on=on, off=off, period=None, start=on, stop=off) if gate is None else gate


def _moving_sd(x: np.ndarray, w: int) -> np.ndarray:
    """The standard deviation of every window of ``w`` samples (window ``k``: samples ``k ... k + w - 1``)."""
    c1 = np.concatenate([[0.0], np.cumsum(x - np.median(x))])
    c2 = np.concatenate([[0.0], np.cumsum((x - np.median(x)) ** 2)])
    m = (c1[w:] - c1[:-w]) / w
    return np.sqrt(np.maximum((c2[w:] - c2[:-w]) / w - m * m, 0.0))


def _perturbed_span(x: np.ndarray, w: int, quiet_ratio: float) -> tuple[int, int, float] | None:
    """The perturbed samples ``a ... b - 1`` (windows whose standard deviation is above 0.2 of its 90th
    percentile) and their standard deviation, when a part of at least two windows before or after them is quiet
    (standard deviation below ``quiet_ratio`` times theirs) and every such part is; else None."""
    sd = _moving_sd(x, w)
    level = np.percentile(sd, 90)
    if not level > 0:
        return None
    active = np.flatnonzero(sd > 0.2 * level)
    if active.size == 0:
        return None
    a, b = int(active[0]), int(active[-1]) + w           # perturbed samples within a ... b
    head, tail = x[:max(a, 0)], x[min(b, len(x)):]
    body = x[a:b]
    quiet = [p for p in (head, tail) if len(p) >= 2 * w]
    if not quiet or len(body) < 4 * w:
        return None
    sb = float(np.std(body))
    if any(float(np.std(p)) > quiet_ratio * sb for p in quiet):
        return None
    return a, b, sb


def _edge(x: np.ndarray, quiet: np.ndarray, sb: float, lo: int, hi: int, forward: bool) -> int:
    """The first sample of ``x[lo:hi]`` leaving the level of the ``quiet`` part by more than five times its noise
    (at least 1e-6 of the perturbation's standard deviation ``sb``), ``forward``; else the sample after the last
    one. ``lo`` (``hi``) when none does."""
    base, noise = float(np.median(quiet)), float(np.std(quiet))
    thr = max(5.0 * noise, 1e-6 * sb)
    out = np.flatnonzero(np.abs(x[lo:hi] - base) > thr)
    if out.size == 0:
        return lo if forward else hi
    return lo + int(out[0]) if forward else lo + int(out[-1]) + 1


def _period(span: np.ndarray) -> int | None:
    """The period (samples) of a repeating ``span`` (mean removed): the peak of the first lobe of its
    autocorrelation (unbiased) above 0.9 past its first zero crossing, within half the span; else None."""
    L = len(span)
    nfft = 1 << int(np.ceil(np.log2(2 * L)))
    S = np.fft.rfft(span, nfft)
    r = np.fft.irfft(np.abs(S) ** 2, nfft)[:L]
    lag = np.arange(L)
    norm = r / np.maximum(r[0], 1e-300) * L / np.maximum(L - lag, 1)
    neg = np.flatnonzero(norm[1:L // 2] < 0)
    if not neg.size:
        return None
    k0 = int(neg[0]) + 1
    hits = np.flatnonzero(norm[k0:L // 2 + 1] > 0.9)
    if not hits.size:
        return None
    stop = k0 + int(hits[0])
    while stop + 1 < len(norm) and norm[stop + 1] >= norm[stop]:
        stop += 1
    return int(stop)


def _whole_periods(x: np.ndarray, on: int, off: int, period: int, w: int) -> Gate | None:
    """The gate of the longest span of whole periods inside ``on ... off`` (centred; within 2 % of a period),
    None when not one fits. When the perturbation lasts (about) whole periods only, the start near the onset
    whose span leaks least power off the harmonics of the period (:func:`_least_leaking_start`)."""
    n = len(x)
    whole = int((off - on + 0.02 * period) // period)
    if whole < 1:
        return None
    span_n = whole * period
    start = on + ((off - on) - span_n) // 2
    if (off - on) - span_n < 2 * w:
        # (about) whole periods only, and the onset may be blurred (filtered records)
        best = _least_leaking_start(x, on, span_n, whole, w)
        start = start if best is None else best
    start = min(max(start, 0), n - span_n)
    return Gate(on=on, off=off, period=period, start=start, stop=start + span_n)


def _least_leaking_start(x: np.ndarray, on: int, span_n: int, whole: int, w: int) -> int | None:
    """Of the starts within ``min(w, 16)`` samples of ``on``, the one whose ``span_n`` samples (``whole``
    periods) put the least power off the harmonics of the period; None without candidates or with one period."""
    reach = min(w, 16)
    cand = np.arange(max(0, on - reach), min(len(x) - span_n, on + reach) + 1)
    if not (cand.size and whole >= 2):
        return None
    off_harm = np.arange(span_n // 2 + 1) % whole != 0
    leak = [float(np.sum(np.abs(np.fft.rfft(x[c:c + span_n] - np.mean(x[c:c + span_n])))[off_harm] ** 2))
            for c in cand]
    return int(cand[int(np.argmin(leak))])
