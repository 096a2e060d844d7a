"""The conformance kit's checks: each a function ``check_<what>(estimator, *, quick=True) -> str``.

Each takes an estimator class (registered or not), fits through the user's path
(:func:`jointbench.fitting.pipeline.fit`, which :func:`jointbench.api.fit` and ``jointbench estimate`` are) on
records of the estimator's own kind (:mod:`jointbench.testing.data`), and returns a short note of what it did;
it raises :class:`CheckSkipped` with the reason when it does not apply (no intervals, no numeric settings), and
an :class:`AssertionError` naming the check, the estimator, the setting and the input (record and seed) when
the estimator fails it. ``quick`` (the default, run in ``make test``) uses few seeds and the grid's ends; the full
version (``make conformance``) more seeds and the whole grid.

In every check a refusal is an :class:`~jointbench.core.errors.InputError` of one line, never another exception
(:func:`fit`). The output rule (:func:`gated`: a returned fit has a VAF of at least 0 on every record it was
fitted on, finite parameters, intervals of finite positive width) is checked by :func:`check_output_gate` on the
reference records and by :func:`check_narrow_band` on the narrow-band record; the other checks look at their own
property only, so that one cause fails one check.

References
----------
Pedregosa et al. (2011), scikit-learn: ``sklearn.utils.estimator_checks.check_estimator`` (the model of this kit);
issue 33 of JointBench (the narrow-band record, the coverage rule of 85 % over 30 seeds).
"""
from __future__ import annotations

import dataclasses
import math
import tempfile
import typing
from pathlib import Path

import numpy as np

from jointbench.core.ensemble import Ensemble
from jointbench.core.errors import ConfigError, InputError
from jointbench.core.types import Trial
from jointbench.testing import data as kit_data
from jointbench.testing.kit import (ALARM, LAG_GRID, NARROW_BAND_COVERAGE, TIME_OFFSET, TORQUE_FACTOR, CheckSkipped,
                                    allowed_misses, bounded_keys, check_times, compare, estimate_values, fail, fit,
                                    first_trial, gated, holds, kind, records_of, reference, reference_fit,
                                    scaled)

# ---------------------------------------------------------------------------------------------- the checks
class Tripwire:
    """A truth that records every read (the kit's witness that a fit stayed blind)."""

    def __init__(self):
        object.__setattr__(self, "reads", [])

    def __getattr__(self, name):
        self.reads.append(name)
        raise AttributeError(f"the conformance kit's truth was read ({name}) while fitting")


def wired(data, wire: Tripwire):
    """``data`` (a trial or an ensemble) with ``wire`` as the truth of every record."""
    trials = tuple(t.replace(truth=wire) for t in records_of(data))
    return Ensemble(trials, name=data.name) if isinstance(data, Ensemble) else trials[0]


def check_blind(cls, *, quick: bool = True) -> str:
    """The estimator never reads the truth: its records carry a truth that records any read while fitting
    (through the path, whatever it hands on; a plugin walking the call frames to the caller's record reads it:
    no frame of the kit holds the record's real truth while it fits)."""
    wire = Tripwire()
    record = wired(reference(kind(cls), 0), wire)
    try:
        fit("check_blind", cls, record, seed=0)
    except InputError as exc:
        raise fail("check_blind", cls, f"refused its own kind of record: {exc}", record=record.name, seed=0) from None
    if wire.reads:
        raise fail("check_blind", cls, f"read the truth while fitting: {sorted(set(wire.reads))}", record=record.name,
                   seed=0)
    return f"fitted {record.name} without reading its truth"


def invalid_values(field: dataclasses.Field, tp) -> list:
    """Values of a numeric setting that must be refused: across each declared bound, NaN, and text."""
    meta = field.metadata
    out: list = ["not a number"]
    if meta.get("gt") is not None:
        out.append(meta["gt"])
    if meta.get("ge") is not None:
        out.append(meta["ge"] - 1)
    if meta.get("lt") is not None:
        out.append(meta["lt"])
    if meta.get("le") is not None:
        out.append(meta["le"] + 1)
    out.append(float("nan") if tp is float else 0.5)
    return out


