"""Apparatus models: how the perturbation reaches the limb and what the torque sensor measures.

Each model is a small frozen dataclass selected by the ``kind`` key of the ``apparatus`` section.
Its one interface to the backends is the linear :class:`Coupling` it declares: the torque on the limb
is ``T_a = g d + g_d d' - k_a theta - b_a theta'`` for drive signal d, and every backend (``lti``,
``ltv``, ``mujoco``) builds its input from :meth:`Coupling.drive_input`, so no backend can drop a term
(a servo damping, the contact damping of a handle).
"""
from __future__ import annotations

import dataclasses
import types
from typing import ClassVar, Literal, Mapping

import numpy as np

from jointbench.core.errors import ConfigError, Incompatible
from jointbench.core.schema import param


def derivative(d: np.ndarray, h: float) -> np.ndarray:
    """d' at the samples: fourth-order central differences (second order at the two samples at each end).

    The drive's derivative enters through a damped contact (``g_d``, e.g. the hand's b_c): the measured
    torque is then a small difference of large contact terms, and a derivative that is only second-order
    accurate (or the piecewise-constant slope of a linearly held drive, which lags by half a step) shows
    up amplified by |b_c ω / Z(ω)|, about 200 near the wrist's resonance (tens of percent at 2.5 kHz).
    """
    out = np.gradient(d, h, edge_order=2)
    if len(d) >= 5:
        out[2:-2] = (d[:-4] - 8 * d[1:-3] + 8 * d[3:-1] - d[4:]) / (12 * h)
    return out


@dataclasses.dataclass(frozen=True)
class Coupling:
    """Linear coupling of drive signal d and limb: ``T_a = g d + g_d d' - k_a theta - b_a theta'``.

    ``T_a`` is both the torque on the limb from the apparatus and what the torque sensor sees.
    """

    g: float
    g_d: float
    k_a: float
    b_a: float

    def drive_input(self, d: np.ndarray, fs: float) -> tuple[np.ndarray, np.ndarray]:
        """``(g d + g_d d', d')``: the part of T_a that does not depend on the limb, and the drive's
        derivative (:func:`derivative`; zeros when ``g_d`` is 0)."""
        d = np.asarray(d, float)
        d_dot = derivative(d, 1.0 / fs) if self.g_d else np.zeros_like(d)
        return self.g * d + self.g_d * d_dot, d_dot

    def torque(self, d: np.ndarray, d_dot: np.ndarray, theta: np.ndarray, theta_dot: np.ndarray) -> np.ndarray:
        """T_a for the given drive, its derivative, and the limb's angle and velocity."""
        return self.g * d + self.g_d * d_dot - self.k_a * theta - self.b_a * theta_dot

    def frozen_response(self, Z: np.ndarray, imposed: str, angle_is_drive: bool) -> tuple[np.ndarray, np.ndarray]:
        """(num, den) of the transfer from the measured input to the measured output, as polynomials in s
        (highest power first, last axis), given the limb impedance polynomial ``Z`` = [I, B, K] per row.

        - torque drive (input torque, output angle): 1 / Z;
        - angle measured on the limb (position servo): Z, whatever the servo;
        - angle measured on the drive (handle): c Z / (Z + r), c = g_d s + g, r = b_a s + k_a.
        """
        Z = np.atleast_2d(Z)
        one = np.ones((len(Z), 1))
        if imposed == "torque":
            return one, Z
        if not angle_is_drive:
            return Z, one
        r = np.array([0.0, self.b_a, self.k_a])
        num = np.zeros((len(Z), Z.shape[1] + 1))      # (g_d s + g) Z, row by row (np.convolve's sums)
        num[:, :-1] = self.g_d * Z
        num[:, 1:] += self.g * Z
        return num, Z + r


