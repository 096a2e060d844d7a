"""Signal-processing steps shared by the simulators, the estimators and the harness."""
from __future__ import annotations

import numpy as np
from scipy import signal as sps

import dataclasses
import functools
from typing import Callable

from jointbench.errors import InputError
from jointbench.types import Trial, Truth


def _map_truth(truth: Truth | None, on_signal: Callable[[np.ndarray], np.ndarray],
               on_param: Callable[[np.ndarray], np.ndarray]) -> Truth | None:
    """Apply ``on_signal`` to the truth's signals and ``on_param`` to its time-varying parameters."""
    if truth is None:
        return None
    par = {k: (v if np.ndim(v) < (2 if k in ("num", "den") else 1) else on_param(np.asarray(v)))
           for k, v in (("I", truth.I), ("B", truth.B), ("K", truth.K), ("num", truth.num),
                        ("den", truth.den)) if v is not None}
    return dataclasses.replace(truth, signals={k: on_signal(v) for k, v in truth.signals.items()}, **par)


def decimate(x: np.ndarray, q: int, cutoff: float = 0.8) -> np.ndarray:
    """Zero-phase FIR anti-alias filter and keep every ``q``-th sample.

    Parameters
    ----------
    x : ndarray
        Signal.
    q : int
        Decimation factor (1 returns a copy).
    cutoff : float
        Pass band edge as a fraction of the new Nyquist frequency.
    """
    if q < 1 or int(q) != q:
        raise InputError(f"decimation factor must be a whole number >= 1, got {q}")
    x = np.asarray(x, float)
    if q == 1:
        return x.copy()
    return sps.resample_poly(x, 1, q, window=_taps(int(q), float(cutoff)), padtype="line")


@functools.lru_cache(maxsize=32)
def _taps(q: int, cutoff: float) -> np.ndarray:
    """The anti-alias FIR of :func:`decimate`, designed once per factor and cutoff (read-only)."""
    taps = sps.firwin(20 * q + 1, cutoff / q)
    taps.flags.writeable = False
    return taps


def resample_trial(trial: Trial, fs_new: float, cutoff: float = 0.8) -> Trial:
    """Decimate a trial to ``fs_new`` (an integer divisor of its rate); truth signals follow."""
    q = trial.fs / fs_new
    if abs(q - round(q)) > 1e-9 or round(q) < 1:
        raise InputError(f"trial '{trial.name}': can only decimate {trial.fs:g} Hz by a whole factor; "
                         f"{fs_new:g} Hz is not {trial.fs:g}/q")
    q = int(round(q))
    if q == 1:
        return trial
    # signals are filtered like the measurements; time-varying parameters are sampled
    truth = _map_truth(trial.truth, lambda v: decimate(v, q, cutoff), lambda v: v[::q])
    a = decimate(trial.angle, q, cutoff)
    return Trial(time=trial.time[0] + np.arange(len(a)) / fs_new, angle=a,
                 torque=decimate(trial.torque, q, cutoff), fs=fs_new, imposed=trial.imposed,
                 truth=truth, name=trial.name)


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
