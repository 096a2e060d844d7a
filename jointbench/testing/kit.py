"""The conformance kit's tools: a fit through the user's path (refusals of one line only), the output rule, a failure
that names the check, the estimator, the setting and the input, and the comparisons of estimates with the truth and
with each other. The checks themselves: :mod:`jointbench.testing.checks`.
"""
from __future__ import annotations

import functools
import math
import typing
from pathlib import Path

import numpy as np

from jointbench.core.ensemble import Ensemble
from jointbench.core.errors import InputError
from jointbench.core.intervals import LEVEL  # the level the kit holds intervals to (every estimator states it)
from jointbench.core.types import Trial
from jointbench.testing import data as kit_data

#: a right interval exceeds the allowed misses over S seeds with probability below this (as
#: tests/test_interval_coverage.py: a false alarm below 2 % over the kit's checks)
ALARM = 0.001
#: the narrow-band acceptance of issue 33: intervals hold the truth in at least this fraction of the seeds
NARROW_BAND_COVERAGE = 0.85
#: the lag grid of the narrow-band check (s; lag_before = lag_after), beside each estimator's default
LAG_GRID = (0.02, 0.04, 0.1)
#: relative tolerance of the invariances (the same arithmetic up to rounding), against a quantity's magnitude
RTOL = 1e-6
#: ... or against its interval's half-width, where it has one (:func:`tolerance`)
WIDTH_FRACTION = 0.01
#: the torque factor and time offset of the invariance checks
TORQUE_FACTOR = 3.0
TIME_OFFSET = 100.0


class CheckSkipped(Exception):
    """A check that does not apply to an estimator; its message is the reason."""


def fail(check: str, cls, what: str, *, setting=None, record: str | None = None, seed=None) -> AssertionError:
    """The failure of ``check`` for ``cls``, naming the setting and the input (record, seed)."""
    where = [f"settings {dict(setting)}" if setting else "default settings"]
    if record is not None:
        where.append(f"record '{record}'")
    if seed is not None:
        where.append(f"seed {seed}")
    return AssertionError(f"{check}: {cls.name} ({', '.join(where)}): {what}")


def build(cls, settings: typing.Mapping | None = None):
    """An estimator of class ``cls`` with ``settings`` parsed strictly (units allowed), as
    :func:`jointbench.estimators.make` builds a registered one."""
    from jointbench.core.schema import parse

    return cls(parse(cls.Settings, dict(settings or {}), f"settings (estimator '{cls.name}')"))


def records_of(data) -> list[Trial]:
    """The trials of ``data`` (a trial, a list of trials or an ensemble)."""
    if isinstance(data, Trial):
        return [data]
    if isinstance(data, Ensemble):
        return list(data.realizations)
    return list(data)


def label(data) -> str:
    """How the kit names ``data`` in a failure: its name, its records' names, or its files."""
    if isinstance(data, (Trial, Ensemble)):
        return data.name
    if isinstance(data, (str, Path)):
        return Path(data).name
    return ", ".join(label(d) for d in data) if data is not None else "arrays"


def fit(check: str, cls, data, settings=None, *, seed=None, gate: bool = False, **kwargs):
    """``data`` fitted by ``cls`` through the user's path; with ``gate``, held to the output rule (:func:`gated`).

    Returns the :class:`~jointbench.fitting.pipeline.Fit`. An :class:`InputError` (a refusal) passes on when it
    is one line; any other exception, or a refusal of several lines, is the check's failure."""
    from jointbench.fitting import pipeline

    record = kwargs.pop("record", None) or label(data)
    try:
        with np.errstate(all="ignore"):
            out = pipeline.fit(build(cls, settings), data, **kwargs)
    except InputError as exc:
        if "\n" in str(exc).strip():
            raise fail(check, cls, f"a refusal of several lines: {exc!r}", setting=settings, record=record,
                       seed=seed) from None
        raise
    except Exception as exc:
        raise fail(check, cls, f"{type(exc).__name__} instead of a one-line InputError: {exc}", setting=settings,
                   record=record, seed=seed) from exc
    if gate:
        gated(check, cls, out, setting=settings, record=record, seed=seed)
    return out


