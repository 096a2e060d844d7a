"""Sensor models, one per measured channel: analog filter, additive white noise, quantization.

The order is that of the hardware: the analog filter (e.g. the 5th-order Bessel anti-alias filter
of the load cell), then additive noise, then quantization (e.g. the encoder resolution), all at the
simulation rate, before the acquisition steps (detrend, decimate, trim).
"""
from __future__ import annotations

import dataclasses
import functools
import math
from typing import Literal

import numpy as np
from jointbench.core.lazy import scipy_signal as sps   # imported on first use: 0.6 CPU-s with scipy.stats

from jointbench.core.errors import ConfigError
from jointbench.core.schema import param


@functools.lru_cache(maxsize=64)
def _design(kind: str, order: int, cutoff: float, fs: float) -> np.ndarray:
    """Second-order sections of a Bessel ('bessel') or Butterworth low-pass; cached, returned read-only."""
    if kind == "bessel":
        sos = sps.bessel(order, cutoff, btype="low", norm="mag", fs=fs, output="sos")
    else:
        sos = sps.butter(order, cutoff, btype="low", fs=fs, output="sos")
    sos.flags.writeable = False
    return sos


@functools.lru_cache(maxsize=16)
def _advance(n: int, fs: float, delay: float) -> np.ndarray:
    """``exp(2j pi f delay)`` at the ``rfft`` bins of ``n`` samples: an advance by ``delay`` seconds; cached
    (every trial of a study has the same length, rate and filter; read-only, so it cannot be changed)."""
    shift = np.exp(2j * np.pi * np.fft.rfftfreq(n, 1.0 / fs) * delay)
    shift.flags.writeable = False
    return shift


@functools.lru_cache(maxsize=64)
def _delay(kind: str, order: int, cutoff: float, fs: float) -> float:
    """Group delay (s) of :func:`_design`'s filter at 1 % of its cutoff; cached."""
    b, a = sps.sos2tf(_design(kind, order, cutoff, fs))
    _, gd = sps.group_delay((b, a), w=[0.01 * cutoff], fs=fs)
    return float(gd[0]) / fs


@dataclasses.dataclass(frozen=True)
class SensorFilter:
    """Analog low-pass filter of a sensor, modelled causally at the simulation rate.

    The filter is designed digitally at ``fs_sim`` from its analog prototype by the bilinear transform:
    ``scipy.signal.bessel(order, cutoff, norm="mag", fs=fs_sim, output="sos")`` (``cutoff`` is the -3 dB
    point) or ``scipy.signal.butter(order, cutoff, fs=fs_sim, output="sos")``.

    Parameters
    ----------
    cutoff : float
        -3 dB frequency (Hz), below fs_sim / 2.
    kind : {'bessel', 'butter'}
        Prototype (default 'bessel').
    order : int
        Filter order (default 5).

    References
    ----------
    Westwick & Perreault 2012, Sec. IV ("fifth-order Bessel filters with 500-Hz cutoff frequencies");
    Xu & Hollerbach 1998, Sec. IV (8-pole linear-phase 150 Hz anti-aliasing filter, delay corrected).
    """

    cutoff: float = param(unit="Hz", gt=0, doc="-3 dB frequency")
    kind: Literal["bessel", "butter"] = "bessel"
    order: int = param(5, ge=1, le=12, doc="filter order")
    delay_correction: bool = param(False, doc="advance the output by the filter's low-frequency delay")

    def delay(self, fs: float) -> float:
        """The filter's group delay at low frequency (1 % of the cutoff), in seconds."""
        return _delay(self.kind, self.order, float(self.cutoff), float(fs))

    def sos(self, fs: float) -> np.ndarray:
        """Second-order sections of the filter at sampling rate ``fs`` (a copy of the design, which is
        computed once per kind, order, cutoff and rate)."""
        return _design(self.kind, self.order, float(self.cutoff), float(fs)).copy()

    def apply(self, x: np.ndarray, fs: float) -> np.ndarray:
        """Filter ``x`` causally from rest (along axis 0: columns of a 2-D array are separate signals).

        With ``delay_correction`` the output is then advanced by :meth:`delay` (a fractional shift by a
        linear phase in the frequency domain; the last ``delay`` seconds wrap around and must be trimmed),
        the digital correction of a linear-phase anti-aliasing filter's pure delay.
        """
        y = sps.sosfilt(self.sos(fs), x, axis=0)
        if not self.delay_correction:
            return y
        n = y.shape[0]
        shift = _advance(n, float(fs), self.delay(fs))
        Y = np.fft.rfft(y, axis=0)
        return np.fft.irfft(Y * (shift if y.ndim == 1 else shift[:, None]), n, axis=0)


