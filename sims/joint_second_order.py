"""Joint model ``second_order``: a linear, time-invariant inertia-damper-spring.

Its admittance is G(s) = 1 / (I s² + B s + K) (Westwick & Perreault 2012, eq. 1); its impedance
is the inverse, tau = I theta'' + B theta' + K theta (eq. 2).
"""
from __future__ import annotations

import dataclasses
import math
from typing import ClassVar

import numpy as np

from jointbench.core.errors import ConfigError
from jointbench.core.schema import param
from jointbench.sims.registries import JOINTS


@JOINTS.register("second_order", tags=("lti",))
@dataclasses.dataclass(frozen=True)
class SecondOrderJoint:
    """Second-order joint: ``I theta'' + B theta' + K theta = torque``.

    The class is its own settings dataclass: the YAML mapping
    ``{model: second_order, I: 0.171, B: 1.22, K: 53.5}`` parses into ``SecondOrderJoint(0.171, 1.22, 53.5)``.

    Parameters
    ----------
    I : float
        Inertia (kg·m², i.e. N·m·s²/rad), > 0.
    B : float
        Viscous damping (N·m·s/rad), >= 0.
    K : float
        Stiffness (N·m/rad), > 0.

    References
    ----------
    Westwick & Perreault 2012, eqs. 1-2 and Fig. 1 (the limb block G(s)).
    """

    I: float = param(unit="kg.m2", gt=0, doc="inertia")
    B: float = param(unit="N.m.s/rad", ge=0, doc="viscous damping")
    K: float = param(unit="N.m/rad", gt=0, doc="stiffness")

    model: ClassVar[str] = "second_order"
    time_invariant: ClassVar[bool] = True
    contact: ClassVar[None] = None

    def __post_init__(self):
        for name, ok, text in (("I", self.I > 0, "> 0"), ("B", self.B >= 0, ">= 0"), ("K", self.K > 0, "> 0")):
            v = getattr(self, name)
            if not (math.isfinite(v) and ok):
                raise ConfigError(f"key '{name}': must be {text} and finite, got {v}")

    def coefficients(self) -> tuple[float, float, float]:
        """``(I, B, K)``, the coefficients of the impedance ``I s² + B s + K``."""
        return float(self.I), float(self.B), float(self.K)

    def coefficients_at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(I, B, K)`` as arrays shaped like ``t`` (constant)."""
        shape = np.shape(t)
        return tuple(np.full(shape, v) for v in self.coefficients())

    def parameters(self) -> tuple[float, float, float]:
        """``(I, B, K)`` as stored in :class:`jointbench.Truth` (constants for this model)."""
        return self.coefficients()

    def state_space(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Continuous state space of the admittance, torque -> (theta, theta').

        Returns
        -------
        A, B, C, D : ndarray
            ``x' = A x + B u``, ``y = C x + D u`` with state and output ``x = [theta, theta']`` and input the
            net torque on the limb (N·m).
        """
        I, B, K = self.coefficients()
        a = np.array([[0.0, 1.0], [-K / I, -B / I]])
        b = np.array([[0.0], [1.0 / I]])
        return a, b, np.eye(2), np.zeros((2, 1))

    @property
    def natural_frequency(self) -> float:
        """Undamped natural frequency omega_n = sqrt(K / I) (rad/s)."""
        return math.sqrt(self.K / self.I)

    @property
    def damping_ratio(self) -> float:
        """Damping ratio zeta = B / (2 sqrt(K I))."""
        return self.B / (2.0 * math.sqrt(self.K * self.I))