def gated(check: str, cls, out, *, setting=None, record=None, seed=None) -> None:
    """The output rule on a returned fit ``out``: a finite VAF of at least 0 on every record fitted (a prediction
    worse than a constant is refused, never returned), finite parameters, intervals of finite positive width."""
    settings = setting
    vaf = [p.vaf() for p in out.predictions]
    if not all(math.isfinite(v) and v >= 0 for v in vaf):
        raise fail(check, cls, f"a fit returned with VAF {np.round(vaf, 1).tolist()} %: a prediction worse than a "
                   f"constant must be refused (Refused), never returned", setting=settings, record=record, seed=seed)
    for key, value in out.estimate.parameters().items():
        if not np.all(np.isfinite(value)):
            raise fail(check, cls, f"non-finite {key} returned", setting=settings, record=record, seed=seed)
    iv = out.estimate.intervals
    for key, (lo, hi) in ({} if iv is None else iv.bounds).items():
        width = np.asarray(hi, float) - np.asarray(lo, float)
        if not np.all(np.isfinite(width)) or not np.all(width > 0):
            raise fail(check, cls, f"interval of {key} of zero, negative or non-finite width returned "
                       f"(width {np.min(width):.3g} ... {np.max(width):.3g})", setting=settings, record=record,
                       seed=seed)


def allowed_misses(checks: int, level: float = LEVEL, alarm: float = ALARM) -> int:
    """The most misses a right ``level`` interval reaches with probability at least ``alarm`` over ``checks``."""
    from scipy import stats

    return int(stats.binom.isf(alarm, checks, 1 - level))


@functools.lru_cache(maxsize=64)
def reference(kind: kit_data.Kind, seed: int):
    """The kind's reference record of ``seed`` (kept: several checks use the same records)."""
    return kit_data.reference(kind, seed)


#: the reference fits made so far, by (estimator class, seed): :func:`reference_fit`
REFERENCE_FITS: dict = {}


def reference_fit(check: str, cls, seed: int):
    """The fit of the kind's reference record ``seed`` at the default settings, made once per estimator class and
    seed (fitting is deterministic; the checks comparing with it share it). A refusal is not kept: each asker
    meets it, named as its own check."""
    key = (cls, seed)
    if key not in REFERENCE_FITS:
        REFERENCE_FITS[key] = fit(check, cls, reference(kind(cls), seed), seed=seed)
    return REFERENCE_FITS[key]


def kind(cls) -> kit_data.Kind:
    return kit_data.kind_of(cls)


def first_trial(data) -> Trial:
    return records_of(data)[0]


# ---------------------------------------------------------------------------------------- what to compare
def truth_at(key: str, trial: Trial, stiffness_hz: float, at: np.ndarray) -> np.ndarray:
    """The true ``key`` (``I``, ``B``, ``K`` or ``stiffness``) of a simulated trial at sample indices ``at``:
    the stiffness is ``|H(stiffness_hz)|`` of the true frozen impedance (:meth:`Trial.frozen_stiffness`)."""
    if key == "stiffness":
        return trial.frozen_stiffness(stiffness_hz)[at]
    return trial.truth.at(key, trial.time[at], trial.time)


def bounded_keys(est) -> list[str]:
    """The quantities of ``est``'s intervals the kit checks (the per-sample bounds of I, B, K, stiffness)."""
    iv = est.intervals
    return [] if iv is None else [k for k in ("I", "B", "K", "stiffness") if k in iv.bounds]


def check_times(est, trial: Trial, count: int) -> np.ndarray:
    """``count`` sample indices of ``trial`` inside the estimate's span, away from its ends (25 ... 75 %); one when
    every interval of ``est`` is constant in time (a time-invariant estimate: its checks at several times would be
    one check counted several times)."""
    iv = est.intervals
    constant = iv is None or all(np.ptp(np.atleast_1d(np.asarray(b, float))) == 0 for lo_hi in iv.bounds.values()
                                 for b in lo_hi)
    return np.linspace(0.25 * (trial.n - 1), 0.75 * (trial.n - 1), 1 if constant else count).astype(int)


