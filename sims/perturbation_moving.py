"""Perturbation ``moving``: a slow imposed movement plus a random perturbation around it.

The experiment of a parameter-varying (LPV) identification: the position servo moves the joint slowly
through its range while a small random perturbation measures the impedance along the way (the REKLAB
pilot trial: -0.41 ... 0.20 rad of slow ankle movement with a random perturbation on top). YAML::

    perturbation:
      kind: moving
      movement: {shape: sine, mean: -0.105, amplitude: 0.305, frequency: 0.05 Hz}   # rad (plain numbers)
      perturbation: {kind: pralds, rms: 0.02 rad, min_hold: 20 ms, max_hold: 200 ms, smoothing: 20 Hz}
      fade: 1 s

``movement`` is any time-variation profile of :mod:`sims.profile` (rad), faded in from 0 by a raised
cosine over ``fade`` seconds (the limb starts at rest; ``acquisition.trim`` removes the fade);
``perturbation`` any other perturbation, drawn from the perturbation's stream. The slow movement is the
scheduling variable of the truth (``trial.truth.signals["scheduling"]``, at the acquired sample times).
"""
from __future__ import annotations

import dataclasses
from typing import Any, ClassVar, Mapping

import numpy as np

from jointbench.core.errors import ConfigError
from jointbench.core.schema import param, parse_tagged
from jointbench.sims.registries import PERTURBATIONS
from jointbench.sims.profile import parse_profile


@PERTURBATIONS.register("moving")
@dataclasses.dataclass(frozen=True)
class Moving:
    """Slow movement (a profile, rad) plus a random perturbation (module docstring).

    Parameters
    ----------
    movement : profile
        The slow imposed trajectory (rad).
    perturbation : mapping
        ``{kind: ..., ...}``: the random perturbation added to it (not ``moving`` itself).
    fade : float
        Raised-cosine fade-in of the movement from 0 (s).
    """

    movement: Any = dataclasses.field(default=None, metadata={"doc": "slow trajectory (rad): a profile {shape: ...}"})
    perturbation: Any = dataclasses.field(default=None, metadata={"doc": "the random perturbation {kind: ...}"})
    fade: float = param(1.0, unit="s", ge=0, doc="raised-cosine fade-in of the movement")

    kind: ClassVar[str] = "moving"

    def __post_init__(self):
        if self.movement is None or self.perturbation is None:
            raise ConfigError("needs keys 'movement' (a profile, rad) and 'perturbation' ({kind: ...})")
        object.__setattr__(self, "movement", parse_profile(self.movement, "key 'movement'"))
        p = self.perturbation
        if isinstance(p, Mapping):
            if p.get("kind") == self.kind:
                raise ConfigError("key 'perturbation': a moving perturbation adds a random one, not another moving one")
            object.__setattr__(self, "perturbation", parse_tagged(p, "kind", PERTURBATIONS, "perturbation",
                                                                  "key 'perturbation'"))
        elif not hasattr(p, "generate"):
            raise ConfigError(f"key 'perturbation': expected a mapping {{kind: ...}}, got {p!r}")

    def check(self, fs: float, duration: float, where: str) -> None:
        self.perturbation.check(fs, duration, f"{where}: perturbation")
        if self.fade >= duration:
            raise ConfigError(f"{where}: key 'fade': {self.fade:g} s is not shorter than the record ({duration:g} s)")

    def movement_at(self, t: np.ndarray) -> np.ndarray:
        """The slow trajectory at times ``t`` (s), faded in over :attr:`fade`."""
        t = np.asarray(t, float)
        x = self.movement.at(t)
        if self.fade > 0:
            x = x * np.where(t < self.fade, 0.5 * (1.0 - np.cos(np.pi * np.clip(t, 0, None) / self.fade)), 1.0)
        return x

    def generate(self, n: int, fs: float, rng: np.random.Generator) -> np.ndarray:
        """The movement plus ``n`` samples of the random perturbation at ``fs`` Hz (drawn from ``rng``)."""
        return self.movement_at(np.arange(n) / fs) + self.perturbation.generate(n, fs, rng)

    def truth_signals(self, t: np.ndarray) -> dict[str, np.ndarray]:
        """Noise-free signals for the truth at times ``t``: the ``scheduling`` variable (the slow movement)."""
        return {"scheduling": self.movement_at(t)}
