"""The data a simulator produces and an estimator consumes: :class:`Trial` and its :class:`Truth`."""
from __future__ import annotations

import copy
import dataclasses
from typing import Literal, Mapping

import numpy as np

from jointbench.core.errors import InputError, JointBenchError

Imposed = Literal["angle", "torque"]


def _as_series(name: str, x, where: str) -> np.ndarray:
    if np.iscomplexobj(x):
        raise InputError(f"{where}: '{name}' is complex; give real values (its real part, np.real, or its "
                         f"magnitude, np.abs, whichever the record means)")
    try:
        a = np.asarray(x, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{where}: '{name}' is not numeric") from None
    if a.ndim != 1:
        a = np.squeeze(a)
    if a.ndim != 1:
        raise InputError(f"{where}: '{name}' must be one-dimensional, got shape {np.shape(x)}")
    bad = ~np.isfinite(a)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(f"{where}: '{name}' has {int(bad.sum())} non-finite value(s) (NaN or inf), "
                         f"first at sample {i}")
    return a


@dataclasses.dataclass(frozen=True)
class Truth:
    """What the simulator knows and an estimator must not see.

    Attributes
    ----------
    I, B, K : float or ndarray
        Inertia (kg·m²), damping (N·m·s/rad) and stiffness (N·m/rad); arrays (one value per sample of
        the trial) when they vary in time.
    signals : mapping of str to ndarray
        Noise-free signals on the trial's time base, e.g. ``"torque"`` (impedance torque without
        voluntary torque and sensor noise) and ``"angle"``.
    """

    I: float | np.ndarray
    B: float | np.ndarray
    K: float | np.ndarray
    signals: Mapping[str, np.ndarray] = dataclasses.field(default_factory=dict)
    num: np.ndarray | None = None
    den: np.ndarray | None = None

    def at(self, name: str, t: np.ndarray, time: np.ndarray) -> np.ndarray:
        """Parameter ``name`` ('I', 'B' or 'K') at times ``t`` (interpolated when time-varying)."""
        v = getattr(self, name)
        if np.ndim(v) == 0:
            return np.full(np.shape(t), float(v))
        return np.interp(t, time, v)

    def frozen_response(self, f: np.ndarray, t: np.ndarray | float | None = None,
                        time: np.ndarray | None = None) -> np.ndarray:
        """The true frozen frequency response from the trial's input to its output.

        ``num`` and ``den`` hold the coefficients (highest power of s first) of the rational transfer
        function ``num(s) / den(s)`` from ``Trial.input`` to ``Trial.output``: shape ``(p,)`` when
        constant, ``(n, p)`` (one row per trial sample) when time-varying. The frozen response at time
        ``t`` uses the coefficients at ``t`` (linear interpolation on ``time``).

        Parameters
        ----------
        f : array_like
            Frequencies (Hz).
        t : float or array_like, optional
            Times (s); needed when the coefficients vary in time.
        time : ndarray, optional
            The trial's time base (needed with ``t`` for time-varying coefficients).

        Returns
        -------
        ndarray
            Shape ``(len(f),)`` for a scalar or absent ``t``, ``(len(t), len(f))`` for an array ``t``.
        """
        if self.num is None or self.den is None:
            raise ValueError("this truth has no frozen transfer function (num, den)")
        s = 2j * np.pi * np.atleast_1d(np.asarray(f, float))
        scalar_t = t is None or np.ndim(t) == 0
        tt = np.atleast_1d(np.asarray(0.0 if t is None else t, float))

        def coef(c: np.ndarray) -> np.ndarray:
            c = np.asarray(c, float)
            if c.ndim == 1:
                return np.broadcast_to(c, (len(tt), len(c)))
            if t is None or time is None:
                raise ValueError("time-varying num/den: give the times t and the trial's time base")
            return np.column_stack([np.interp(tt, time, c[:, j]) for j in range(c.shape[1])])

        def poly(c: np.ndarray) -> np.ndarray:
            out = np.zeros((c.shape[0], len(s)), complex)
            for j in range(c.shape[1]):
                out = out * s + c[:, j:j + 1]
            return out

        H = poly(coef(self.num)) / poly(coef(self.den))
        return H[0] if scalar_t else H


class TruthHidden(JointBenchError):
    """An estimator read ``Trial.truth`` while fitting: estimators fit blind."""


class HiddenTruth:
    """What ``Trial.truth`` is while an estimator fits (:meth:`Trial.blind`): reading anything of it, or
    asking whether it is there, raises :class:`TruthHidden` naming the estimator. The trial the caller
    holds keeps its truth for scoring."""

    __slots__ = ("estimator",)

    def __init__(self, estimator: str):
        object.__setattr__(self, "estimator", estimator)

    def _refuse(self, what: str):
        raise TruthHidden(f"estimator '{self.estimator}' read Trial.truth{what} while fitting: estimators fit "
                          f"blind (the truth of a simulated trial is hidden from fit and kept for scoring)")

    def __getattr__(self, name: str):
        if name.startswith("__"):            # copy, pickle and friends probing for protocols
            raise AttributeError(name)
        self._refuse(f".{name}")

    def __bool__(self):
        self._refuse(" (as a condition)")

    def __repr__(self) -> str:
        return f"<truth hidden while '{self.estimator}' fits>"


@dataclasses.dataclass(frozen=True, eq=False)
class Trial:
    """One record of joint angle and torque on a uniform time base.

    Attributes
    ----------
    time : ndarray
        Sample times (s), uniform at ``fs``.
    angle : ndarray
        Joint angle (rad).
    torque : ndarray
        Joint torque (N·m).
    fs : float
        Sampling rate (Hz).
    imposed : {'angle', 'torque'}
        Which signal the apparatus imposed (the input of the identification).
    truth : Truth or None
        Ground truth when simulated.
    name : str
        Label used in messages and outputs.
    channels : mapping of str to ndarray
        Further recorded channels on the same time base (e.g. a scheduling variable such as EMG or a
        slow position for a parameter-varying fit), name -> one value per sample; empty by default.
    """

    time: np.ndarray
    angle: np.ndarray
    torque: np.ndarray
    fs: float
    imposed: Imposed = "angle"
    truth: Truth | None = None
    name: str = "trial"
    channels: Mapping[str, np.ndarray] = dataclasses.field(default_factory=dict)

    def __post_init__(self):
        where = f"trial '{self.name}'"
        t = _as_series("time", self.time, where)
        a = _as_series("angle", self.angle, where)
        y = _as_series("torque", self.torque, where)
        if not (len(t) == len(a) == len(y)):
            raise InputError(f"{where}: mismatched lengths: time {len(t)}, angle {len(a)}, torque {len(y)}")
        if len(t) < 2:
            raise InputError(f"{where}: needs at least 2 samples, got {len(t)}")
        if not np.isfinite(self.fs) or self.fs <= 0:
            raise InputError(f"{where}: sampling rate must be > 0 Hz, got {self.fs}")
        dt = np.diff(t)
        step = 1.0 / self.fs
        dev = np.abs(dt - step)
        if dev.max() > 1e-6 * step + 1e-9 * abs(t).max():
            i = int(np.argmax(dev))
            raise InputError(f"{where}: time is not uniform at {self.fs:g} Hz: step {dt[i]:.6g} s between "
                             f"samples {i} and {i + 1} (expected {step:.6g} s)")
        if self.imposed not in ("angle", "torque"):
            raise InputError(f"{where}: imposed must be 'angle' or 'torque', got {self.imposed!r}")
        object.__setattr__(self, "time", t)
        object.__setattr__(self, "angle", a)
        object.__setattr__(self, "torque", y)
        object.__setattr__(self, "fs", float(self.fs))
        if self.channels:
            chans = {}
            for key, x in dict(self.channels).items():
                c = _as_series(f"channel {key}", x, where)
                if len(c) != len(t):
                    raise InputError(f"{where}: channel '{key}' has {len(c)} samples, the trial {len(t)}")
                chans[str(key)] = c
            object.__setattr__(self, "channels", chans)

    @classmethod
    def from_arrays(cls, angle, torque, fs: float, t0: float = 0.0, imposed: Imposed = "angle",
                    truth: Truth | None = None, name: str = "trial", channels: Mapping | None = None) -> "Trial":
        """Build a trial with a uniform time base starting at ``t0``."""
        n = np.size(angle)
        return cls(time=t0 + np.arange(n) / fs, angle=angle, torque=torque, fs=fs, imposed=imposed,
                   truth=truth, name=name, channels=dict(channels or {}))

    @property
    def n(self) -> int:
        return len(self.time)

    @property
    def duration(self) -> float:
        return self.n / self.fs

    @property
    def input(self) -> np.ndarray:
        """The imposed signal (the identification input)."""
        return self.angle if self.imposed == "angle" else self.torque

    @property
    def output(self) -> np.ndarray:
        return self.torque if self.imposed == "angle" else self.angle

    def replace(self, **changes) -> "Trial":
        return dataclasses.replace(self, **changes)

    def blind(self, estimator: str = "?") -> "Trial":
        """This trial as an estimator may see it: the same arrays, ``truth`` replaced by a
        :class:`HiddenTruth` (``self`` when it has no truth). Cheap: nothing is copied or re-checked."""
        if self.truth is None or isinstance(self.truth, HiddenTruth):
            return self
        out = copy.copy(self)
        object.__setattr__(out, "truth", HiddenTruth(estimator))
        return out

    def frozen_stiffness(self, f_hz: float = 0.0) -> np.ndarray:
        """The stiffness an estimator of this simulated trial should be scored against (N·m/rad), at every
        sample: the magnitude of the true frozen impedance (angle to torque) at ``f_hz``.

        ``f_hz = 0`` gives the static gain: what an IRF's sum, a parametric K and the series stiffness of a
        joint with hand contact are (``truth.K`` is the joint's intrinsic stiffness alone, which is not what
        the data determine when other elastic elements are in series); the lowest multisine line is what
        KBR and skirt report. Computed from the trial's input-to-output transfer function
        (:meth:`Truth.frozen_response`): itself when the angle is imposed, its inverse when the torque is.

        Raises
        ------
        ValueError
            A trial without a truth (a recording), or a truth without a transfer function.
        """
        if not isinstance(self.truth, Truth):
            raise ValueError(f"trial '{self.name}' has no truth (only simulated trials have a frozen stiffness)")
        t = self.time
        h = np.abs(np.atleast_1d(self.truth.frozen_response(np.array([float(f_hz)]), t, t))).reshape(-1)
        if h.size == 1:
            h = np.full(len(t), float(h[0]))
        return h if self.imposed == "angle" else 1.0 / h
