"""A JointBench plugin: I(t), B(t), K(t) by least squares in a sliding window.

The simplest time-varying parametric estimator: angle and torque are low-passed (zero phase), the angle
differentiated, and ``tau = I theta'' + B theta' + K theta`` fitted by least squares over the samples of a
window centred on each sample. Short windows follow fast changes and pay in noise; long ones average
them away: the trade-off every time-varying method makes (Xu & Hollerbach 1998 weight their least
squares exponentially instead, FSEWLS). It is here to show how an outside method enters the benchmark:
a class registered with :func:`jointbench.estimators.register`, an entry point in ``pyproject.toml``.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import scipy.signal as sps

from jointbench.core.errors import InputError
from jointbench.core.estimate import ParametricEstimate, Prediction
from jointbench.estimators import Estimator, register
from jointbench.core.schema import Tune, param

__version__ = "0.1.0"


def regressors(trial, cutoff: float) -> tuple[np.ndarray, np.ndarray]:
    """(phi, tau): ``[theta'', theta', theta]`` (n x 3) and the torque, both low-passed at ``cutoff``."""
    fs = trial.fs
    sos = sps.butter(4, cutoff, fs=fs, output="sos")
    theta = sps.sosfiltfilt(sos, trial.angle - trial.angle.mean())
    tau = sps.sosfiltfilt(sos, trial.torque - trial.torque.mean())
    d1 = np.gradient(theta, 1 / fs)
    return np.stack([np.gradient(d1, 1 / fs), d1, theta], axis=1), tau


@dataclasses.dataclass(eq=False)
class SlidingEstimate(ParametricEstimate):
    """I(t), B(t), K(t) with the prediction they were fitted for: the low-passed torque."""

    cutoff: float = 20.0
    edge: int = 0

    def prediction(self, trial, index: int = 0) -> Prediction:
        phi, tau = regressors(trial, self.cutoff)
        n = min(len(tau), len(self.time))
        x = np.stack([np.broadcast_to(np.asarray(v, float), (len(self.time),)) for v in (self.I, self.B, self.K)], 1)
        used = np.zeros(len(tau), bool)
        used[self.edge:n - self.edge] = True
        yhat = np.zeros(len(tau))
        yhat[:n] = np.einsum("ni,ni->n", phi[:n], x[:n])
        return Prediction(tau, yhat, used, f"torque against I(t) theta'' + B(t) theta' + K(t) theta, both low-passed "
                                           f"to {self.cutoff:g} Hz (zero phase), without the first and last "
                                           f"{self.edge} samples (half a window)")


@register("sliding_ibk", tags=("time-varying", "plugin"))
class SlidingIBK(Estimator):
    """I(t), B(t), K(t) by least squares in a sliding window (a plugin example)."""

    accepts = frozenset({"trial"})

    @dataclasses.dataclass(frozen=True)
    class Settings:
        # the smoothing setting (short windows follow fast changes and pay in noise): a comparison's tuned
        # column tries the configured window, half and twice it (Tune's default factors), with no study edit
        window: float = param(0.4, unit="s", gt=0, doc="length of the window centred on each sample", tune=Tune())
        cutoff: float = param(20.0, unit="Hz", gt=0, doc="zero-phase low-pass of angle and torque before "
                                                         "differentiating (4th-order Butterworth)")

    def _fit(self, trials):
        trial = trials[0]
        fs, n = trial.fs, trial.n
        half = int(round(self.settings.window * fs / 2))
        if 2 * half + 1 < 6 or 2 * half + 1 > n:
            raise InputError(f"{self.name}: window = {self.settings.window:g} s is {2 * half + 1} samples at "
                             f"{fs:g} Hz; need 6 to {n} (the record)")
        if not self.settings.cutoff < fs / 2:
            raise InputError(f"{self.name}: cutoff = {self.settings.cutoff:g} Hz must be below fs/2 = {fs / 2:g} Hz")
        phi, tau = regressors(trial, self.settings.cutoff)
        # windowed sums of phi' phi and phi' tau for every centre sample, from cumulative sums
        outer = np.concatenate([np.zeros((1, 3, 3)), np.cumsum(phi[:, :, None] * phi[:, None, :], axis=0)])
        cross = np.concatenate([np.zeros((1, 3)), np.cumsum(phi * tau[:, None], axis=0)])
        lo = np.clip(np.arange(n) - half, 0, n)
        hi = np.clip(np.arange(n) + half + 1, 0, n)
        A = outer[hi] - outer[lo]
        b = cross[hi] - cross[lo]
        scale = np.maximum(np.einsum("nii->ni", A), 1e-300)            # column scaling: I, B, K differ by 1e4
        s = 1 / np.sqrt(scale)
        x = np.linalg.solve(A * s[:, :, None] * s[:, None, :], (b * s)[..., None])[..., 0] * s
        return SlidingEstimate(I=x[:, 0], B=x[:, 1], K=x[:, 2], fs=fs, time=trial.time, estimator=self.name,
                               band_hz=(0.0, self.settings.cutoff), cutoff=self.settings.cutoff, edge=half)
