"""Perturbation ``prbs``: pseudorandom binary sequence of levels +-amplitude held for one clock period."""
from __future__ import annotations

import dataclasses
import math
from typing import ClassVar, Literal

import numpy as np
from jointbench.core.lazy import scipy_signal as sps   # imported on first use: 0.6 CPU-s with scipy.stats

from jointbench.core.errors import ConfigError
from jointbench.core.schema import param
from jointbench.sims.registries import PERTURBATIONS


@PERTURBATIONS.register("prbs")
@dataclasses.dataclass(frozen=True)
class PRBS:
    """Binary levels ``+-amplitude``, a new level every ``clock`` seconds, held in between.

    ``sequence: mls`` (default) takes the levels from a maximum-length sequence
    (:func:`scipy.signal.max_len_seq`) of the smallest register length whose period covers the record,
    started at a random register state drawn from the perturbation's stream; its autocorrelation is
    -1/period beyond one clock. ``sequence: random`` draws independent fair coin flips per clock instead.
    Either way the first switch happens at t = 0 and the record holds whole or partial clock periods.

    Parameters
    ----------
    amplitude : float
        Level (N·m for a torque drive, rad for a position servo; give it without a unit).
    clock : float
        Clock period (s), e.g. 10 ms for a 100 Hz DAC update.
    sequence : {'mls', 'random'}
        How the levels are drawn.

    References
    ----------
    Xu & Hollerbach 1998, Sec. IV-A: "pseudorandom binary sequence ... +-4 N·m ... 10 ms"; the
    autocorrelation is below 10 % beyond one clock period.
    """

    amplitude: float = param(4.0, gt=0, doc="binary level (N.m for a torque drive)")
    clock: float = param(0.01, unit="s", gt=0, doc="clock period: a new level every clock seconds")
    sequence: Literal["mls", "random"] = "mls"

    kind: ClassVar[str] = "prbs"

    def check(self, fs: float, duration: float, where: str) -> None:
        """The clock must hold at least one simulation sample and fit the record."""
        if self.clock * fs < 1 - 1e-9:
            raise ConfigError(f"{where}: key 'clock': {self.clock:g} s is shorter than one sample at "
                              f"fs_sim = {fs:g} Hz")
        if self.clock > duration:
            raise ConfigError(f"{where}: key 'clock': {self.clock:g} s is longer than the record ({duration:g} s)")

    def levels(self, n_clocks: int, rng: np.random.Generator) -> np.ndarray:
        """``n_clocks`` levels of +-1."""
        if self.sequence == "random":
            return np.where(rng.random(n_clocks) < 0.5, -1.0, 1.0)
        nbits = max(2, math.ceil(math.log2(n_clocks + 1)))
        state = np.zeros(nbits, dtype=np.int8)
        while not state.any():   # the all-zero state is not allowed
            state = rng.integers(0, 2, nbits).astype(np.int8)
        seq, _ = sps.max_len_seq(nbits, state=state, length=n_clocks)
        return 2.0 * seq - 1.0

    def generate(self, n: int, fs: float, rng: np.random.Generator) -> np.ndarray:
        """``n`` samples at ``fs`` Hz: the level of clock period ``floor(t / clock)`` at t = i / fs."""
        idx = np.floor(np.arange(n) / fs / self.clock + 1e-9).astype(int)
        return self.amplitude * self.levels(int(idx[-1]) + 1, rng)[idx]
