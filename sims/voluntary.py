"""Voluntary torque T_v: the subject's own torque, a disturbance to the identification (Fig. 1)."""
from __future__ import annotations

import dataclasses

import numpy as np
from jointbench.core.lazy import scipy_signal as sps   # imported on first use: 0.6 CPU-s with scipy.stats

from jointbench.core.errors import ConfigError
from jointbench.core.schema import param
from jointbench.sims.perturbation_filtered_noise import scale_to_rms


@dataclasses.dataclass(frozen=True)
class Voluntary:
    """Voluntary torque ``T_v = mean + n(t)``, ``n`` Gaussian white noise through a 2nd-order Butterworth
    low-pass at ``cutoff``, scaled to the exact rms ``rms`` over the record.

    The low-pass is designed digitally at the simulation rate (``scipy.signal.butter(2, cutoff, fs=fs_sim)``)
    and run causally from rest. The mean is present from t = 0; the start-up transient it causes is
    one of those that ``acquisition.trim`` removes.

    Parameters
    ----------
    mean : float
        Constant part (N·m), e.g. the flexion torque held by the subject.
    rms : float
        Rms of the fluctuating part (N·m); 0 = none.
    cutoff : float
        -3 dB frequency of the fluctuations (Hz).

    References
    ----------
    Westwick & Perreault 2012, Fig. 1 and eqs. 3-8 (T_v enters the measured torque with gain about -1);
    Sec. IV (subject holding 5 % of maximum voluntary contraction).
    """

    mean: float = param(0.0, unit="N.m", doc="constant voluntary torque")
    rms: float = param(0.0, unit="N.m", ge=0, doc="rms of the low-passed noise part")
    cutoff: float = param(1.0, unit="Hz", gt=0, doc="-3 dB frequency of the noise part")
    movement_amplitude: float = param(0.0, unit="rad", ge=0, doc="amplitude of a voluntary sinusoidal movement")
    movement_frequency: float | None = param(None, unit="Hz", gt=0, doc="its frequency")

    def __post_init__(self):
        if self.movement_amplitude > 0 and self.movement_frequency is None:
            raise ConfigError("key 'movement_frequency': needed when movement_amplitude > 0")

    @property
    def active(self) -> bool:
        """True when T_v is not identically zero."""
        return self.mean != 0 or self.rms > 0 or self.moving

    @property
    def moving(self) -> bool:
        """True when the subject makes a voluntary movement."""
        return self.movement_amplitude > 0

    def movement(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The intended trajectory ``theta_n = A sin(2π f t)`` and its first two derivatives (rad, rad/s,
        rad/s²) at times ``t``; zeros when there is no movement.

        The voluntary torque that makes ``theta_n`` the unperturbed trajectory is
        ``I theta_n'' + B(t) theta_n' + K(t) theta_n`` (plus the apparatus' restoring terms); the
        experiment adds it to the torque from :meth:`generate`.

        References
        ----------
        Xu & Hollerbach 1998, Sec. IV-A (voluntary movement theta_n = 0.5 sin 2π f_v t).
        """
        t = np.asarray(t, float)
        if not self.moving:
            z = np.zeros_like(t)
            return z, z, z
        w = 2 * np.pi * float(self.movement_frequency)
        a = float(self.movement_amplitude)
        s = np.sin(w * t)
        return a * s, a * w * np.cos(w * t), -a * w * w * s

    def position(self, t: np.ndarray) -> np.ndarray:
        """The intended trajectory ``theta_n`` alone (rad): the first output of :meth:`movement`, without
        computing the derivatives (bit-identical to it).

        References
        ----------
        Xu & Hollerbach 1998, Sec. IV-A (voluntary movement theta_n = 0.5 sin 2π f_v t).
        """
        t = np.asarray(t, float)
        if not self.moving:
            return np.zeros_like(t)
        return float(self.movement_amplitude) * np.sin(2 * np.pi * float(self.movement_frequency) * t)

    def check(self, fs: float, where: str) -> None:
        """Raise :class:`ConfigError` if the settings cannot be realised at ``fs``."""
        if self.moving and not self.movement_frequency < fs / 2:
            raise ConfigError(f"{where}: key 'movement_frequency': must be below fs_sim / 2 = {fs / 2:g} Hz")
        if self.rms > 0 and not self.cutoff < fs / 2:
            raise ConfigError(f"{where}: key 'cutoff': must be below fs_sim / 2 = {fs / 2:g} Hz, "
                              f"got {self.cutoff:g} Hz")

    def generate(self, n: int, fs: float, rng: np.random.Generator) -> np.ndarray:
        """``n`` samples of T_v at ``fs`` Hz (N·m), drawn from the voluntary torque's own stream ``rng``
        (constant and noise parts; the movement's torque depends on the joint and is added by the experiment)."""
        tv = np.full(n, float(self.mean))
        if self.rms > 0:
            sos = sps.butter(2, self.cutoff, btype="low", fs=fs, output="sos")
            tv += scale_to_rms(sps.sosfilt(sos, rng.standard_normal(n)), self.rms)
        return tv
