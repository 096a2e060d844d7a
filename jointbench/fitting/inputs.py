"""What :func:`jointbench.api.fit` and ``jointbench estimate`` are given, as records.

File paths are read (:mod:`.read`: CSV, NPZ, MATLAB; ``FILE:NAME`` picks an N x 2 array; an NPZ/.mat file
whose angle and torque are 2-D is an ensemble, :mod:`.read_ensemble`), with a recorded scheduling channel
beside them when one is named (:mod:`.schedule`); arrays become a :class:`~jointbench.core.types.Trial`
(1-D) or an :class:`~jointbench.core.ensemble.Ensemble` (2-D, samples x realizations); a trial, a list of
trials or an ensemble is taken as it is. Whether several records are fitted as an ensemble is decided once,
by the pipeline (:func:`jointbench.fitting.pipeline.fit`), not here. Errors name the arguments as the caller
knows them (:func:`jointbench.core.errors.argument`).
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

from jointbench.core.arguments import rate
from jointbench.core.ensemble import Ensemble
from jointbench.core.errors import ConfigError, argument
from jointbench.core.types import Trial


def is_paths(data) -> bool:
    """A file path, or a non-empty list of them."""
    return isinstance(data, (str, Path)) or (isinstance(data, (list, tuple)) and bool(data)
                                             and all(isinstance(d, (str, Path)) for d in data))


def read_files(paths: str | Path | Sequence[str | Path], *, array: str | None = None, fs: float | None = None,
               schedule: str | None = None) -> list[Trial] | Ensemble:
    """The records of files: a list of trials, or the ensemble of a file with 2-D angle and torque (which must
    then be the only file); ``schedule`` names a recorded channel read beside them (names derived from the
    angle need none)."""
    from jointbench.fitting import read, read_ensemble
    from jointbench.fitting import schedule as sched

    paths = [paths] if isinstance(paths, (str, Path)) else list(paths)
    sources = [read.parse_source(str(p), array) for p in paths]
    records = read_ensemble.read_records(sources, fs=fs)
    if schedule:
        records = sched.attach(records, sources, schedule)
    return records


def from_arrays(angle, torque, fs: float | None) -> list[Trial] | Ensemble:
    """One record from 1-D arrays, an ensemble from 2-D ones (samples x realizations), sampled at ``fs`` Hz."""
    import numpy as np

    if fs is None:
        raise ConfigError(f"{argument('fs')}: angle= and torque= need the sampling rate (Hz)")
    if np.ndim(angle) == 2:
        return Ensemble.from_arrays(angle, torque, float(fs), name="record")
    return [Trial.from_arrays(angle, torque, float(fs), name="record")]


def records(data=None, *, angle=None, torque=None, fs: float | None = None, array: str | None = None,
            schedule: str | None = None) -> list[Trial] | Ensemble:
    """The records in ``data`` (a trial, a list of trials, an ensemble, or file paths) or in the arrays
    ``angle`` and ``torque``: a list of trials, or an ensemble (given as one, or read from one file)."""
    fs = rate(fs)
    if data is not None and (angle is not None or torque is not None):
        raise ConfigError(f"give either {argument('data')} (records, an ensemble or file paths) or the arrays "
                          f"angle= and torque=, not both")
    if data is None:
        if angle is None or torque is None:
            raise ConfigError(f"give {argument('data')} (a Trial, a list of records, an Ensemble or file paths), "
                              f"or the arrays angle= and torque= with {argument('fs')}")
        return from_arrays(angle, torque, fs)
    if is_paths(data):
        return read_files(data, array=array, fs=fs, schedule=schedule)
    if isinstance(data, Ensemble):
        return data
    if isinstance(data, Trial):
        return [data]
    if isinstance(data, (list, tuple)) and data and all(isinstance(d, Trial) for d in data):
        return list(data)
    raise ConfigError(f"{argument('data')}: must be a Trial, a list of Trials, an Ensemble or file paths, got "
                      f"{type(data).__name__}")
