"""Joint model ``position_dependent``: stiffness and damping that depend on the joint angle, K(theta), B(theta).

``I theta'' + B(theta) theta' + P(theta) = torque`` with the elastic torque ``P(theta) = int_0^theta
K(phi) d phi``: the incremental stiffness dP/dtheta at any angle is K(theta), what a parameter-varying
(LPV) identification scheduled on the angle recovers (Sobhani Tehrani & Kearney's parameter-varying
models of the ankle). Ankle stiffness grows as the ankle is dorsiflexed (Mirbagheri, Barbeau & Kearney
2000), so a slow imposed movement sweeps it while a small perturbation measures it.

K(theta) and B(theta) are each a number, a polynomial in the angle (rad) or a table (linear
interpolation between the listed angles)::

    K: {polynomial: [100, 150, 200]}                    # 100 + 150 theta + 200 theta^2, N·m/rad
    K: {angle: [-0.5, 0, 0.3], value: [60, 100, 140]}   # table, N·m/rad at those angles (rad)
    B: 0.8                                              # or damping_ratio: 0.3 (B = 2 zeta sqrt(K I))

Outside ``angle_range`` (required with a polynomial; a table's own span by default) both are held at
their values at the range's ends, and P continues as a straight line. Every value must stay > 0 (K) or
>= 0 (B) over the range (checked on a dense grid).

The plant is nonlinear: backends integrate it with their time-stepping path (:mod:`sims.backend_stepping`,
the physics backend step by step). The linear part they integrate exactly is the model linearized at
theta = 0 (:meth:`PositionDependentJoint.coefficients_at`), the rest is :meth:`~PositionDependentJoint.remainder`.
The truth of a trial states K(theta(t)) and B(theta(t)) along the simulated angle.

References
----------
Mirbagheri, M. M., Barbeau, H. & Kearney, R. E. (2000). Exp. Brain Res. 135(4), 423-436 (intrinsic and
reflex stiffness both increase as the ankle is dorsiflexed). Sobhani Tehrani, E. & Kearney, R. E. (2022).
IEEE Trans. Biomed. Eng. (parameter-varying parallel cascade of the ankle, position as the scheduling
variable).
"""
from __future__ import annotations

import dataclasses
import functools
import math
from typing import Any, ClassVar, Mapping

import numpy as np
from numpy.polynomial import polynomial as P

from jointbench.core.errors import ConfigError
from jointbench.core.schema import param, parse
from jointbench.sims.registries import JOINTS

_GRID = 10001      # points on which a function's range is checked