def numeric_type(tp):
    """``int`` or ``float`` when a settings field holds one (optionally None), else None."""
    if tp in (int, float):
        return tp
    args = [a for a in typing.get_args(tp) if a is not type(None)]
    return args[0] if len(args) == 1 and args[0] in (int, float) else None


def check_settings_validated(cls, *, quick: bool = True) -> str:
    """Every declared numeric setting refuses an invalid value on construction (a value across each of its
    bounds, NaN, text) with a :class:`~jointbench.core.errors.ConfigError` naming the setting."""
    Settings = cls.Settings
    if not dataclasses.is_dataclass(Settings):
        raise fail("check_settings_validated", cls, f"Settings ({Settings!r}) is not a dataclass")
    hints = typing.get_type_hints(Settings)
    tried = 0
    for field in dataclasses.fields(Settings):
        tp = numeric_type(hints.get(field.name))
        if tp is None or not field.init:
            continue
        for bad in invalid_values(field, tp):
            setting = {field.name: bad}
            try:
                Settings(**setting)
            except ConfigError as exc:
                if field.name not in str(exc):
                    raise fail("check_settings_validated", cls, f"the refusal does not name the setting: {exc}",
                               setting=setting) from None
                tried += 1
                continue
            except Exception as exc:
                raise fail("check_settings_validated", cls, f"{type(exc).__name__} instead of a ConfigError: {exc}",
                           setting=setting) from exc
            raise fail("check_settings_validated", cls, "accepted on construction", setting=setting)
    if not tried:
        raise CheckSkipped("no numeric settings declared")
    return f"{tried} invalid values refused"


def lag_settings(cls) -> list[str]:
    return [f.name for f in dataclasses.fields(cls.Settings) if f.name in ("lag_before", "lag_after")]


def window_settings(cls) -> list[str]:
    """Window-like settings (seconds, named ``*window*`` or ``segment``) with a number as default."""
    out = []
    for f in dataclasses.fields(cls.Settings):
        if f.metadata.get("unit") == "s" and ("window" in f.name or f.name == "segment") \
                and isinstance(f.default, (int, float)):
            out.append(f.name)
    return out


def setting_grid(cls, quick: bool) -> list[dict]:
    """The narrow-band check's settings: the defaults; ``lag_before = lag_after`` over :data:`LAG_GRID`; each
    window-like setting at half and double its default. Quick: the defaults, 40 ms lags, double windows."""
    grid: list[dict] = [{}]
    lags = lag_settings(cls)
    if lags:
        grid += [{k: v for k in lags} for v in ((0.04,) if quick else LAG_GRID)]
    for name in window_settings(cls):
        default = next(f.default for f in dataclasses.fields(cls.Settings) if f.name == name)
        grid += [{name: factor * default} for factor in ((2.0,) if quick else (0.5, 2.0))]
    return grid


def narrow_band_seeds(k: kit_data.Kind, quick: bool) -> range:
    """Seeds of the narrow-band check: 30 (issue 33's acceptance), 10 for an ensemble kind (each seed
    :data:`~jointbench.testing.data.NARROW_BAND_REALIZATIONS` records); quick: 2, 1 for an ensemble kind."""
    if quick:
        return range(1 if k.ensemble else 2)
    return range(10 if k.ensemble else 30)


