"""Gravity on the limb segment: the tau_g(theta) of Xu & Hollerbach's eq. 1.

The segment (forearm and hand) moves in a vertical plane. With its mass m at the distance l from the
joint, and ``posture`` the angle of theta = 0 measured from hanging straight down,

    tau_g(theta) = -m g l sin(posture + theta),   K_g(theta) = -d tau_g / d theta = m g l cos(posture + theta).

By the paper's linearization (eq. 2, K(t) = -d(tau_m + tau_g)/d theta), an identification sees the
joint's own stiffness plus K_g: positive (stabilising) below the horizontal, zero at it, negative above.
The subject holds the posture: the experiment adds -tau_g(theta_n(t)) to the voluntary torque, so that the
intended trajectory theta_n stays the unperturbed one. Only a physics backend simulates gravity; the
analytic backends refuse an experiment with it.

References
----------
Xu & Hollerbach 1998, eqs. 1-2 (Sec. II-A) and Sec. IV (movements in a vertical plane).
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from jointbench.core.errors import ConfigError
from jointbench.core.schema import param


@dataclasses.dataclass(frozen=True)
class Gravity:
    """Gravity on the moving segment.

    Parameters
    ----------
    mass : float
        Mass of the segment (kg), e.g. forearm and hand 1.6 kg.
    com_distance : float
        Distance from the joint axis to the segment's centre of mass (m).
    posture : float
        Angle of theta = 0 from hanging straight down (rad; 90 deg = horizontal).
    g : float
        Gravitational acceleration (m/s²).
    """

    mass: float = param(unit="kg", gt=0, doc="mass of the moving segment")
    com_distance: float = param(unit="m", gt=0, doc="distance from the joint to its centre of mass")
    posture: float = param(0.0, unit="rad", doc="angle of theta = 0 from hanging straight down")
    g: float = param(9.81, unit="m/s2", gt=0, doc="gravitational acceleration")

    @property
    def moment(self) -> float:
        """m g l (N·m): the largest gravity torque and the gravity stiffness hanging down."""
        return float(self.mass * self.g * self.com_distance)

    def torque(self, theta: np.ndarray) -> np.ndarray:
        """tau_g(theta) = -m g l sin(posture + theta) (N·m)."""
        return -self.moment * np.sin(self.posture + np.asarray(theta, float))

    def stiffness(self, theta: np.ndarray) -> np.ndarray:
        """K_g(theta) = m g l cos(posture + theta) (N·m/rad), what gravity adds to the joint's stiffness."""
        return self.moment * np.cos(self.posture + np.asarray(theta, float))

    def check(self, inertia: float, where: str) -> None:
        """The segment's inertia about the joint must exceed that of its mass at the centre of mass."""
        point = self.mass * self.com_distance ** 2
        if not inertia > point:
            raise ConfigError(f"{where}: gravity: the joint's inertia {inertia:g} kg.m2 is not above m l^2 = "
                              f"{point:g} kg.m2 of a {self.mass:g} kg segment with its centre of mass at "
                              f"{self.com_distance:g} m; lower 'com_distance' or 'mass'")
        if not math.isfinite(self.posture):
            raise ConfigError(f"{where}: gravity: key 'posture' must be finite")