@dataclasses.dataclass(frozen=True)
class PositionServo:
    """Position servo of finite stiffness: ``T_a = K_a (theta_r - theta)``, measured torque ``T_m = T_a``.

    The servo is the constant gain K_a of Fig. 1, standing for a servo whose bandwidth is far above the
    limb's. The drive signal is the position command theta_r (rad).

    Parameters
    ----------
    stiffness : float
        Servo stiffness K_a (N·m/rad), default 30 000 (the apparatus of Sec. IV).

    References
    ----------
    Westwick & Perreault 2012, Fig. 1 and eqs. 3-8 (Sec. II-A); Sec. IV (30 000 N·m/rad).
    """

    stiffness: float = param(30000.0, unit="N.m/rad", gt=0, doc="servo stiffness K_a")
    damping: float = param(0.0, unit="N.m.s/rad", ge=0, doc="servo damping B_a (T_a += B_a (theta_r' - theta'))")

    kind: ClassVar[str] = "position_servo"
    imposed: ClassVar[Literal["angle", "torque"]] = "angle"
    angle_is_drive: ClassVar[bool] = False

    def coupling(self, joint=None) -> Coupling:
        """``T_a = K_a (theta_r - theta) + B_a (theta_r' - theta')``."""
        return Coupling(g=self.stiffness, g_d=self.damping, k_a=self.stiffness, b_a=self.damping)


@dataclasses.dataclass(frozen=True)
class TorqueDrive:
    """Torque drive: the perturbation is a torque applied to the limb and is what the sensor measures.

    References
    ----------
    Xu & Hollerbach 1998, eq. 7 (torque-driven elbow); studies spec section A.
    """

    kind: ClassVar[str] = "torque_drive"
    imposed: ClassVar[Literal["angle", "torque"]] = "torque"
    angle_is_drive: ClassVar[bool] = False

    def coupling(self, joint=None) -> Coupling:
        """``T_a = T_p``."""
        return Coupling(g=1.0, g_d=0.0, k_a=0.0, b_a=0.0)


@dataclasses.dataclass(frozen=True)
class Handle:
    """A position-controlled handle coupled to the limb through the joint model's contact (``k_c``,
    ``b_c``); the torque sensor measures the contact torque ``b_c (u' - theta') + k_c (u - theta)``.

    Ideal by default: the handle angle u is the drive signal (and the measured angle), as in the paper's
    model. A physics backend can give the handle its own dynamics instead: a hinge of inertia
    ``inertia`` driven by a position servo (``servo_stiffness``, ``servo_damping``) towards the drive
    signal; the measured angle is then the handle's own angle. The analytic backends simulate only the
    ideal handle and refuse these settings rather than ignore them.

    Needs a joint model with a ``contact`` (e.g. ``wrist_contact``).

    Parameters
    ----------
    inertia : float, optional
        The handle's own inertia (kg·m²) about its axis; none = ideal handle.
    servo_stiffness, servo_damping : float, optional
        Gains of the handle's position servo (N·m/rad, N·m·s/rad); with ``inertia``.

    References
    ----------
    van de Ruit et al. 2018, eqs. 11-13 and Fig. 2 (handle angle u as input, handle torque y as output).
    """

    inertia: float | None = param(None, unit="kg.m2", gt=0, doc="the handle's own inertia; none = ideal handle")
    servo_stiffness: float | None = param(None, unit="N.m/rad", gt=0, doc="stiffness of the handle's servo")
    servo_damping: float | None = param(None, unit="N.m.s/rad", ge=0, doc="damping of the handle's servo")

    kind: ClassVar[str] = "handle"
    imposed: ClassVar[Literal["angle", "torque"]] = "angle"
    angle_is_drive: ClassVar[bool] = True

    def __post_init__(self):
        given = [self.inertia is not None, self.servo_stiffness is not None, self.servo_damping is not None]
        if any(given) and not all(given):
            raise ConfigError("a handle with its own dynamics needs all of 'inertia', 'servo_stiffness' and "
                              "'servo_damping' (leave all three out for an ideal handle)")

    @property
    def dynamics(self) -> str:
        """'' for the ideal handle, else a description of the settings only a physics backend models."""
        if self.inertia is None:
            return ""
        return (f"inertia {self.inertia:g} kg.m2 and servo ({self.servo_stiffness:g} N.m/rad, "
                f"{self.servo_damping:g} N.m.s/rad)")

    def coupling(self, joint=None) -> Coupling:
        contact = getattr(joint, "contact", None)
        if contact is None:
            raise Incompatible(f"apparatus 'handle' needs a joint model with a contact (k_c, b_c), e.g. "
                              f"'wrist_contact'; got {type(joint).__name__}")
        k_c, b_c = contact
        return Coupling(g=k_c, g_d=b_c, k_a=k_c, b_a=b_c)


Apparatus = PositionServo | TorqueDrive | Handle

#: ``kind`` -> apparatus dataclass
APPARATUS_KINDS: Mapping[str, type] = types.MappingProxyType(
    {"position_servo": PositionServo, "torque_drive": TorqueDrive, "handle": Handle})
