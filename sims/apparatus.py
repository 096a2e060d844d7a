"""Apparatus models: how the perturbation reaches the limb and what the torque sensor measures.

Each model is a small frozen dataclass selected by the ``kind`` key of the ``apparatus`` section.
The backends only use the linear coupling it declares, so a new apparatus needs no backend change:
the actuator torque on the limb is ``T_a = input_gain * drive - stiffness_on_angle * theta``.
"""
from __future__ import annotations

import dataclasses
import types
from typing import ClassVar, Literal, Mapping

import numpy as np

from jointbench.schema import param


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

    kind: ClassVar[str] = "position_servo"
    imposed: ClassVar[Literal["angle", "torque"]] = "angle"

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


Apparatus = PositionServo | TorqueDrive

#: ``kind`` -> apparatus dataclass
APPARATUS_KINDS: Mapping[str, type] = types.MappingProxyType(
    {"position_servo": PositionServo, "torque_drive": TorqueDrive})