def holds(est, trial: Trial, key: str, stiffness_hz: float, at: np.ndarray) -> np.ndarray:
    """Whether ``est``'s interval of ``key`` holds the truth at samples ``at`` of ``trial`` (bool per sample)."""
    lo, hi = (np.broadcast_to(np.asarray(b, float), est.time.shape) for b in est.intervals.bounds[key])
    t = trial.time[at]
    lo, hi = np.interp(t, est.time, lo), np.interp(t, est.time, hi)
    truth = truth_at(key, trial, stiffness_hz, at)
    return (lo <= truth) & (truth <= hi)


def estimate_values(est) -> dict[str, np.ndarray]:
    """The numbers an estimate reports: its parameters, its stiffness and its interval bounds, as arrays."""
    out = {k: np.atleast_1d(np.asarray(v, float)) for k, v in est.parameters().items()}
    out["stiffness"] = np.atleast_1d(np.asarray(est.stiffness(est.time), float))
    iv = est.intervals
    for key, (lo, hi) in ({} if iv is None else iv.bounds).items():
        out[f"{key}_lo"], out[f"{key}_hi"] = np.atleast_1d(np.asarray(lo, float)), np.atleast_1d(np.asarray(hi, float))
    return out


def tolerance(key: str, want: dict) -> np.ndarray:
    """What ``want[key]`` may differ by under an invariance: :data:`WIDTH_FRACTION` of the interval's half-width
    where the quantity has one (sample by sample; a solver stopped at its tolerance moves the estimate by less than
    anyone reading the interval could see), and :data:`RTOL` of the quantity's largest magnitude in any case."""
    b = want[key]
    base = key[:-3] if key.endswith(("_lo", "_hi")) else key
    floor = RTOL * max(float(np.max(np.abs(b))), 1e-300)
    if f"{base}_lo" in want and f"{base}_hi" in want:
        half = np.abs(want[f"{base}_hi"] - want[f"{base}_lo"]) / 2
        return np.maximum(WIDTH_FRACTION * np.broadcast_to(half, b.shape), floor)
    return np.full(b.shape, floor)


def compare(check: str, cls, got: dict, want: dict, *, setting=None, record=None, seed=None, what: str = ""):
    """``got`` equals ``want`` quantity by quantity, within :func:`tolerance`."""
    if set(got) != set(want):
        raise fail(check, cls, f"{what}: the quantities differ: {sorted(got)} against {sorted(want)}",
                   setting=setting, record=record, seed=seed)
    for key in want:
        a, b = got[key], want[key]
        if a.shape != b.shape:
            raise fail(check, cls, f"{what}: {key} has shape {a.shape}, expected {b.shape}", setting=setting,
                       record=record, seed=seed)
        tol = tolerance(key, want)
        if not np.all(np.abs(a - b) <= tol):
            i = int(np.argmax(np.abs(a - b) / tol))
            raise fail(check, cls, f"{what}: {key} differs by {abs(a[i] - b[i]):.3g} (allowed {tol[i]:.3g}) at sample "
                       f"{i}: {a[i]:.6g} against {b[i]:.6g}", setting=setting, record=record, seed=seed)


def scaled(data, factor: float | None = None, offset: float | None = None):
    """``data`` with every torque times ``factor`` and every time plus ``offset`` (the truth kept: the kit
    compares estimate with estimate)."""
    def one(t: Trial) -> Trial:
        changes = {}
        if factor is not None:
            changes["torque"] = factor * t.torque
        if offset is not None:
            changes["time"] = t.time + offset
        return t.replace(**changes)
    if isinstance(data, Ensemble):
        return Ensemble(tuple(one(t) for t in data.realizations), name=data.name)
    return one(data)
