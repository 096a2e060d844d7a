"""Profile ``ramp``: a straight line between two levels, held before and after.

YAML: ``K: {shape: ramp, initial: 20, final: 60, start: 10 s, duration: 20 s}``.
"""
from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

import numpy as np

from jointbench.core.errors import ConfigError
from jointbench.core.schema import param
from jointbench.sims.registries import PROFILES


@PROFILES.register("ramp")
@dataclasses.dataclass(frozen=True)
class Ramp:
    """``x(t) = initial`` up to ``start``, then a straight line to ``final`` at ``start + duration``,
    then ``final``.

    The one-ramp special case of :class:`sims.profile.Piecewise` (``interpolate: linear``), named by what
    a researcher sets: the two levels, when the change begins and how long it takes. Values stay
    between the two levels (exactly: they are clipped to them against rounding), so the minimum is the
    lower level.
    """

    initial: float = param(doc="value up to 'start'")
    final: float = param(doc="value from 'start' + 'duration' on")
    duration: float = param(unit="s", gt=0, doc="time the ramp takes")
    start: float = param(0.0, unit="s", doc="time the ramp begins")

    shape: ClassVar[str] = "ramp"

    def __post_init__(self):
        for key in ("initial", "final", "duration", "start"):
            if not math.isfinite(getattr(self, key)):
                raise ConfigError(f"ramp: key '{key}': must be finite, got {getattr(self, key)}")

    def at(self, t: np.ndarray) -> np.ndarray:
        frac = np.clip((np.asarray(t, float) - self.start) / self.duration, 0.0, 1.0)
        x = (1.0 - frac) * self.initial + frac * self.final
        return np.clip(x, self.minimum, max(self.initial, self.final))

    @property
    def minimum(self) -> float:
        """The smallest value the profile takes (the lower level)."""
        return float(min(self.initial, self.final))

    @property
    def constant(self) -> bool:
        return self.initial == self.final
