"""Reflex pathway ``stretch``: delayed joint velocity -> static nonlinearity -> activation -> torque.

The stretch reflex of a joint as Kearney, Stein & Parameswaran (1997) and Mirbagheri et al. (2000)
identify it at the ankle: the joint velocity, delayed by the reflex loop's transport time, passes a
static nonlinearity resembling a half-wave rectifier (only stretch of the reflexively active muscle
excites it) and a second-order low-pass that stands for the muscle's activation dynamics; the result is
a torque that adds to the intrinsic torque and resists the stretch::

    T_r(t) = sigma * H * [ G(t) N(sigma theta'(t - delta)) ]
    H(s)   = omega^2 / (s^2 + 2 zeta omega s + omega^2)          (unit static gain)
    N(x)   = max(x, 0) (half_wave) or x (none)

``sigma`` is +1 when positive velocities stretch the muscle (``stretch: positive``) and -1 otherwise,
``G(t)`` the reflex gain (N·m·s/rad: torque per rad/s of rectified velocity), any time-variation
profile of :mod:`sims.profile`, applied to the activation's input (a modulated reflex drive).

In a config the pathway sits in the joint's mapping (every joint model takes it)::

    joint:
      model: second_order
      I: 0.015 kg.m2
      ...
      reflex: {pathway: stretch, gain: 5 N.m.s/rad, delay: 40 ms, frequency: 3.2 Hz, damping_ratio: 0.7}

The reflex makes the plant nonlinear; backends integrate it with a time-stepping path
(:mod:`sims.backend_stepping`, the physics backend step by step): the pathway's torque over the next
``delay`` seconds depends only on velocities already simulated, so it is computed ahead, a window at a
time, by :class:`ReflexStepper`.

References
----------
Kearney, R. E., Stein, R. B. & Parameswaran, L. (1997). Identification of intrinsic and reflex
contributions to human ankle stiffness dynamics. IEEE Trans. Biomed. Eng. 44(6), 493-504 (the
parallel-cascade model: delay, half-wave rectifier, second-order low-pass).
Mirbagheri, M. M., Barbeau, H. & Kearney, R. E. (2000). Intrinsic and reflex contributions to human ankle
stiffness: variation with activation level and position. Exp. Brain Res. 135(4), 423-436.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar, Literal

import numpy as np
from jointbench.core.lazy import scipy_signal as sps

from jointbench.core.errors import ConfigError
from jointbench.core.schema import number, param
from jointbench.sims.registries import REFLEXES
from jointbench.sims.profile import parse_profile


@REFLEXES.register("stretch")
@dataclasses.dataclass(frozen=True)
class StretchReflex:
    """Stretch-reflex pathway: delay, static nonlinearity, second-order activation, gain (module docstring).

    Parameters
    ----------
    gain : float or profile
        G(t), N·m·s/rad (torque per rad/s of rectified delayed velocity), >= 0 at all times; 0 = no reflex
        torque (the pathway is still simulated, by the same path). A constant may carry its unit
        (``5 N.m.s/rad``); a profile's numbers are plain (N·m·s/rad).
    delay : float
        Reflex loop delay delta (s), at least one simulation step.
    nonlinearity : {'half_wave', 'none'}
        Static nonlinearity N: a half-wave rectifier of the stretch velocity, or none (a linear pathway).
    stretch : {'positive', 'negative'}
        Which sign of the joint velocity stretches the reflexively active muscle (sigma = +1 or -1).
    frequency : float
        Natural frequency omega / 2 pi of the activation low-pass (Hz).
    damping_ratio : float
        Its damping ratio zeta.
    """

    gain: Any = dataclasses.field(metadata={"doc": "reflex gain G(t), N.m.s/rad: number or profile (0: no torque)"})
    delay: float = param(0.04, unit="s", gt=0, doc="reflex loop delay")
    nonlinearity: Literal["half_wave", "none"] = param("half_wave", doc="static nonlinearity of the velocity")
    stretch: Literal["positive", "negative"] = param("positive", doc="velocity sign that stretches the muscle")
    frequency: float = param(3.2, unit="Hz", gt=0, doc="natural frequency of the activation low-pass")
    damping_ratio: float = param(0.7, gt=0, doc="damping ratio of the activation low-pass")

    pathway: ClassVar[str] = "stretch"

    def __post_init__(self):
        if self.gain is None:
            raise ConfigError("missing required key 'gain' (N.m.s/rad; 0 for a pathway without torque)")
        gain = self.gain
        if isinstance(gain, str):         # a constant with its unit, e.g. '5 N.m.s/rad'
            gain = number(gain, "N.m.s/rad", "reflex", "gain")
        object.__setattr__(self, "gain", parse_profile(gain, "key 'gain'"))
        if not self.gain.minimum >= 0:
            raise ConfigError(f"key 'gain': the profile reaches {self.gain.minimum:g}; a reflex gain must stay >= 0 "
                              f"(the pathway's sign is set by 'stretch')")

    @property
    def sign(self) -> float:
        """sigma: +1 when positive velocities stretch the muscle, -1 otherwise."""
        return 1.0 if self.stretch == "positive" else -1.0

    def check(self, fs_sim: float, duration: float, where: str, min_steps: int = 1) -> None:
        """Raise :class:`ConfigError` when the delay is shorter than ``min_steps`` simulation steps, or the
        activation is too fast for the simulation rate."""
        if self.delay * fs_sim < min_steps - 1e-9:
            raise ConfigError(f"{where}: key 'delay': {self.delay * 1e3:g} ms is shorter than {min_steps} simulation "
                              f"step(s) ({min_steps / fs_sim * 1e3:g} ms at fs_sim = {fs_sim:g} Hz); the time-stepping "
                              f"path computes the reflex torque ahead by its delay")
        if self.delay >= duration:
            raise ConfigError(f"{where}: key 'delay': {self.delay:g} s is not shorter than the record ({duration:g} s)")
        if not self.frequency < fs_sim / 10:
            raise ConfigError(f"{where}: key 'frequency': {self.frequency:g} Hz must stay below fs_sim / 10 = "
                              f"{fs_sim / 10:g} Hz")

    def gain_at(self, t: np.ndarray) -> np.ndarray:
        """G(t) at times ``t`` (s)."""
        return self.gain.at(np.asarray(t, float))

    def afferent(self, velocity: np.ndarray) -> np.ndarray:
        """N(sigma theta'): the rectified (or plain) stretch velocity."""
        x = self.sign * np.asarray(velocity, float)
        return np.maximum(x, 0.0) if self.nonlinearity == "half_wave" else x

    def activation(self, fs: float) -> tuple[np.ndarray, np.ndarray]:
        """``(b, a)`` of the activation low-pass discretized exactly for an input held linearly between
        samples (first-order hold; :func:`sims.backend_lti.foh`), in powers of z^-1."""
        from jointbench.sims.backend_lti import transfer_coefficients, foh

        w = 2.0 * math.pi * self.frequency
        A = np.array([[0.0, 1.0], [-w * w, -2.0 * self.damping_ratio * w]])
        B = np.array([[0.0], [w * w]])
        num, den = transfer_coefficients(*foh(A, B, 1.0 / fs))
        return num[0, 0], den

    def torque(self, velocity: np.ndarray, fs: float, t0: float = 0.0, v_before: float = 0.0) -> np.ndarray:
        """The reflex torque for a whole velocity record at ``fs`` (what :class:`ReflexStepper` computes a
        window at a time): from rest, the velocity before the record equal to ``v_before``."""
        st = ReflexStepper(self, fs, len(velocity), t0, v_before)
        st.advance(len(velocity), np.asarray(velocity, float))
        return st.torque


class ReflexStepper:
    """The reflex torque of :class:`StretchReflex`, computed ahead a window at a time.

    ``T_r[k]`` needs the velocity up to sample ``k - d`` (``d = floor(delay fs)``; a fractional delay is
    read by linear interpolation between the two samples around ``t_k - delay``), so once the
    velocities up to sample ``j`` are known, the torque up to sample ``j + d`` is. :meth:`advance` extends
    the torque to a requested sample; the activation low-pass carries its state between calls, so the
    numbers do not depend on how the record is cut into windows.
    """

    def __init__(self, reflex: StretchReflex, fs: float, n: int, t0: float = 0.0, v_before: float = 0.0):
        self.reflex = reflex
        x = reflex.delay * fs
        self.d = int(math.floor(x + 1e-9))
        self.frac = max(0.0, x - self.d) if abs(x - round(x)) > 1e-9 else 0.0
        if self.d < 1:
            raise ConfigError(f"reflex delay {reflex.delay:g} s is shorter than one step at {fs:g} Hz")
        self.fs = fs
        self.gain = reflex.gain_at(t0 + np.arange(n) / fs)
        self.b, self.a = reflex.activation(fs)
        self.zi = np.zeros(2)
        self.v_before = float(v_before)
        self.torque = np.zeros(n)
        self.done = 0          # torque known for samples < done

    @property
    def lookahead(self) -> int:
        """How many samples beyond the last known velocity the torque is known: the delay in whole steps
        (one less with a fractional part: the interpolation reads the sample after it)."""
        return self.d

    def advance(self, stop: int, velocity: np.ndarray) -> None:
        """Compute the torque for samples ``done ... stop - 1`` from ``velocity`` (which must hold the
        samples up to ``stop - 1 - d``)."""
        stop = min(stop, len(self.torque))
        if stop <= self.done:
            return
        k = np.arange(self.done, stop)
        i0 = k - self.d                      # t_k - delay lies between samples i0 - 1 and i0 (frac from i0)
        v0 = np.where(i0 >= 0, velocity[np.clip(i0, 0, None)], self.v_before)
        if self.frac:
            i1 = i0 - 1
            v1 = np.where(i1 >= 0, velocity[np.clip(i1, 0, None)], self.v_before)
            v0 = (1.0 - self.frac) * v0 + self.frac * v1
        drive = self.gain[k] * self.reflex.afferent(v0)
        y, self.zi = sps.lfilter(self.b, self.a, drive, zi=self.zi)
        self.torque[self.done:stop] = self.reflex.sign * y
        self.done = stop