@dataclasses.dataclass(frozen=True)
class AngleFunction:
    """A function of the joint angle: a polynomial or a table, held outside ``[lo, hi]``.

    ``at(theta)`` is the value; ``integral(theta)`` is ``int_0^theta`` of the held function (exact: the
    polynomial's antiderivative, or the table's piecewise-quadratic integral).
    """

    kind: str                   # 'polynomial' or 'table'
    coef: tuple[float, ...]     # polynomial coefficients (ascending powers) or table values
    angles: tuple[float, ...]   # table angles (rad); () for a polynomial
    lo: float
    hi: float

    @classmethod
    def parse(cls, data: Any, key: str, angle_range: tuple[float, float] | None) -> "AngleFunction":
        """From a number, ``{polynomial: [...]}`` or ``{angle: [...], value: [...]}`` (errors name ``key``)."""
        if isinstance(data, (int, float)) and not isinstance(data, bool):
            data = {"polynomial": [float(data)]}
            if angle_range is None:
                angle_range = (-math.pi, math.pi)
        if not isinstance(data, Mapping):
            raise ConfigError(f"key '{key}': expected a number, {{polynomial: [c0, c1, ...]}} or "
                              f"{{angle: [...], value: [...]}}, got {data!r}")
        spec = parse(AngleSpec, data, f"key '{key}'")
        if spec.polynomial is not None and spec.angle is None and spec.value is None:
            if angle_range is None:
                raise ConfigError(f"key 'angle_range': a polynomial {key}(theta) needs the angle range (rad) it "
                                  f"holds over, e.g. angle_range: [-0.6, 0.4]")
            return cls("polynomial", spec.polynomial, (), float(angle_range[0]), float(angle_range[1]))
        if spec.polynomial is None and spec.angle is not None and spec.value is not None:
            a, v = np.asarray(spec.angle, float), spec.value
            if len(a) != len(v) or len(a) < 2:
                raise ConfigError(f"key '{key}': a table needs as many angles as values (at least 2), got "
                                  f"{len(a)} and {len(v)}")
            if np.any(np.diff(a) <= 0):
                raise ConfigError(f"key '{key}.angle': the angles must increase strictly, got {list(a)}")
            lo, hi = (a[0], a[-1]) if angle_range is None else angle_range
            return cls("table", v, tuple(a), float(lo), float(hi))
        raise ConfigError(f"key '{key}': expected {{polynomial: [...]}} or {{angle: [...], value: [...]}}, got keys "
                          f"{sorted(data)}")

    @functools.cached_property
    def _integ(self) -> np.ndarray:
        """Coefficients of the polynomial's antiderivative (computed once)."""
        return tuple(P.polyint(np.asarray(self.coef, float)))

    def _raw(self, x: np.ndarray) -> np.ndarray:
        if self.kind == "polynomial":
            return _horner(x, self.coef)
        return np.interp(x, self.angles, self.coef)

    def _antiderivative(self, x: np.ndarray) -> np.ndarray:
        """An antiderivative of the unheld function on [lo, hi] (any constant)."""
        if self.kind == "polynomial":
            return _horner(x, self._integ)
        a, v = np.asarray(self.angles), np.asarray(self.coef)
        slope = np.diff(v) / np.diff(a)
        cum = np.concatenate([[0.0], np.cumsum(np.diff(a) * (v[:-1] + v[1:]) / 2)])
        i = np.clip(np.searchsorted(a, x, side="right") - 1, 0, len(a) - 2)
        dx = x - a[i]
        return cum[i] + v[i] * dx + 0.5 * slope[i] * dx * dx

    def at(self, theta: np.ndarray) -> np.ndarray:
        """The value at ``theta`` (held outside the range)."""
        return self._raw(np.clip(np.asarray(theta, float), self.lo, self.hi))

    def integral(self, theta: np.ndarray) -> np.ndarray:
        """``int_0^theta`` of the held function."""
        theta = np.asarray(theta, float)

        def g(x):
            c = np.clip(x, self.lo, self.hi)
            return self._antiderivative(c) + self._raw(c) * (x - c)

        return g(theta) - g(np.zeros(1))[0]

    def extremes(self) -> tuple[float, float]:
        """Smallest and largest value over the range (dense grid, and the table's knots)."""
        x = np.linspace(self.lo, self.hi, _GRID)
        y = self.at(np.concatenate([x, np.asarray(self.angles, float)]))
        return float(np.min(y)), float(np.max(y))


def _horner(x: np.ndarray, coef) -> np.ndarray:
    """The polynomial with ascending coefficients ``coef`` at ``x`` (Horner's rule)."""
    coef = [float(c) for c in coef]
    y = np.full(np.shape(x), coef[-1])
    for c in reversed(coef[:-1]):
        y = y * x + c
    return y


def _nonempty(value: tuple[float, ...] | None) -> None:
    if value is not None and not value:
        raise ConfigError("expected a non-empty list of numbers, got []")


@dataclasses.dataclass(frozen=True)
class AngleSpec:
    """A function of the joint angle as written: ``{polynomial: [...]}`` or ``{angle: [...], value: [...]}``."""

    polynomial: tuple[float, ...] | None = param(None, doc="coefficients c0, c1, ... (ascending powers)")
    angle: tuple[float, ...] | None = param(None, unit="rad", doc="table: increasing angles")
    value: tuple[float, ...] | None = param(None, doc="table: the values at those angles")

    def __post_init__(self):
        for v in (self.polynomial, self.angle, self.value):
            _nonempty(v)


