"""``jointbench estimate --schedule``: a parameter-varying fit's scheduling variable, and K at chosen values.

``--schedule angle_slow`` (or ``angle``) derives the scheduling variable from the angle; any other name is a
column of a CSV input or an array of an NPZ/.mat input, read beside the angle and torque and carried through
the decimation and cropping as a channel of the record (:attr:`jointbench.core.types.Trial.channels`). The
estimator must take a ``schedule`` setting (``pv_irf``). After the fit, K at the ``--at`` values (default:
five over the range the schedule visited) is printed with its band.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from jointbench.core.errors import ConfigError, InputError

#: scheduling variables derived from the angle (anything else is read from the input)
DERIVED = ("angle_slow", "angle")


def parse_at(text: str) -> np.ndarray:
    """``V1,V2,...`` -> an array of numbers (one-line error otherwise)."""
    try:
        values = np.array([float(v) for v in str(text).split(",") if v.strip()])
    except ValueError:
        raise ConfigError(f"--at: expected numbers separated by commas, e.g. -0.3,0,0.2; got {text!r}") from None
    if not values.size or not np.all(np.isfinite(values)):
        raise ConfigError(f"--at: expected finite numbers separated by commas, got {text!r}")
    return values


def check_schedulable(name: str, names=None) -> None:
    """Refuse an estimator that takes no ``schedule`` setting (one line naming the parameter-varying ones)."""
    import dataclasses

    from jointbench import estimators

    cls = estimators.REGISTRY.get(name)
    if "schedule" not in {f.name for f in dataclasses.fields(cls.Settings)}:
        takes = [n for n in estimators.REGISTRY.names("lpv")]
        raise ConfigError(f"{_flag(names)}: estimator '{name}' takes no scheduling variable; "
                          f"parameter-varying estimators: {', '.join(takes) or 'none'}")


def make_scheduled(name: str, assignments: Sequence[str], schedule: str, make_estimator):
    """The estimator with ``schedule=NAME`` added to its settings; refused when it takes no schedule.

    ``make_estimator(name, assignments)`` builds it (the caller's, so that errors name the caller's flags).
    """
    check_schedulable(name)
    return make_estimator(name, [*assignments, f"schedule={schedule}"])


def _flag(names=None) -> str:
    """How errors name the scheduling argument: ``--schedule`` (the CLI, default) or ``schedule=`` (the API)."""
    return "--schedule" if names is None else names("schedule")


def _variables(path):
    from jointbench.fitting import read

    suffix = path.suffix.lower()
    if suffix == ".csv":          # every column (the record reader keeps time, angle and torque only)
        import pandas as pd

        try:
            df = pd.read_csv(path, comment="#", skipinitialspace=True)
        except (pd.errors.ParserError, UnicodeDecodeError, OSError) as exc:
            raise InputError(f"{path}: cannot read as CSV: {str(exc).strip()}") from None
        out = {}
        for c in df.columns:
            values = pd.to_numeric(df[c], errors="coerce").to_numpy(dtype=float)
            out[str(c).strip()] = values
        return out
    if suffix == ".npz":
        return read._read_npz(path)
    return read._read_mat(path)


def attach(records, sources, name: str, names=None):
    """The records with the scheduling channel ``name`` read from each source (derived names: unchanged);
    errors name the argument as ``names`` does (default: the CLI's ``--schedule``)."""
    from jointbench.core.ensemble import Ensemble

    if name in DERIVED:
        return records
    if isinstance(records, Ensemble):
        raise InputError(f"{_flag(names)}: a recorded scheduling channel is read for single records, not ensembles")
    out = []
    for rec, src in zip(records, sources):
        variables = _variables(src.path)
        if name not in variables:
            known = ", ".join(k for k in variables if k not in ("time", "fs") and not k.startswith("__")) or "none"
            raise InputError(f"{_flag(names)}: {src.path} has no column or array '{name}'; it has: {known}")
        x = np.asarray(variables[name], float).squeeze()
        if np.any(~np.isfinite(x)):
            raise InputError(f"{_flag(names)}: '{name}' in {src.path} has non-numeric or non-finite values")
        if x.ndim != 1 or len(x) != rec.n:
            raise InputError(f"{_flag(names)}: '{name}' in {src.path} has shape {np.shape(variables[name])}; "
                             f"expected one value per sample ({rec.n})")
        out.append(rec.replace(channels={**rec.channels, name: x}))
    return out


def stiffness_text(est, at: np.ndarray | None = None) -> str:
    """K at the scheduling values ``at`` (default: 5 over the visited range) with the estimate's band."""
    if not hasattr(est, "stiffness_at"):
        return ""
    values = np.linspace(est.lo, est.hi, 5) if at is None else np.asarray(at, float)
    k = est.stiffness_at(values)
    lo, hi = est.stiffness_band(values)
    level = getattr(est, "level", 0.95)
    lines = [f"K at chosen values of the scheduling variable '{est.schedule_name}' (visited {est.lo:.4g} ... "
             f"{est.hi:.4g}; {100 * level:g} % pointwise intervals in [ ]):"]
    for v, kk, a, b in zip(values, k, lo, hi):
        outside = "" if est.lo <= v <= est.hi else "  (outside the visited range: extrapolated)"
        lines.append(f"  {v:10.4g}   K = {kk:.4g} [{a:.4g}, {b:.4g}] N.m/rad{outside}")
    return "\n".join(lines)
