"""Voluntary torque T_v: the subject's own torque, a disturbance to the identification (Fig. 1)."""
from __future__ import annotations

import dataclasses

import numpy as np
from scipy import signal as sps

from jointbench.errors import ConfigError
from jointbench.schema import param
from sims.perturbation_filtered_noise import scale_to_rms


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

    @property
    def active(self) -> bool:
        """True when T_v is not identically zero."""
        return self.mean != 0 or self.rms > 0

    def check(self, fs: float, where: str) -> None:
        """Raise :class:`ConfigError` if the settings cannot be realised at ``fs``."""
        if self.rms > 0 and not self.cutoff < fs / 2:
            raise ConfigError(f"{where}: key 'cutoff': must be below fs_sim / 2 = {fs / 2:g} Hz, "
                              f"got {self.cutoff:g} Hz")

    def generate(self, n: int, fs: float, rng: np.random.Generator) -> np.ndarray:
        """``n`` samples of T_v at ``fs`` Hz (N·m), drawn from the voluntary torque's own stream ``rng``."""
        tv = np.full(n, float(self.mean))
        if self.rms > 0:
            sos = sps.butter(2, self.cutoff, btype="low", fs=fs, output="sos")
            tv += scale_to_rms(sps.sosfilt(sos, rng.standard_normal(n)), self.rms)
        return tv