@JOINTS.register("position_dependent", tags=("lpv", "nonlinear"))
@dataclasses.dataclass(frozen=True)
class PositionDependentJoint:
    """Second-order joint whose stiffness (and damping) depend on the angle (module docstring).

    Parameters
    ----------
    I : float
        Inertia (kg·m²), > 0.
    K : number, polynomial or table
        Incremental stiffness K(theta) (N·m/rad), > 0 over ``angle_range``.
    B : number, polynomial or table, optional
        Damping B(theta) (N·m·s/rad), >= 0. Exactly one of ``B`` and ``damping_ratio``.
    damping_ratio : float, optional
        B(theta) = 2 zeta sqrt(K(theta) I).
    angle_range : [lo, hi]
        Angles (rad) over which K and B follow their description (held outside).
    """

    I: float = param(unit="kg.m2", gt=0, doc="inertia")
    K: Any = dataclasses.field(metadata={"doc": "stiffness K(theta): number, {polynomial: [...]} "
                                                             "or {angle: [...], value: [...]}"})
    B: Any = dataclasses.field(default=None, metadata={"doc": "damping B(theta), same forms (or damping_ratio)"})
    damping_ratio: float | None = param(None, ge=0, doc="constant damping ratio; B = 2 zeta sqrt(K(theta) I)")
    angle_range: tuple[float, ...] | None = param(None, unit="rad", doc="[lo, hi]: K and B are held outside")

    model: ClassVar[str] = "position_dependent"
    contact: ClassVar[None] = None
    time_invariant: ClassVar[bool] = False     # the truth's I, B, K are arrays (along the angle)
    nonlinear: ClassVar[bool] = True

    def __post_init__(self):
        if self.K is None:
            raise ConfigError("missing required key 'K'")
        if (self.B is None) == (self.damping_ratio is None):
            raise ConfigError("give exactly one of 'B' (number, polynomial or table) and 'damping_ratio'")
        rng = None
        if self.angle_range is not None:
            if len(self.angle_range) != 2 or not self.angle_range[0] < self.angle_range[1]:
                raise ConfigError(f"key 'angle_range': expected [lo, hi] with lo < hi (rad), "
                                  f"got {list(self.angle_range)}")
            rng = (float(self.angle_range[0]), float(self.angle_range[1]))
        K = AngleFunction.parse(self.K, "K", rng)
        object.__setattr__(self, "K", K)
        if self.angle_range is None:
            object.__setattr__(self, "angle_range", (K.lo, K.hi))
        rng = (float(self.angle_range[0]), float(self.angle_range[1]))
        k_lo, _ = K.extremes()
        if not k_lo > 0:
            raise ConfigError(f"key 'K': K(theta) reaches {k_lo:g} N.m/rad over angle_range {list(rng)}; "
                              f"it must stay > 0")
        if self.B is not None:
            B = AngleFunction.parse(self.B, "B", rng)
            object.__setattr__(self, "B", B)
            if not B.extremes()[0] >= 0:
                raise ConfigError(f"key 'B': B(theta) reaches {B.extremes()[0]:g} over angle_range {list(rng)}; "
                                  f"it must stay >= 0")

    # ------------------------------------------------------------------------- the angle dependence
    def stiffness_at(self, theta: np.ndarray) -> np.ndarray:
        """K(theta) (N·m/rad)."""
        return self.K.at(theta)

    def damping_at(self, theta: np.ndarray) -> np.ndarray:
        """B(theta) (N·m·s/rad)."""
        if self.B is not None:
            return self.B.at(theta)
        return 2.0 * self.damping_ratio * np.sqrt(self.K.at(theta) * self.I)

    def elastic_torque(self, theta: np.ndarray) -> np.ndarray:
        """P(theta) = int_0^theta K (N·m)."""
        return self.K.integral(theta)

    @property
    def stiffness_range(self) -> tuple[float, float]:
        """Smallest and largest K over the angle range (the stiffest instant a stability check needs)."""
        return self.K.extremes()

    # ------------------------------------------------------------------- what the backends integrate
    def coefficients_at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The linear part the backends integrate exactly: I, B(0), K(0) (the model at theta = 0)."""
        shape = np.shape(t)
        zero = np.zeros(1)
        return (np.full(shape, float(self.I)), np.full(shape, float(self.damping_at(zero)[0])),
                np.full(shape, float(self.K.at(zero)[0])))

    def remainder(self, theta: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        """Torque beyond the linear part: ``P(theta) - K(0) theta + (B(theta) - B(0)) theta'``."""
        theta = np.asarray(theta, float)
        zero = np.zeros(1)
        return (self.elastic_torque(theta) - self.K.at(zero)[0] * theta
                + (self.damping_at(theta) - self.damping_at(zero)[0]) * np.asarray(velocity, float))

    def state_coefficients(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The local linearization along the angle: (I, B(theta), K(theta)) (the truth's parameters)."""
        theta = np.asarray(theta, float)
        return np.full(theta.shape, float(self.I)), self.damping_at(theta), self.stiffness_at(theta)
