"""Time-variation profiles of a joint parameter: constant, sine, square wave, piecewise (steps or ramps),
and the registry's other shapes, one file each: ``ramp`` (sims/profile_ramp.py), ``smooth_random``
(sims/profile_random.py), ``file`` (sims/profile_file.py).

A profile is a small frozen dataclass registered in :data:`sims.PROFILES` with ``at(t)`` (the values at
times t), ``minimum`` (the smallest value it ever takes, exactly: joints check positivity from it),
``constant`` and a ``shape`` name; a deterministic function of its settings. In a config a parameter is
either a plain number (constant) or a mapping with a ``shape`` key, e.g.::

    K: {shape: sine, mean: 40, amplitude: 15, frequency: 0.5 Hz}
    k: {shape: square, mean: 5.6, amplitude: 0.9, period: 20 s}
    B: {shape: piecewise, times: [0, 15, 30], values: [1.13, 10.1, 1.13]}
    K: {shape: ramp, initial: 20, final: 60, start: 10 s, duration: 20 s}
    K: {shape: smooth_random, mean: 40, amplitude: 15, bandwidth: 0.5 Hz, seed: 3}
    k: {shape: file, path: stiffness.csv}

Profiles are shared by every time-varying joint model (Xu & Hollerbach 1998 elbow and calibration arm,
van de Ruit et al. 2018 wrist).
"""
from __future__ import annotations

import dataclasses
from typing import Any, ClassVar, Literal, Mapping

import numpy as np

from jointbench.core.errors import ConfigError
from jointbench.core.schema import param, parse
from jointbench.sims.registries import PROFILES


def _period(frequency: float | None, period: float | None, where: str) -> float:
    if (frequency is None) == (period is None):
        raise ConfigError(f"{where}: give exactly one of 'frequency' (Hz) and 'period' (s)")
    return float(period) if period is not None else 1.0 / float(frequency)


@PROFILES.register("constant")
@dataclasses.dataclass(frozen=True)
class Constant:
    """``x(t) = value``."""

    value: float = param(doc="the constant value")

    shape: ClassVar[str] = "constant"

    def at(self, t: np.ndarray) -> np.ndarray:
        return np.full(np.shape(t), float(self.value))

    @property
    def minimum(self) -> float:
        """The smallest value the profile takes."""
        return float(self.value)

    @property
    def mean(self) -> float:
        return float(self.value)

    @property
    def constant(self) -> bool:
        return True


@dataclasses.dataclass(frozen=True)
class _Periodic:
    """Fields shared by the periodic profiles: ``mean``, ``amplitude``, and ``frequency`` or ``period``."""

    mean: float = param(doc="mean value")
    amplitude: float = param(doc="amplitude (half the peak-to-peak range)")
    frequency: float | None = param(None, unit="Hz", gt=0, doc="frequency of the variation")
    period: float | None = param(None, unit="s", gt=0, doc="or its period")
    phase: float = param(0.0, unit="rad", doc="phase at t = 0")

    shape: ClassVar[str] = "periodic"

    def __post_init__(self):
        _period(self.frequency, self.period, self.shape)   # exactly one of frequency and period

    @property
    def T(self) -> float:
        """The period (s)."""
        return _period(self.frequency, self.period, self.shape)

    @property
    def constant(self) -> bool:
        return self.amplitude == 0

    @property
    def minimum(self) -> float:
        """The smallest value the profile takes."""
        return float(self.mean - abs(self.amplitude))


@PROFILES.register("sine")
@dataclasses.dataclass(frozen=True)
class Sine(_Periodic):
    """``x(t) = mean + amplitude · sin(2π t / period + phase)``.

    References
    ----------
    Xu & Hollerbach 1998, Sec. IV-A (K(t) = 40 + 15 sin 2π f_v t); van de Ruit et al. 2018, Sec. IV-C
    (sinusoidal stiffness, period 20 s).
    """

    shape: ClassVar[str] = "sine"

    def at(self, t: np.ndarray) -> np.ndarray:
        return self.mean + self.amplitude * np.sin(2 * np.pi * np.asarray(t, float) / self.T + self.phase)


