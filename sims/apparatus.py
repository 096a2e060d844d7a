"""Apparatus models: how the perturbation reaches the limb and what the torque sensor measures.

Each model is a small frozen dataclass selected by the ``kind`` key of the ``apparatus`` section.
The backends only use the linear :class:`Coupling` it declares, so a new apparatus needs no backend
change: the torque on the limb is ``T_a = g d + g_d d' - k_a theta - b_a theta'`` for drive signal d.
"""
from __future__ import annotations

import dataclasses
import types
from typing import ClassVar, Literal, Mapping

import numpy as np

from jointbench.errors import ConfigError
from jointbench.schema import param


@dataclasses.dataclass(frozen=True)
class Coupling:
    """Linear coupling of drive signal d and limb: ``T_a = g d + g_d d' - k_a theta - b_a theta'``.

    ``T_a`` is both the torque on the limb from the apparatus and what the torque sensor sees.
    """

    g: float
    g_d: float
    k_a: float
    b_a: float

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
        c = np.array([self.g_d, self.g])
        r = np.array([0.0, self.b_a, self.k_a])
        num = np.stack([np.convolve(c, z) for z in Z])
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

    @property
    def input_gain(self) -> float:
        """Actuator torque per unit drive signal (N·m/rad)."""
        return float(self.stiffness)

    @property
    def stiffness_on_angle(self) -> float:
        """Actuator torque per unit joint angle, with the sign of a restoring spring (N·m/rad)."""
        return float(self.stiffness)

    def actuator_torque(self, drive: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """T_a = K_a (theta_r - theta)."""
        return self.stiffness * (np.asarray(drive) - np.asarray(theta))

    def measured_torque(self, drive: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """The torque the load cell sees, before the sensor model: T_m = T_a."""
        return self.actuator_torque(drive, theta)


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

    @property
    def input_gain(self) -> float:
        return 1.0

    @property
    def stiffness_on_angle(self) -> float:
        return 0.0

    def actuator_torque(self, drive: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """T_a = T_p, independent of the angle."""
        return np.array(drive, dtype=float, copy=True)

    def measured_torque(self, drive: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """The measured torque is the applied torque T_p."""
        return self.actuator_torque(drive, theta)


@dataclasses.dataclass(frozen=True)
class Handle:
    """An ideally position-controlled handle: the handle angle is the drive signal (the measured angle),
    and the limb is coupled to it through the joint model's contact (``k_c``, ``b_c``); the torque
    sensor measures the contact torque ``b_c (u' - theta') + k_c (u - theta)``.

    Needs a joint model with a ``contact`` (e.g. ``wrist_contact``).

    References
    ----------
    van de Ruit et al. 2018, eqs. 11-13 and Fig. 2 (handle angle u as input, handle torque y as output).
    """

    kind: ClassVar[str] = "handle"
    imposed: ClassVar[Literal["angle", "torque"]] = "angle"
    angle_is_drive: ClassVar[bool] = True

    def coupling(self, joint=None) -> Coupling:
        contact = getattr(joint, "contact", None)
        if contact is None:
            raise ConfigError(f"apparatus 'handle' needs a joint model with a contact (k_c, b_c), e.g. "
                              f"'wrist_contact'; got {type(joint).__name__}")
        k_c, b_c = contact
        return Coupling(g=k_c, g_d=b_c, k_a=k_c, b_a=b_c)


Apparatus = PositionServo | TorqueDrive | Handle

#: ``kind`` -> apparatus dataclass
APPARATUS_KINDS: Mapping[str, type] = types.MappingProxyType(
    {"position_servo": PositionServo, "torque_drive": TorqueDrive, "handle": Handle})