def check_narrow_band(cls, *, quick: bool = True) -> str:
    """On issue 33's narrow-band record (multisine angle to 12 Hz, 30 s at 500 Hz, I 0.02, B 0.6, K 120, torque
    noise 10 % low-passed at 30 Hz; an ensemble kind gets realizations of 3 s, 2 s and its default settings
    only in the quick version: its fits cost tens of times a trial's), at each setting of
    :func:`setting_grid`: a one-line refusal, or a fit that passes the output gate (:func:`gated`: never a VAF
    below 0, never an interval of zero width) and whose intervals hold the truth in at least 85 % of the seeds
    fitted (full: issue 33's acceptance). Quick: the few seeds of :func:`narrow_band_seeds` under the loose
    binomial bound of :func:`allowed_misses` (a coverage miss fails only when a right interval would almost never
    miss that often), so that the quick version's teeth are the gate and the refusals."""
    k = kind(cls)
    seeds = narrow_band_seeds(k, quick)
    notes = []
    for setting in setting_grid(cls, quick)[:1] if quick and k.ensemble else setting_grid(cls, quick):
        misses: dict[str, int] = {}
        fitted = refused = 0
        for seed in seeds:
            data = kit_data.narrow_band_records(k, seed, duration=(2.0 if quick else 3.0) if k.ensemble else 30.0)
            try:
                out = fit("check_narrow_band", cls, data, setting, seed=seed, gate=True)
            except InputError:
                refused += 1
                continue
            fitted += 1
            trial = first_trial(data)
            at = check_times(out.estimate, trial, 1)
            for key in bounded_keys(out.estimate):
                misses[key] = misses.get(key, 0) + int(not holds(out.estimate, trial, key, 0.0, at).all())
        allowed = allowed_misses(fitted) if quick else int(math.floor((1 - NARROW_BAND_COVERAGE) * fitted))
        bad = {key: m for key, m in misses.items() if m > allowed}
        if bad:
            raise fail("check_narrow_band", cls, f"intervals miss the truth (I 0.02, B 0.6, K 120) in "
                       f"{', '.join(f'{key}: {m} of {fitted}' for key, m in bad.items())} fits (allowed {allowed})",
                       setting=setting, record="narrow_band", seed=f"{seeds[0]} ... {seeds[-1]}")
        notes.append(f"{setting or 'default'}: {fitted} fitted, {refused} refused, misses {misses}")
    return "; ".join(notes)


def check_output_gate(cls, *, quick: bool = True) -> str:
    """Nothing untrustworthy is returned as a result (issue 33's output gate): every fit of reference records of the
    estimator's kind (quick 2 seeds, full 10) that the path returns has VAF >= 0 on each record, finite
    parameters and intervals of finite positive width; else the path must refuse
    (:class:`~jointbench.core.errors.Refused`)."""
    k = kind(cls)
    seeds = range(2 if quick else 10)
    refused = 0
    for seed in seeds:
        try:
            out = reference_fit("check_output_gate", cls, seed)
        except InputError:
            refused += 1
            continue
        gated("check_output_gate", cls, out, record=reference(k, seed).name, seed=seed)
    return f"{len(seeds) - refused} fits held to the gate, {refused} refused"


def check_interval_coverage(cls, *, quick: bool = True) -> str:
    """The intervals hold the truth of reference records of the estimator's kind at the stated rate: over the
    seeds (quick 4, full 20) and three times of each record (one for a time-invariant estimate), the misses stay
    within what a right 95 % interval exceeds with probability below 0.001 (:func:`allowed_misses`)."""
    k = kind(cls)
    seeds = range(4 if quick else 20)
    misses: dict[str, int] = {}
    checks = 0
    for seed in seeds:
        data = reference(k, seed)
        try:
            out = reference_fit("check_interval_coverage", cls, seed)
        except InputError as exc:
            raise fail("check_interval_coverage", cls, f"refused its own kind of record: {exc}", record=data.name,
                       seed=seed) from None
        keys = bounded_keys(out.estimate)
        if not keys:
            raise CheckSkipped("no intervals of I, B, K or the stiffness on the estimate's time base")
        trial = first_trial(data)
        at = check_times(out.estimate, trial, 3)
        checks += len(at)
        for key in keys:
            misses[key] = misses.get(key, 0) + int(np.sum(~holds(out.estimate, trial, key, k.stiffness_hz, at)))
    allowed = allowed_misses(checks)
    bad = {key: m for key, m in misses.items() if m > allowed}
    if bad:
        raise fail("check_interval_coverage", cls, f"{', '.join(f'{key} missed {m}' for key, m in bad.items())} of "
                   f"{checks} (a right 95 % interval misses more than {allowed} with probability below {ALARM})",
                   record=f"{k.name} reference", seed=f"0 ... {len(seeds) - 1}")
    return f"{checks} checks per quantity, misses {misses} (allowed {allowed})"


