"""Perturbation ``pralds``: pseudorandom arbitrary-level distributed signal (random levels, random hold times)."""
from __future__ import annotations

import dataclasses
from typing import ClassVar

import numpy as np
from jointbench.core.lazy import scipy_signal as sps   # imported on first use: 0.6 CPU-s with scipy.stats

from jointbench.core.errors import ConfigError
from jointbench.core.schema import param
from jointbench.sims.registries import PERTURBATIONS


@PERTURBATIONS.register("pralds")
@dataclasses.dataclass(frozen=True)
class PRALDS:
    """Levels drawn uniformly in ``[-1, 1]``, each held for a time drawn uniformly in ``[min_hold, max_hold]``.

    The held sequence, zero-mean over its active part and zero in the first and last ``quiet`` seconds,
    is smoothed by a causal 2nd-order Butterworth low-pass at ``smoothing`` (the actuator cannot jump:
    a step of the handle through the hand contact's damping would be an impulse of torque), then
    scaled to ``rms`` over the active part. Every draw comes from the perturbation's stream, so each realization of
    an experiment (``sims.simulate(..., realization=r)``) has its own signal.

    Parameters
    ----------
    rms : float
        Rms over the active part (rad for a handle or position servo).
    min_hold, max_hold : float
        Range of the hold times (s).
    smoothing : float or None
        -3 dB frequency (Hz) of the smoothing low-pass; None = none (steps).
    quiet : float
        Seconds without perturbation at the start and at the end.

    References
    ----------
    Ludvig, D. & Perreault, E. J. (2012), IEEE TBME 59(12) (SDS, designed with PRALDS perturbations);
    Guarin & Kearney (2017), Front. Comput. Neurosci. 11:51; van de Ruit et al. (2018), Sec. VI-A ("both
    methods were developed with a pseudorandom arbitrary level perturbation signal").
    """

    rms: float = param(0.02, unit="rad", gt=0, doc="rms over the active part")
    min_hold: float = param(0.02, unit="s", gt=0, doc="shortest hold of a level")
    max_hold: float = param(0.2, unit="s", gt=0, doc="longest hold of a level")
    smoothing: float | None = param(20.0, unit="Hz", gt=0, doc="-3 dB frequency of the 2nd-order smoothing "
                                                                 "low-pass; none = steps")
    quiet: float = param(0.0, unit="s", ge=0, doc="seconds without perturbation at each end")

    kind: ClassVar[str] = "pralds"

    def __post_init__(self):
        if self.max_hold < self.min_hold:
            raise ConfigError(f"key 'max_hold': {self.max_hold:g} s is below min_hold = {self.min_hold:g} s")

    def check(self, fs: float, duration: float, where: str) -> None:
        if self.min_hold * fs < 1 - 1e-9:
            raise ConfigError(f"{where}: key 'min_hold': {self.min_hold:g} s is shorter than one sample at "
                              f"fs_sim = {fs:g} Hz")
        if self.smoothing is not None and not self.smoothing < fs / 2:
            raise ConfigError(f"{where}: key 'smoothing': must be below fs_sim / 2 = {fs / 2:g} Hz")
        if duration - 2 * self.quiet < 10 * self.max_hold:
            raise ConfigError(f"{where}: key 'quiet': {duration:g} s minus two quiet margins of {self.quiet:g} s "
                              f"holds fewer than 10 of the longest levels ({self.max_hold:g} s)")

    def generate(self, n: int, fs: float, rng: np.random.Generator) -> np.ndarray:
        """``n`` samples at ``fs`` Hz; levels and hold times from ``rng``."""
        t = np.arange(n) / fs
        active = (t >= self.quiet - 1e-9) & (t < n / fs - self.quiet - 1e-9)
        m = int(active.sum())
        holds = rng.uniform(self.min_hold, self.max_hold, int(np.ceil(m / fs / self.min_hold)) + 1)
        switches = np.floor(np.cumsum(holds) * fs).astype(int)
        levels = rng.uniform(-1.0, 1.0, len(holds) + 1)
        x = levels[np.searchsorted(switches, np.arange(m), side="right")]
        u = np.zeros(n)
        u[active] = x - x.mean()
        if self.smoothing is not None:      # the whole record, from rest: the quiet margins are smoothed too
            u = sps.sosfilt(sps.butter(2, self.smoothing, fs=fs, output="sos"), u)
        return u * (self.rms / np.sqrt(np.mean(u[active] ** 2)))
