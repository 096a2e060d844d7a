"""Perturbation ``multisine``: random-phase sparse multisine with quiet margins."""
from __future__ import annotations

import dataclasses
from typing import ClassVar

import numpy as np

from jointbench.core.errors import ConfigError
from jointbench.core.schema import param
from jointbench.sims.registries import PERTURBATIONS


@PERTURBATIONS.register("multisine")
@dataclasses.dataclass(frozen=True)
class Multisine:
    """Sum of cosines at lines ``f_min, f_min + spacing, ... <= f_max`` on the grid 1/period.

    ``u(t) = sum_l A_l cos(2π f_l (t - quiet) + phi_l)`` for ``quiet <= t < duration - quiet`` and 0
    outside; phases uniform in [0, 2π) from the perturbation's stream; amplitudes flat up to ``corner`` and
    falling by ``slope`` dB per decade above; scaled so the rms over the active part is ``rms``. Every line
    is a whole number of cycles per ``period``, so the signal is periodic with ``period``.

    Parameters
    ----------
    period : float
        Period (s); lines are multiples of 1/period.
    f_min, f_max, spacing : float
        First line, upper limit and line spacing (Hz); each a multiple of 1/period.
    corner : float
        Amplitudes are flat up to here (Hz) ...
    slope : float
        ... and fall by this many dB per decade above it (<= 0).
    rms : float
        Rms over the active part (rad for a handle or position servo).
    quiet : float
        Seconds without perturbation at the start and at the end.

    References
    ----------
    van de Ruit et al. 2018, Sec. IV-D: period 10 s, 0.1 ... 19.3 Hz every 0.8 Hz, flat to 6 Hz then
    -20 dB/decade, random phases, 0.02 rad rms; Sec. IV-C: no perturbation in the first and last 5 s.
    """

    period: float = param(10.0, unit="s", gt=0, doc="multisine period")
    f_min: float = param(0.1, unit="Hz", gt=0, doc="first excited line")
    f_max: float = param(19.3, unit="Hz", gt=0, doc="last excited line (upper limit)")
    spacing: float = param(0.8, unit="Hz", gt=0, doc="line spacing")
    corner: float = param(6.0, unit="Hz", gt=0, doc="amplitudes flat up to this frequency")
    slope: float = param(-20.0, le=0, doc="dB per decade above the corner")
    rms: float = param(0.02, unit="rad", gt=0, doc="rms over the active part")
    quiet: float = param(5.0, unit="s", ge=0, doc="seconds without perturbation at each end")

    kind: ClassVar[str] = "multisine"

    def __post_init__(self):
        for key in ("f_min", "spacing"):
            k = getattr(self, key) * self.period
            if abs(k - round(k)) > 1e-6:
                raise ConfigError(f"key '{key}': {getattr(self, key):g} Hz is not a multiple of 1/period = "
                                  f"{1 / self.period:g} Hz")
        if self.f_max < self.f_min:
            raise ConfigError(f"key 'f_max': {self.f_max:g} Hz is below f_min = {self.f_min:g} Hz")

    @property
    def bins(self) -> np.ndarray:
        """Excited harmonics of 1/period."""
        k0, dk = round(self.f_min * self.period), round(self.spacing * self.period)
        k1 = int(np.floor(self.f_max * self.period + 1e-6))
        return np.arange(k0, k1 + 1, dk)

    @property
    def lines(self) -> np.ndarray:
        """Excited frequencies (Hz)."""
        return self.bins / self.period

    def amplitudes(self) -> np.ndarray:
        """Relative amplitudes of the lines (1 up to the corner)."""
        f = self.lines
        return np.where(f <= self.corner, 1.0, (f / self.corner) ** (self.slope / 20.0))

    def check(self, fs: float, duration: float, where: str) -> None:
        if not self.f_max < fs / 2:
            raise ConfigError(f"{where}: key 'f_max': must be below fs_sim / 2 = {fs / 2:g} Hz")
        if duration - 2 * self.quiet < self.period:
            raise ConfigError(f"{where}: key 'quiet': {duration:g} s minus two quiet margins of {self.quiet:g} s "
                              f"leaves less than one period ({self.period:g} s)")

    def generate(self, n: int, fs: float, rng: np.random.Generator) -> np.ndarray:
        """``n`` samples at ``fs`` Hz; phases drawn from ``rng``.

        The active part is periodic: when a whole number ``M`` of samples spans one period (or a few
        periods: ``r <= 1000`` periods within the active part), one such stretch is synthesised by an
        inverse FFT of length ``M`` (line ``k`` of the period at DFT bin ``r k``, with the phase of the first
        active sample) and tiled; otherwise every sample is summed directly. Both give the formula above;
        the FFT is also the more accurate (about 1e-15 of the rms against 1e-12 for cosines of arguments
        up to thousands of radians).
        """
        phases = rng.uniform(0.0, 2 * np.pi, len(self.bins))
        t = np.arange(n) / fs
        active = (t >= self.quiet - 1e-9) & (t < n / fs - self.quiet - 1e-9)
        # exact rms of the periodic signal: sum A² / 2; scale the amplitudes rather than the samples
        a = self.amplitudes()
        a = a * (self.rms / np.sqrt(np.sum(a ** 2) / 2.0))
        u = np.zeros(n)
        idx = np.flatnonzero(active)
        if idx.size == 0:
            return u
        r = _periods_in_whole_samples(self.period * fs, idx.size)
        if r is None or 2 * r * self.bins[-1] >= round(r * self.period * fs):   # no stretch, or lines above Nyquist
            u[idx] = np.cos(2 * np.pi * np.outer(t[idx] - self.quiet, self.lines) + phases) @ a
            return u
        M = int(round(r * self.period * fs))
        tau0 = t[idx[0]] - self.quiet          # time of the first active sample on the signal's clock
        X = np.zeros(M // 2 + 1, complex)
        X[r * self.bins] = (M / 2.0) * a * np.exp(1j * (phases + 2 * np.pi * self.lines * tau0))
        u[idx] = np.resize(np.fft.irfft(X, M), idx.size)
        return u


def _periods_in_whole_samples(samples_per_period: float, n: int) -> int | None:
    """Smallest ``r <= 1000`` such that ``r`` periods span a whole number of samples, else None.

    Whole to within a drift of 1e-10 sample over ``n`` samples (tiling a stretch that is ``e`` samples
    too short shifts the signal by ``n e / M`` samples at the end); more than one period only while the
    stretch stays within ``n`` samples.
    """
    for r in range(1, 1001):
        m = r * samples_per_period
        if r > 1 and m > n:
            return None
        if abs(m - round(m)) * n <= 1e-10 * m:
            return r
    return None