def check_torque_scaling(cls, *, quick: bool = True) -> str:
    """The torque scaled by c (3) scales I, B, K, the stiffness and their intervals by c (equivariance: the
    impedance is linear in the torque)."""
    data = reference(kind(cls), 0)
    base = reference_fit("check_torque_scaling", cls, 0)
    out = fit("check_torque_scaling", cls, scaled(data, factor=TORQUE_FACTOR), seed=0)
    want = {key: TORQUE_FACTOR * v for key, v in estimate_values(base.estimate).items()}
    compare("check_torque_scaling", cls, estimate_values(out.estimate), want, record=f"{data.name} torque x 3",
            seed=0, what=f"torque x {TORQUE_FACTOR:g}")
    return f"{len(want)} quantities scaled by {TORQUE_FACTOR:g}"


def check_time_shift(cls, *, quick: bool = True) -> str:
    """The record's time shifted (time + 100 s) gives the same parameters and intervals (on a shifted time base)."""
    data = reference(kind(cls), 0)
    base = reference_fit("check_time_shift", cls, 0)
    out = fit("check_time_shift", cls, scaled(data, offset=TIME_OFFSET), seed=0)
    record = f"{data.name} time + {TIME_OFFSET:g} s"
    compare("check_time_shift", cls, estimate_values(out.estimate), estimate_values(base.estimate), record=record,
            seed=0, what=f"time + {TIME_OFFSET:g} s")
    compare("check_time_shift", cls, {"time": np.asarray(out.estimate.time, float)},
            {"time": np.asarray(base.estimate.time, float) + TIME_OFFSET}, record=record, seed=0, what="time base")
    return "same parameters, time base shifted"


def write_csv(trial: Trial, path: Path) -> Path:
    """``trial`` as a CSV file of the reading path's columns (``time`` s, ``angle`` rad, ``torque`` N m), every
    digit of a double kept."""
    body = np.column_stack([trial.time, trial.angle, trial.torque])
    np.savetxt(path, body, delimiter=",", header="time,angle,torque", comments="", fmt="%.17g")
    return path


def check_units(cls, *, quick: bool = True) -> str:
    """A change of units gives the same parameters in SI: each setting in seconds given in milliseconds
    (``"40 ms"``), and the record read from a CSV file of the reading path (:mod:`jointbench.fitting.read`).

    The reading path takes the angle in radians only (no unit option in files or on the command line): the
    kit says so in its note rather than check a degrees file against nothing."""
    k = kind(cls)
    data = reference(k, 0)
    base = reference_fit("check_units", cls, 0)
    want = estimate_values(base.estimate)
    in_ms = {f.name: f"{f.default * 1000:.12g} ms" for f in dataclasses.fields(cls.Settings)
             if f.metadata.get("unit") == "s" and isinstance(f.default, (int, float))
             and not isinstance(f.default, bool)}
    if in_ms:
        out = fit("check_units", cls, data, in_ms, seed=0)
        compare("check_units", cls, estimate_values(out.estimate), want, setting=in_ms, record=data.name, seed=0,
                what="settings in ms")
    with tempfile.TemporaryDirectory(prefix="jointbench-kit-") as tmp:
        paths = [str(write_csv(t, Path(tmp) / f"{t.name}.csv")) for t in records_of(data)]
        out = fit("check_units", cls, paths if len(paths) > 1 else paths[0], seed=0,
                  ensemble=True if isinstance(data, Ensemble) else None)
        compare("check_units", cls, estimate_values(out.estimate), want, record=f"{data.name} as CSV", seed=0,
                what="read from CSV")
    return (f"{len(in_ms)} settings in ms, the record from CSV: same estimate; angles in degrees not checked "
            f"(the reading path takes radians only)")


