"""A parameter-varying fit's scheduling variable (``schedule=`` of :func:`jointbench.api.fit`, ``jointbench
estimate --schedule``).

``angle_slow`` (or ``angle``) derives the scheduling variable from the angle; any other name is a column of a
CSV input or an array of an NPZ/.mat input, read beside the angle and torque and carried through the
decimation and cropping as a channel of the record (:attr:`jointbench.core.types.Trial.channels`). The
estimator must take a ``schedule`` setting (``pv_irf``).
"""
from __future__ import annotations

import numpy as np

from jointbench.core.errors import ConfigError, InputError, argument

#: scheduling variables derived from the angle (anything else is read from the input)
DERIVED = ("angle_slow", "angle")


def check_schedulable(name: str) -> None:
    """Refuse an estimator that takes no ``schedule`` setting (one line naming the parameter-varying ones)."""
    import dataclasses

    from jointbench import estimators

    cls = estimators.REGISTRY.get(name)
    if "schedule" not in {f.name for f in dataclasses.fields(cls.Settings)}:
        takes = [n for n in estimators.REGISTRY.names("lpv")]
        raise ConfigError(f"{argument('schedule')}: estimator '{name}' takes no scheduling variable; "
                          f"parameter-varying estimators: {', '.join(takes) or 'none'}")


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
        return read.read_npz(path)
    return read.read_mat(path)


def attach(records, sources, name: str):
    """The records with the scheduling channel ``name`` read from each source (derived names: unchanged)."""
    from jointbench.core.ensemble import Ensemble

    if name in DERIVED:
        return records
    if isinstance(records, Ensemble):
        raise InputError(f"{argument('schedule')}: a recorded scheduling channel is read for single records, "
                         f"not ensembles")
    out = []
    for rec, src in zip(records, sources):
        variables = _variables(src.path)
        if name not in variables:
            known = ", ".join(k for k in variables if k not in ("time", "fs") and not k.startswith("__")) or "none"
            raise InputError(f"{argument('schedule')}: {src.path} has no column or array '{name}'; it has: {known}")
        x = np.asarray(variables[name], float).squeeze()
        if np.any(~np.isfinite(x)):
            raise InputError(f"{argument('schedule')}: '{name}' in {src.path} has non-numeric or non-finite values")
        if x.ndim != 1 or len(x) != rec.n:
            raise InputError(f"{argument('schedule')}: '{name}' in {src.path} has shape {np.shape(variables[name])}; "
                             f"expected one value per sample ({rec.n})")
        out.append(rec.replace(channels={**rec.channels, name: x}))
    return out
