"""Perturbation ``filtered_noise``: white Gaussian noise through a Butterworth low-pass."""
from __future__ import annotations

import dataclasses
from typing import ClassVar

import numpy as np
from jointbench.core.lazy import scipy_signal as sps   # imported on first use: 0.6 CPU-s with scipy.stats

from jointbench.core.errors import ConfigError
from jointbench.core.schema import param
from jointbench.sims.registries import PERTURBATIONS


def scale_to_rms(x: np.ndarray, rms: float) -> np.ndarray:
    """Return ``x`` scaled so that ``sqrt(mean(x**2)) == rms`` over the whole record (zeros stay zeros)."""
    r = float(np.sqrt(np.mean(np.square(x))))
    return x * (rms / r) if r > 0 else np.zeros_like(x)


def raised_cosine_taper(n: int, m: int) -> np.ndarray:
    """Window of length ``n`` rising from 0 to 1 over ``m`` samples at the start and falling at the end."""
    w = np.ones(n)
    if m > 0:
        rise = 0.5 * (1.0 - np.cos(np.pi * np.arange(m) / m))
        w[:m] = rise
        w[n - m:] = np.minimum(w[n - m:], rise[::-1])
    return w


@PERTURBATIONS.register("filtered_noise")
@dataclasses.dataclass(frozen=True)
class FilteredNoise:
    """White Gaussian noise low-passed by an ``order``-th order Butterworth filter, scaled to ``rms``.

    The filter stands for the analog Butterworth of the paper; it is designed digitally at the
    simulation rate, ``scipy.signal.butter(order, cutoff, fs=fs_sim, output="sos")`` (bilinear transform
    with pre-warping, so the -3 dB point is exactly ``cutoff``), and run causally from rest. The output
    is then faded in and out over ``ramp`` seconds by a raised cosine (quiet margins) and scaled so that
    its rms over the whole record equals ``rms`` exactly.

    Parameters
    ----------
    cutoff : float
        -3 dB frequency of the low-pass (Hz), below fs_sim / 2.
    order : int
        Filter order (default 2: -40 dB/decade).
    rms : float
        Root mean square of the signal over the record: rad for a position command (position servo);
        for a torque drive the same number is read in N·m (give it without a unit).
    ramp : float
        Length of the raised-cosine fade at each end (s); 0 = none.

    References
    ----------
    Westwick & Perreault 2012, Sec. IV ("30-s record of white Gaussian noise which had been low-pass
    filtered by a second-order Butterworth filter with either a 2, 5, or 10-Hz cutoff") and Sec. III-D.
    """

    cutoff: float = param(unit="Hz", gt=0, doc="-3 dB frequency of the Butterworth low-pass")
    order: int = param(2, ge=1, le=12, doc="Butterworth order")
    rms: float = param(0.02, unit="rad", ge=0, doc="rms over the record (rad; N·m for a torque drive)")
    ramp: float = param(0.0, unit="s", ge=0, doc="raised-cosine fade in/out at each end")

    kind: ClassVar[str] = "filtered_noise"

    def check(self, fs: float, duration: float, where: str) -> None:
        """Raise :class:`ConfigError` if the settings cannot be realised at ``fs`` over ``duration``."""
        if not self.cutoff < fs / 2:
            raise ConfigError(f"{where}: key 'cutoff': must be below fs_sim / 2 = {fs / 2:g} Hz, "
                              f"got {self.cutoff:g} Hz")
        if 2 * self.ramp >= duration:
            raise ConfigError(f"{where}: key 'ramp': two fades of {self.ramp:g} s do not fit in a "
                              f"{duration:g} s record")

    def generate(self, n: int, fs: float, rng: np.random.Generator) -> np.ndarray:
        """Draw ``n`` samples at ``fs`` Hz from ``rng``.

        Parameters
        ----------
        n : int
            Number of samples.
        fs : float
            Simulation rate (Hz).
        rng : numpy.random.Generator
            The perturbation's own random stream.

        Returns
        -------
        ndarray
            The perturbation signal (rad for a position command).
        """
        sos = sps.butter(self.order, self.cutoff, btype="low", fs=fs, output="sos")
        x = sps.sosfilt(sos, rng.standard_normal(n))
        x = x * raised_cosine_taper(n, int(round(self.ramp * fs)))
        return scale_to_rms(x, self.rms)
