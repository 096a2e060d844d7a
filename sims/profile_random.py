"""Profile ``smooth_random``: a seeded, band-limited random variation with an exactly known range.

YAML: ``K: {shape: smooth_random, mean: 40, amplitude: 15, bandwidth: 0.5 Hz, seed: 3}``.
"""
from __future__ import annotations

import dataclasses
import functools
import math
from typing import ClassVar

import numpy as np

from jointbench.core.errors import ConfigError
from jointbench.core.schema import param
from jointbench.sims.registries import PROFILES

_MAX_LINES = 20_000
_GRID_PER_LINE = 32      # grid points per line over one period when searching the extremes


@PROFILES.register("smooth_random")
@dataclasses.dataclass(frozen=True)
class SmoothRandom:
    """``x(t) = mean + amplitude · g(t)``: ``g`` a random trigonometric polynomial rescaled so that its
    range is exactly [-1, 1].

    ``r(t) = Re sum_{l=1..L} c_l exp(2π j l t / period)`` with ``L = floor(bandwidth · period)`` lines
    (every multiple of 1/period up to ``bandwidth``) and ``c_l`` independent complex standard Gaussians
    from ``numpy.random.default_rng(seed)`` (a flat spectrum up to ``bandwidth``, nothing above: smooth,
    with random phases). ``g = (2 r - r_max - r_min) / (r_max - r_min)`` with ``r_min``, ``r_max`` the
    extremes of ``r`` over a period (found on a grid of 32 points per line, then refined by Newton's
    method on ``r' = 0``), so the profile spans ``mean - amplitude ... mean + amplitude``, reaches both
    ends, and :attr:`minimum` is ``mean - amplitude``.

    A function of its settings only: the same ``seed`` gives the same profile in every case and run
    (vary ``seed`` for other realisations). It repeats with ``period``; make the period at least the
    simulated duration for a variation that never repeats.

    Parameters
    ----------
    mean : float
        Middle of the range.
    amplitude : float
        Half the range (>= 0).
    bandwidth : float
        Highest frequency of the variation (Hz), at least 1/period.
    period : float
        The profile repeats after this time (s; default 120, longer than the papers' trials).
    seed : int
        Seed of the coefficients.
    """

    mean: float = param(doc="middle of the range")
    amplitude: float = param(ge=0, doc="half the range; the profile reaches mean +- amplitude")
    bandwidth: float = param(unit="Hz", gt=0, doc="highest frequency of the variation")
    seed: int = param(ge=0, doc="seed of the random coefficients")
    period: float = param(120.0, unit="s", gt=0, doc="the profile repeats after this time")

    shape: ClassVar[str] = "smooth_random"

    def __post_init__(self):
        for key in ("mean", "amplitude", "bandwidth", "period"):
            if not math.isfinite(getattr(self, key)):
                raise ConfigError(f"smooth_random: key '{key}': must be finite, got {getattr(self, key)}")
        L = self.lines
        if L < 1:
            raise ConfigError(f"smooth_random: key 'bandwidth': {self.bandwidth:g} Hz is below 1/period = "
                              f"{1 / self.period:g} Hz: no line to vary")
        if L > _MAX_LINES:
            raise ConfigError(f"smooth_random: bandwidth x period = {L} lines, more than {_MAX_LINES}; lower "
                              f"'bandwidth' or 'period'")

    @property
    def lines(self) -> int:
        """Number of lines ``L`` (multiples of 1/period up to the bandwidth)."""
        return int(math.floor(self.bandwidth * self.period * (1 + 1e-12)))

    def raw(self, t: np.ndarray) -> np.ndarray:
        """``r(t)`` before rescaling (Horner's rule in ``exp(2π j t / period)``)."""
        c = _coefficients(self.seed, self.lines)
        theta = 2 * np.pi * np.mod(np.asarray(t, float) / self.period, 1.0)
        z = np.exp(1j * theta)
        acc = np.full(z.shape, c[-1])
        for cl in c[-2::-1]:
            acc = acc * z + cl
        return (acc * z).real

    def at(self, t: np.ndarray) -> np.ndarray:
        lo, hi = _extremes(self.seed, self.lines)
        g = (2.0 * self.raw(t) - (hi + lo)) / (hi - lo)
        return self.mean + self.amplitude * np.clip(g, -1.0, 1.0)

    @property
    def minimum(self) -> float:
        """The smallest value the profile takes: ``mean - amplitude``."""
        return float(self.mean - self.amplitude)

    @property
    def constant(self) -> bool:
        return self.amplitude == 0


@functools.lru_cache(maxsize=64)
def _coefficients(seed: int, lines: int) -> np.ndarray:
    """``c_1 ... c_L``, complex standard Gaussians (read-only)."""
    rng = np.random.default_rng(seed)
    c = (rng.standard_normal(lines) + 1j * rng.standard_normal(lines)) / math.sqrt(2.0)
    c.flags.writeable = False
    return c


@functools.lru_cache(maxsize=64)
def _extremes(seed: int, lines: int) -> tuple[float, float]:
    """``(min, max)`` of ``r`` over a period (period 1: the extremes do not depend on it).

    ``r`` on a grid of ``32 L`` points (an inverse FFT); every grid point below (above) both neighbours
    is refined by Newton's method on ``r'`` (steps limited to one grid spacing), and the extreme of the
    refined and grid values is kept. At 32 points per shortest cycle two extremes closer than a grid
    spacing would have to be nearly a double root of ``r'``, where the value between them differs from
    the grid's by far less than the rounding of the result.
    """
    c = _coefficients(seed, lines)
    l = np.arange(1, lines + 1)
    n = max(64, 2 ** math.ceil(math.log2(_GRID_PER_LINE * lines)))
    X = np.zeros(n // 2 + 1, complex)
    X[1:lines + 1] = c * (n / 2.0)
    r = np.fft.irfft(X, n)
    w = 2 * np.pi * l
    out = []
    for sign in (1.0, -1.0):                                  # minima of r, then of -r (maxima)
        s = sign * r
        cand = np.flatnonzero((s <= np.roll(s, 1)) & (s <= np.roll(s, -1)))
        t = cand / n
        for _ in range(30):
            e = np.exp(1j * np.outer(t, w)) * c
            d1 = sign * (e * (1j * w)).real.sum(axis=1)
            d2 = sign * (e * (-w * w)).real.sum(axis=1)
            step = np.where(d2 > 0, -d1 / np.where(d2 > 0, d2, 1.0), 0.0)
            step = np.clip(step, -1.0 / n, 1.0 / n)
            t = t + step
            if np.all(np.abs(step) < 1e-15):
                break
        vals = sign * (np.exp(1j * np.outer(t, w)) @ c).real
        out.append(sign * min(float(vals.min()), float(s.min())))
    lo, hi = out
    return lo, hi