@PROFILES.register("square")
@dataclasses.dataclass(frozen=True)
class Square(_Periodic):
    """``x(t) = mean + amplitude · sign(sin(2π t / period + phase))`` (high first for phase 0); the
    amplitude is half the step height.

    The value at a switching instant is the new level (the sign of 0 is taken as +1).

    References
    ----------
    Xu & Hollerbach 1998, Sec. IV-A (square-wave variation); van de Ruit et al. 2018, Sec. IV-C (square
    waves of period 10, 20 and 30 s).
    """

    shape: ClassVar[str] = "square"

    def at(self, t: np.ndarray) -> np.ndarray:
        # position within the cycle, robust at the switching instants (no sin() rounding)
        c = np.mod(np.asarray(t, float) / self.T + self.phase / (2 * np.pi), 1.0)
        return self.mean + self.amplitude * np.where(c < 0.5, 1.0, -1.0)


def interpolate(knots: np.ndarray, values: np.ndarray, t: np.ndarray, how: str) -> np.ndarray:
    """Values at ``knots`` (increasing) read at times ``t``: joined by straight lines (``how='linear'``) or
    each held until the next knot (``'step'``); the first (last) value before (after) the knots."""
    tt = np.asarray(t, float)
    if how == "linear":
        return np.interp(tt, knots, values)
    i = np.clip(np.searchsorted(knots, tt, side="right") - 1, 0, len(knots) - 1)
    return values[i]


@PROFILES.register("piecewise")
@dataclasses.dataclass(frozen=True)
class Piecewise:
    """Values given at times: held until the next time (``interpolate: step``) or joined by straight
    lines (``linear``). Before the first time the first value holds, after the last the last.

    References
    ----------
    Xu & Hollerbach 1998, Sec. IV-B (calibration arm whose damping is switched during the trial).
    """

    times: list[float] = param(unit="s", doc="increasing times (s)")
    values: list[float] = param(doc="values at those times")
    interpolate: Literal["step", "linear"] = "step"

    shape: ClassVar[str] = "piecewise"

    def __post_init__(self):
        t = np.asarray(self.times, float)
        v = np.asarray(self.values, float)
        if t.ndim != 1 or len(t) < 1 or len(t) != len(v):
            raise ConfigError(f"piecewise: 'times' and 'values' need the same number (>= 1) of entries, "
                              f"got {len(t)} and {len(v)}")
        if np.any(np.diff(t) <= 0):
            raise ConfigError(f"piecewise: 'times' must increase strictly, got {list(self.times)}")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
            raise ConfigError("piecewise: 'times' and 'values' must be finite")

    def at(self, t: np.ndarray) -> np.ndarray:
        return interpolate(np.asarray(self.times, float), np.asarray(self.values, float), t, self.interpolate)

    @property
    def constant(self) -> bool:
        return bool(np.all(np.asarray(self.values) == self.values[0]))

    @property
    def minimum(self) -> float:
        """The smallest value the profile takes (ramps stay between their end values)."""
        return float(np.min(self.values))


def _is_profile(obj: Any) -> bool:
    return any(obj.__class__ is PROFILES.get(name) for name in PROFILES.names())


def parse_profile(data: Any, where: str) -> Any:
    """A profile from a plain number (constant) or a mapping ``{shape: name, ...}``.

    Raises
    ------
    ConfigError
        Unknown shape or key, bad value; the message names ``where``.
    """
    if isinstance(data, (int, float, str)) and not isinstance(data, bool):
        return parse(Constant, {"value": data}, where)
    if _is_profile(data):
        return data
    if not isinstance(data, Mapping) or "shape" not in data:
        raise ConfigError(f"{where}: expected a number or a mapping with key 'shape' "
                          f"(one of: {', '.join(PROFILES.names())}), got {data!r}")
    shape = data["shape"]
    if shape not in PROFILES:
        raise ConfigError(f"{where}: key 'shape': unknown profile {shape!r}; known: {', '.join(PROFILES.names())}")
    rest = {k: v for k, v in data.items() if k != "shape"}
    return parse(PROFILES.get(shape), rest, f"{where} ({shape})")


def parse_profile_fields(obj: Any, names: tuple[str, ...]) -> None:
    """Turn the named fields of dataclass ``obj`` (numbers or ``{shape: ...}`` mappings) into profiles, in
    place (a joint model's ``__post_init__``); errors name the key."""
    for name in names:
        v = getattr(obj, name)
        if v is not None:
            object.__setattr__(obj, name, parse_profile(v, f"key '{name}'"))


def require_positive(name: str, profile: Any, strict: bool) -> None:
    """Raise :class:`ConfigError` if ``profile`` ever goes to or below zero (``strict``) or below zero."""
    low = profile.minimum
    if not (low > 0 if strict else low >= 0):
        raise ConfigError(f"key '{name}': the profile reaches {low:g}; it must stay "
                          f"{'> 0' if strict else '>= 0'} at all times")
