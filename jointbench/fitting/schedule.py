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
        check_span(x, f"'{name}' in {src.path}")
        out.append(rec.replace(channels={**rec.channels, name: x}))
    return out


#: a recorded schedule must span this many times the range its noise alone reaches over the record
SPAN_OVER_NOISE = 2.0


def noise_level(x: np.ndarray) -> float:
    """The standard deviation of the white noise on a smoothly varying signal ``x``, from its second
    differences (pseudo-residuals, whose variance is ``6 sigma^2`` for white noise while a smooth signal's
    nearly cancel): ``1.4826 MAD(diff(x, 2)) / sqrt(6)``, the median making a few steps harmless.

    References
    ----------
    Gasser, T., Sroka, L. & Jennen-Steinmetz, C. (1986). Residual variance and residual pattern in nonlinear
    regression. Biometrika 73(3), 625-633 (the difference-based variance estimator); 1.4826: the MAD's factor
    for a Gaussian's standard deviation.
    """
    d = np.diff(np.asarray(x, float), 2)
    if d.size == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / np.sqrt(6.0))


def check_span(x: np.ndarray, what: str) -> None:
    """Refuse a recorded scheduling variable whose span is not :data:`SPAN_OVER_NOISE` times the range that
    its noise alone reaches over its ``n`` samples, ``2 sigma sqrt(2 ln n)`` (the expected extreme of ``n``
    Gaussian samples is about ``sigma sqrt(2 ln n)``): a channel that wanders over a few mrad of noise would
    otherwise pass the estimator's relative ``min_span`` and K over it be printed as a function of noise.

    References
    ----------
    Cramér, H. (1946). Mathematical Methods of Statistics, sec. 28.6 (the largest of n normal samples).
    """
    x = np.asarray(x, float)
    sigma = noise_level(x)
    reach = 2.0 * sigma * np.sqrt(2.0 * np.log(max(x.size, 2)))
    span = float(np.ptp(x)) if x.size else 0.0
    if not span > SPAN_OVER_NOISE * reach:
        raise InputError(f"{argument('schedule')}: {what} spans {span:.3g}, within {SPAN_OVER_NOISE:g} x the "
                         f"{reach:.3g} that its noise (sd {sigma:.3g}) alone reaches over {x.size} samples: it does "
                         f"not move; record a scheduling variable that varies, or fit a time-invariant model")
