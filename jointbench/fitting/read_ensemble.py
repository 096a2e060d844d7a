"""Read ensembles (realizations of one time-varying condition) for ``jointbench estimate``.

Two layouts (see ``docs/estimate.md``, *Ensembles*): one NPZ/.mat file whose ``angle`` and ``torque``
are 2-D, samples × realizations, with a scalar ``fs`` or a 1-D ``time``; or several records of equal
length and rate (read by :func:`jointbench.fitting.read.read_trials`) taken as realizations. Every
problem raises :class:`~jointbench.core.errors.InputError` with a message naming the file. Kept beside
:mod:`jointbench.fitting.read` (whose readers and checks it reuses) so that the single-record reader
stays small.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from jointbench.fitting.read import (Source, file_rate, numeric, read_mat, read_npz, shape_text, time_base,
                                      what_is_there, read_trials)
from jointbench.fitting.read_matlab import Recording
from jointbench.core.ensemble import Ensemble
from jointbench.core.errors import InputError, argument

def is_ensemble_file(source: Source | str | Path) -> bool:
    """True for an NPZ/.mat file (column layout) whose ``angle`` and ``torque`` are 2-D (samples × realizations),
    or a REKLAB data object (``nldat``, ``tvdat``) of several realizations picked by ``FILE:NAME``."""
    src = source if isinstance(source, Source) else Source(Path(source))
    suffix = src.path.suffix.lower()
    if (src.array is not None and suffix != ".mat") or suffix not in (".npz", ".mat") or not src.path.is_file():
        return False
    try:
        variables = read_npz(src.path) if suffix == ".npz" else read_mat(src.path)
    except InputError:
        return False
    if src.array is not None:
        rec = variables.get(src.array)
        return isinstance(rec, Recording) and rec.realizations > 1
    return all(k in variables and np.ndim(variables[k]) == 2 and min(np.shape(variables[k])) > 1
               for k in ("angle", "torque"))


def read_ensemble(path: str | Path, *, fs: float | None = None, name: str | None = None, array: str | None = None):
    """Read an ensemble: an NPZ or .mat file whose ``angle`` and ``torque`` are 2-D, samples × realizations.

    The sampling rate comes from a scalar ``fs`` variable, a 1-D ``time`` variable (one per sample, shared
    by every realization) or the ``fs`` argument; time starts at ``time[0]`` (or 0).

    ``array`` picks a REKLAB data object (``nldat``, ``tvdat``) of a .mat file instead, whose ``dataSet`` is
    samples x channels x realizations (:func:`object_ensemble`).

    Returns
    -------
    jointbench.core.ensemble.Ensemble
        Realizations named ``FILE[r]`` (r from 0), ``imposed="angle"``.

    Raises
    ------
    InputError
        One line naming the file: missing or non-numeric variables, shapes that differ or look transposed,
        a ``time`` that is not one shared time base, no sampling rate, NaN/inf (naming the realization).
    """
    path = Path(path)
    where = str(path)
    if not path.is_file():
        raise InputError(f"{where}: no such file")
    suffix = path.suffix.lower()
    if suffix not in (".npz", ".mat"):
        raise InputError(f"{where}: an ensemble file must be .npz or .mat with 2-D angle and torque "
                         f"(samples x realizations), got {path.suffix or '(no extension)'!r}")
    variables = read_npz(path) if suffix == ".npz" else read_mat(path)
    if array is not None:
        return object_ensemble(variables.get(array), fs, where, name or f"{path.name}:{array}")
    missing = [k for k in ("angle", "torque") if k not in variables]
    if missing:
        raise InputError(f"{where}: missing variable{'s' if len(missing) > 1 else ''} "
                         f"{', '.join(map(repr, missing))}; {what_is_there(variables)}")
    a = numeric(variables["angle"], "'angle'", where)
    y = numeric(variables["torque"], "'torque'", where)
    if a.ndim != 2 or y.ndim != 2:
        raise InputError(f"{where}: an ensemble needs 2-D 'angle' and 'torque' (samples x realizations), got "
                         f"shapes {shape_text(a)} and {shape_text(y)}")
    if a.shape != y.shape:
        raise InputError(f"{where}: 'angle' ({shape_text(a)}) and 'torque' ({shape_text(y)}) differ in shape; "
                         f"both must be samples x realizations")
    t0 = 0.0
    if "time" in variables:
        t = numeric(variables["time"], "'time'", where)
        t = np.squeeze(t) if t.ndim == 2 and min(t.shape) == 1 else t
        if t.ndim == 2 and t.shape == a.shape:
            if not np.allclose(t, t[:, :1]):
                raise InputError(f"{where}: 'time' differs between realizations; the realizations of an ensemble "
                                 f"share one time base (aligned sample by sample)")
            t = t[:, 0]
        if t.ndim != 1:
            raise InputError(f"{where}: 'time' must be one time base for all realizations (1-D), got shape "
                             f"{shape_text(variables['time'])}")
        if len(t) != a.shape[0]:
            tip = " (transpose 'angle' and 'torque' to samples x realizations)" if len(t) == a.shape[1] else ""
            raise InputError(f"{where}: 'time' has {len(t)} samples but 'angle' has {a.shape[0]} rows{tip}")
        rate, t = time_base(t, where)
        file_fs = file_rate(variables, fs, where)
        if file_fs is not None and not np.isclose(rate, file_fs, rtol=1e-3):
            raise InputError(f"{where}: the time variable gives {rate:.6g} Hz but the sampling rate is given as "
                             f"{file_fs:g} Hz")
        fs, t0 = (rate if file_fs is None else file_fs), float(t[0])
    else:
        fs = file_rate(variables, fs, where)
        if fs is None:
            raise InputError(f"{where}: no sampling rate: the file has neither a scalar 'fs' nor a 'time' "
                             f"variable; give it with --fs HZ")
        if a.shape[0] < a.shape[1]:
            raise InputError(f"{where}: 'angle' is {shape_text(a)}: an ensemble is samples x realizations (more "
                             f"samples than realizations); transpose 'angle' and 'torque'")
    label = name or path.name
    try:
        return Ensemble.from_arrays(a, y, fs, t0=t0, name=label,
                                    names=[f"{label}[{r}]" for r in range(a.shape[1])])
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None


def object_ensemble(rec: Recording, fs: float | None, where: str, label: str):
    """The ensemble of a REKLAB data object of several realizations: its angle and torque channels (found by
    name, :meth:`~jointbench.fitting.read_matlab.Recording.angle_torque`), samples x realizations, at
    ``1 / domainIncr`` Hz from ``domainStart``."""
    if not isinstance(rec, Recording) or len(rec.segments) > 1:
        raise InputError(f"{where}: '{label}' is not a REKLAB nldat or tvdat object of several realizations")
    if fs is not None and not np.isclose(rec.fs, fs, rtol=1e-9):
        raise InputError(f"{where}: {rec.classname} '{rec.variable}' is sampled at {rec.fs:g} Hz (domainIncr "
                         f"{rec.increment:g} s) but {fs:g} Hz was given")
    i, j = rec.angle_torque(where)
    try:
        return Ensemble.from_arrays(rec.data[:, i, :], rec.data[:, j, :], rec.fs, t0=float(rec.starts[0]),
                                    name=label, names=[f"{label}[{r}]" for r in range(rec.realizations)])
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None


def read_records(sources: Sequence[Source | str | Path], *, fs: float | None = None):
    """The records of ``sources``: a list of trials, or the ensemble of a file with 2-D angle and torque
    (:func:`is_ensemble_file`), which must then be the only source. Whether several records are fitted as
    an ensemble is the pipeline's decision (:func:`jointbench.fitting.pipeline.fit`)."""
    srcs = [s if isinstance(s, Source) else Source(Path(s)) for s in sources]
    two_d = [s for s in srcs if is_ensemble_file(s)]
    if two_d:
        if len(srcs) > 1:
            raise InputError(f"{two_d[0].path}: holds an ensemble (2-D angle and torque); give it as the only "
                             f"{argument('data')}, or give one record per file")
        return read_ensemble(two_d[0].path, fs=fs, array=two_d[0].array)
    return read_trials(srcs, fs=fs)