def degenerate_inputs(data, lags_samples: int) -> dict[str, tuple[np.ndarray, np.ndarray, float]]:
    """Degenerate versions of ``data`` as arrays (angle, torque, fs; samples x realizations for an ensemble)."""
    trials = records_of(data)
    fs = trials[0].fs
    angle = np.column_stack([t.angle for t in trials])
    torque = np.column_stack([t.torque for t in trials])
    one = angle.shape[1] == 1
    squeeze = (lambda x: x[:, 0]) if one else (lambda x: x)
    nan_angle = angle.copy()
    nan_angle[len(angle) // 2] = np.nan
    short = max(2, min(lags_samples, len(angle) - 1))
    return {"constant angle": (squeeze(np.full_like(angle, 0.1)), squeeze(torque), fs),
            "constant torque": (squeeze(angle), squeeze(np.full_like(torque, 2.0)), fs),
            "zero torque": (squeeze(angle), squeeze(np.zeros_like(torque)), fs),
            "a NaN in the angle": (squeeze(nan_angle), squeeze(torque), fs),
            "one sample": (squeeze(angle[:1]), squeeze(torque[:1]), fs),
            f"{short} samples (shorter than the lags)": (squeeze(angle[:short]), squeeze(torque[:short]), fs)}


def check_degenerate_inputs(cls, *, quick: bool = True) -> str:
    """Constant angle, constant or zero torque, a NaN, one sample, a record shorter than the lags: each a
    one-line :class:`~jointbench.core.errors.InputError`, never a traceback, never a result."""
    data = reference(kind(cls), 0)
    defaults = cls.Settings()
    lags = sum(getattr(defaults, name) for name in lag_settings(cls))
    lags_samples = int(round(lags * records_of(data)[0].fs)) if lags else 10
    for label, (angle, torque, fs) in degenerate_inputs(data, lags_samples).items():
        try:
            out = fit("check_degenerate_inputs", cls, None, angle=angle, torque=torque, fs=fs, seed=0,
                      record=f"{data.name}: {label}")
        except InputError:
            continue
        raise fail("check_degenerate_inputs", cls, f"returned a result (VAF {np.round(out.vaf, 1).tolist()} %) "
                   f"instead of a one-line InputError", record=f"{data.name}: {label}", seed=0)
    return "every degenerate input refused in one line"


def check_data_kinds(cls, *, quick: bool = True) -> str:
    """The estimator takes what ``accepts`` declares and refuses the rest in one line: two records to a
    single-trial method refused; pooled only where it pools (a fit of both records); a single trial to an
    ensemble-only method refused; an ensemble to a method that takes none refused."""
    data = reference(kind(cls), 0)
    trials = records_of(data)
    if len(trials) < 2:
        trials = trials + records_of(reference(kind(cls), 1))
    two = [trials[0], trials[1].replace(name=trials[1].name + "_second")]
    done = []

    def refused(what: str, given, **kw):
        try:
            out = fit("check_data_kinds", cls, given, seed=0, **kw)
        except InputError:
            done.append(f"{what} refused")
            return
        raise fail("check_data_kinds", cls, f"{what}: fitted (VAF {np.round(out.vaf, 1).tolist()} %) although "
                   f"accepts = {sorted(cls.accepts)}", record=", ".join(t.name for t in records_of(given)), seed=0)

    if "pooled" in cls.accepts:
        out = fit("check_data_kinds", cls, two, seed=0, ensemble=False)
        if len(out.vaf) != 2:
            raise fail("check_data_kinds", cls, f"two records pooled, {len(out.vaf)} scored", seed=0,
                       record=f"{two[0].name}, {two[1].name}")
        done.append("two records pooled")
    elif "trial" in cls.accepts:
        refused("two records to a single-trial method", two, ensemble=False)
    if "trial" not in cls.accepts:
        refused("one trial to a method that takes no single trial", trials[0])
    if "ensemble" not in cls.accepts:
        refused("an ensemble to a method that takes none", Ensemble(tuple(two), name="two realizations"))
    return "; ".join(done)


#: the checks, in the order they run
CHECKS = {f.__name__: f for f in (check_settings_validated, check_blind, check_data_kinds, check_degenerate_inputs,
                                  check_output_gate, check_torque_scaling, check_time_shift, check_units,
                                  check_interval_coverage, check_narrow_band)}
