"""Sensor models, one per measured channel: analog filter, additive white noise, quantization.

The order is that of the hardware: the analog filter (e.g. the 5th-order Bessel anti-alias filter
of the load cell), then additive noise, then quantization (e.g. the encoder resolution), all at the
simulation rate, before the acquisition steps (detrend, decimate, trim).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Literal

import numpy as np
from scipy import signal as sps

from jointbench.errors import ConfigError
from jointbench.schema import param


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
    Westwick & Perreault 2012, Sec. IV ("fifth-order Bessel filters with 500-Hz cutoff frequencies").
    """

    cutoff: float = param(unit="Hz", gt=0, doc="-3 dB frequency")
    kind: Literal["bessel", "butter"] = "bessel"
    order: int = param(5, ge=1, le=12, doc="filter order")

    def sos(self, fs: float) -> np.ndarray:
        """Second-order sections of the filter at sampling rate ``fs``."""
        if self.kind == "bessel":
            return sps.bessel(self.order, self.cutoff, btype="low", norm="mag", fs=fs, output="sos")
        return sps.butter(self.order, self.cutoff, btype="low", fs=fs, output="sos")

    def apply(self, x: np.ndarray, fs: float) -> np.ndarray:
        """Filter ``x`` causally from rest (along axis 0: columns of a 2-D array are separate signals)."""
        return sps.sosfilt(self.sos(fs), x, axis=0)


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
        signal is the channel's noise-free measurement. At most one of ``noise_rms`` and ``noise_snr_db``.
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
    quantization: float = param(0.0, ge=0, doc="quantization step; 0 = off")

    def __post_init__(self):
        if self.noise_rms is not None and self.noise_snr_db is not None:
            raise ConfigError("give at most one of 'noise_rms' and 'noise_snr_db', not both")
        if self.noise_snr_db is not None and not math.isfinite(self.noise_snr_db):
            raise ConfigError(f"key 'noise_snr_db': must be finite, got {self.noise_snr_db} "
                              f"(leave it out for no noise)")

    @property
    def noisy(self) -> bool:
        """True when the channel adds noise."""
        return bool(self.noise_rms) or self.noise_snr_db is not None

    def check(self, fs: float, where: str) -> None:
        """Raise :class:`ConfigError` if the filter cannot be realised at ``fs``."""
        if self.filter is not None and not self.filter.cutoff < fs / 2:
            raise ConfigError(f"{where}: filter: key 'cutoff': must be below fs_sim / 2 = {fs / 2:g} Hz, "
                              f"got {self.filter.cutoff:g} Hz")

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
        if self.noise_snr_db is not None:
            target = float(np.var(clean_acquired)) / 10.0 ** (self.noise_snr_db / 10.0)
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
