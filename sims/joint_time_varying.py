"""Joint model ``time_varying``: inertia-damper-spring whose stiffness and damping follow profiles.

``I theta'' + B(t) theta' + K(t) theta = torque``, with ``I`` constant, ``K(t)`` any profile of
:mod:`sims.profile` and ``B(t)`` either its own profile or ``2 zeta sqrt(K(t) I)`` for a constant damping
ratio zeta ("the damping varies like the stiffness while the damping ratio is constant").
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar

import numpy as np

from jointbench.core.errors import ConfigError
from jointbench.core.schema import Problems, param
from jointbench.sims.registries import JOINTS
from jointbench.sims.profile import parse_profile_fields, require_positive


@JOINTS.register("time_varying", tags=("ltv",))
@dataclasses.dataclass(frozen=True)
class TimeVaryingJoint:
    """Second-order joint with time-varying stiffness and damping.

    YAML: ``{model: time_varying, I: 0.06, K: {shape: sine, mean: 40, amplitude: 15, frequency: 0.5 Hz},
    damping_ratio: 0.3}`` or with ``B: <number or profile>`` instead of ``damping_ratio``.

    Parameters
    ----------
    I : float
        Inertia (kg·m²), constant, > 0.
    K : float or profile
        Stiffness (N·m/rad), must stay > 0.
    B : float or profile, optional
        Damping (N·m·s/rad), must stay >= 0. Exactly one of ``B`` and ``damping_ratio``.
    damping_ratio : float, optional
        Constant damping ratio zeta: ``B(t) = 2 zeta sqrt(K(t) I)``.

    References
    ----------
    Xu & Hollerbach 1998, eq. 7 and Sec. IV-A (elbow model, K(t) = 40 + 15 sin 2π f_v t, constant
    damping ratio); Sec. IV-B (calibration arm with damping switched during the trial).
    """

    I: float = param(unit="kg.m2", gt=0, doc="inertia (constant)")
    K: Any = dataclasses.field(metadata={"doc": "stiffness: number or profile {shape: ...}"})
    B: Any = dataclasses.field(default=None, metadata={"doc": "damping: number or profile (or damping_ratio)"})
    damping_ratio: float | None = param(None, ge=0, doc="constant damping ratio; B = 2 zeta sqrt(K I)")

    model: ClassVar[str] = "time_varying"
    contact: ClassVar[None] = None

    def __post_init__(self):
        problems = Problems()                      # every error of the model at once
        with problems.catch():
            if self.K is None:
                raise ConfigError("missing required key 'K'")
            parse_profile_fields(self, ("K",))
            require_positive("K", self.K, strict=True)
        with problems.catch():
            if (self.B is None) == (self.damping_ratio is None):
                raise ConfigError("give exactly one of 'B' (number or profile) and 'damping_ratio'")
            if self.B is not None:
                parse_profile_fields(self, ("B",))
                require_positive("B", self.B, strict=False)
        with problems.catch():
            if not math.isfinite(self.I):
                raise ConfigError(f"key 'I': must be finite, got {self.I}")
        problems.raise_all()

    @property
    def time_invariant(self) -> bool:
        return self.K.constant and (self.B is None or self.B.constant)

    def coefficients_at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(I, B, K)`` at times ``t`` (s), as arrays shaped like ``t``."""
        t = np.asarray(t, float)
        K = self.K.at(t)
        B = self.B.at(t) if self.B is not None else 2.0 * self.damping_ratio * np.sqrt(K * self.I)
        return np.full(t.shape, float(self.I)), B, K