@dataclasses.dataclass(frozen=True)
class Sensor:
    """One measurement channel.

    Parameters
    ----------
    filter : SensorFilter or None
        Analog filter; None = ideal (flat).
    noise_rms : float or None
        Rms of the additive white Gaussian noise in the acquired record (channel unit).
    noise_snr_db : float or None
        Or the noise level as 10·log10(var(signal) / var(noise)) over the acquired record, where the
        signal is the channel's noise-free measurement.
    noise_variance_ratio : float or None
        Or var(noise) / var(signal) over the acquired record (the NSR of Xu & Hollerbach 1998, Fig. 3).
        At most one of the three noise settings.
    noise_filter : SensorFilter or None
        Colours the noise: white noise through this filter (causal, from rest) before scaling, e.g. the
        2nd-order 15 Hz Butterworth of van de Ruit et al. 2018, Sec. IV-C.
    quantization : float
        Quantization step (channel unit); 0 = off.

    Notes
    -----
    The noise is white at the simulation rate (an analog sensor noise); acquisition then removes the part
    above the new Nyquist rate. Both noise settings therefore refer to the acquired record (after detrend,
    decimation and trim), which is what an estimator sees and what the papers quote: the experiment
    scales the noise to the exact rms or SNR there (:meth:`noise_gain`).
    """

    filter: SensorFilter | None = None
    noise_rms: float | None = param(None, ge=0, doc="rms of the additive white noise (acquired record)")
    noise_snr_db: float | None = param(None, unit="dB", doc="SNR of the acquired record (dB)")
    noise_variance_ratio: float | None = param(None, ge=0, doc="var(noise) / var(signal), acquired record")
    noise_filter: SensorFilter | None = None
    quantization: float = param(0.0, ge=0, doc="quantization step; 0 = off")

    def __post_init__(self):
        given = [k for k in ("noise_rms", "noise_snr_db", "noise_variance_ratio") if getattr(self, k) is not None]
        if len(given) > 1:
            raise ConfigError(f"give at most one of 'noise_rms', 'noise_snr_db' and 'noise_variance_ratio', "
                              f"got {' and '.join(given)}")
        if self.noise_snr_db is not None and not math.isfinite(self.noise_snr_db):
            raise ConfigError(f"key 'noise_snr_db': must be finite, got {self.noise_snr_db} "
                              f"(leave it out for no noise)")

    @property
    def noisy(self) -> bool:
        """True when the channel adds noise."""
        return bool(self.noise_rms) or self.noise_snr_db is not None or bool(self.noise_variance_ratio)

    def check(self, fs: float, where: str) -> None:
        """Raise :class:`ConfigError` if the filter cannot be realised at ``fs``."""
        for key, flt in (("filter", self.filter), ("noise_filter", self.noise_filter)):
            if flt is not None and not flt.cutoff < fs / 2:
                raise ConfigError(f"{where}: {key}: key 'cutoff': must be below fs_sim / 2 = {fs / 2:g} Hz, "
                                  f"got {flt.cutoff:g} Hz")

    def filtered(self, x: np.ndarray, fs: float) -> np.ndarray:
        """The analog filter's output (``x`` itself when there is no filter); 2-D: one signal per column."""
        return x if self.filter is None else self.filter.apply(x, fs)

    def noise_gain(self, clean_acquired: np.ndarray, unit_noise_acquired: np.ndarray) -> float:
        """Factor by which unit white noise at the simulation rate is multiplied.

        Parameters
        ----------
        clean_acquired : ndarray
            The channel's noise-free measurement after acquisition.
        unit_noise_acquired : ndarray
            The channel's unit-variance white noise after the same acquisition.
        """
        if self.noise_snr_db is not None or self.noise_variance_ratio is not None:
            ratio = (self.noise_variance_ratio if self.noise_variance_ratio is not None
                     else 10.0 ** (-self.noise_snr_db / 10.0))
            target = float(np.var(clean_acquired)) * ratio
            have = float(np.var(unit_noise_acquired))
        else:
            target = float(self.noise_rms or 0.0) ** 2
            have = float(np.mean(np.square(unit_noise_acquired)))
        return math.sqrt(target / have) if have > 0 else 0.0

    def quantize(self, x: np.ndarray) -> np.ndarray:
        """Round ``x`` to the nearest multiple of the quantization step (no-op when the step is 0)."""
        if not self.quantization:
            return x
        return self.quantization * np.round(x / self.quantization)


@dataclasses.dataclass(frozen=True)
class AngleSensor(Sensor):
    """The angle channel (rad): an encoder is usually quantized, e.g. 3.6e-3 deg = 6.28e-5 rad."""

    noise_rms: float | None = param(None, unit="rad", ge=0, doc="rms of the additive white noise (acquired)")
    quantization: float = param(0.0, unit="rad", ge=0, doc="quantization step; 0 = off")


@dataclasses.dataclass(frozen=True)
class TorqueSensor(Sensor):
    """The torque channel (N·m): a load cell, usually behind an analog anti-alias filter."""

    noise_rms: float | None = param(None, unit="N.m", ge=0, doc="rms of the additive white noise (acquired)")
    quantization: float = param(0.0, unit="N.m", ge=0, doc="quantization step; 0 = off")


@dataclasses.dataclass(frozen=True)
class Sensors:
    """The sensor models of the two channels (ideal by default)."""

    angle: AngleSensor = dataclasses.field(default_factory=AngleSensor)
    torque: TorqueSensor = dataclasses.field(default_factory=TorqueSensor)

    def check(self, fs: float, where: str) -> None:
        self.angle.check(fs, f"{where}: angle")
        self.torque.check(fs, f"{where}: torque")
