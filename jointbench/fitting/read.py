"""Read users' recordings (CSV, NPZ, MATLAB .mat) into :class:`jointbench.Trial` objects.

Two layouts are understood:

*Columns* (CSV, NPZ, .mat)
    Three one-dimensional series named ``time`` (s), ``angle`` (rad) and ``torque`` (N·m). In a CSV
    they are columns of a file with a header row (names matched case-insensitively, surrounding blanks
    ignored, extra columns ignored, lines starting with ``#`` skipped); in an NPZ or .mat file they
    are variables of any shape that squeezes to 1-D. ``time`` may be left out when the sampling rate
    is known (a scalar variable ``fs`` in an NPZ/.mat file, or ``fs=`` here); time then starts at 0.

*Array* (NPZ, .mat)
    One N×2 array ``[angle, torque]`` picked by name (``array=`` here, ``--array NAME`` or
    ``--input FILE:NAME`` on the command line); the sampling rate comes from a scalar ``fs`` variable
    in the file or from ``fs=``; time starts at 0.

The angle is taken as the imposed signal (``Trial.imposed == "angle"``). Every problem raises
:class:`~jointbench.core.errors.InputError` with a message naming the file.

MATLAB files of versions 4 to 7.2 are read with :func:`scipy.io.loadmat`, version 7.3 (HDF5) with
``h5py`` (an extra: ``pip install 'jointbench[hdf5]'``); a file holding MATLAB class objects (the REKLAB
toolbox's ``nldat``, ``segdat``, ``tvdat``) with mat-io (:mod:`jointbench.fitting.read_matlab`, the extra
``matlab``): such an object picked by ``array=`` is a record whose channels are found by name and whose
sampling rate is ``1 / domainIncr``; a ``segdat`` of several segments is several records
(:func:`read_source`). An NPZ member is loaded only after its header's
claimed size has been checked against the bytes stored and the memory available.
Limits (a regular file, the memory that loading it takes) are checked before anything is loaded:
:mod:`jointbench.fitting.read_limits`.
"""
from __future__ import annotations

import dataclasses
import re
import zipfile
from pathlib import Path
from typing import Mapping, Sequence

import numpy as np

from jointbench.fitting import read_limits as limits
from jointbench.fitting.read_matlab import Recording, Unreadable, read_mat, read_mat73  # noqa: F401 - re-exported
from jointbench.fitting.read_limits import size_text
from jointbench.core.errors import InputError
from jointbench.core.types import Trial

#: File extensions understood by :func:`read_trial`.
SUFFIXES = (".csv", ".npz", ".mat")
COLUMNS = ("time", "angle", "torque")

# Time stamps in text files are rounded; a step may deviate this much (relative) from the mean step
# before the time base counts as non-uniform.
_TIME_TOL = 0.01


@dataclasses.dataclass(frozen=True)
class Source:
    """One record to read: a file and, for the array layout, the array's name.

    Attributes
    ----------
    path : Path
        The file.
    array : str or None
        Name of an N×2 ``[angle, torque]`` array in an NPZ/.mat file, or ``None`` for the column layout.
    """

    path: Path
    array: str | None = None

    @property
    def label(self) -> str:
        """Name used for the trial: the file name, plus ``:array`` for the array layout."""
        return self.path.name + (f":{self.array}" if self.array else "")


def parse_source(spec: str, array: str | None = None) -> Source:
    """Interpret a command-line ``--input`` value.

    ``FILE:NAME`` selects array ``NAME`` of ``FILE`` when ``FILE`` does not itself exist under the
    full spelling and ``NAME`` looks like a variable name; otherwise the whole text is the file and
    ``array`` (the ``--array`` option, may be ``None``) applies.

    Parameters
    ----------
    spec : str
        The value given to ``--input``.
    array : str or None
        Default array name (``--array``).
    """
    path = Path(spec)
    if not path.exists():
        m = re.fullmatch(r"(.+):([A-Za-z_][A-Za-z0-9_]*)", spec)
        if m and m.group(1) not in ("", ".") and not re.fullmatch(r"[A-Za-z]", m.group(1)):
            return Source(Path(m.group(1)), m.group(2))
    return Source(path, array)


def read_trial(path: str | Path, *, array: str | None = None, fs: float | None = None,
               name: str | None = None) -> Trial:
    """Read one record.

    Parameters
    ----------
    path : str or Path
        A ``.csv``, ``.npz`` or ``.mat`` file.
    array : str or None
        Name of an N×2 ``[angle, torque]`` array (NPZ/.mat only); ``None`` for the column layout.
    fs : float or None
        Sampling rate (Hz). Required for the array layout when the file has no ``fs`` variable; when
        both are given they must agree (as must a ``time`` column).
    name : str or None
        Trial name; default the file name (plus ``:array``).

    Returns
    -------
    Trial
        With ``imposed="angle"``.

    Raises
    ------
    InputError
        Missing or unreadable file, unknown extension, missing or malformed variable, NaN/inf,
        non-uniform or non-increasing time, mismatched lengths, fewer than 2 samples, no sampling rate.
    """
    trials = read_records_of(path, array=array, fs=fs, name=name)
    if len(trials) > 1:
        raise InputError(f"{path}: '{array}' holds {len(trials)} segments (a segdat): read it with read_trials "
                         f"(each segment a record of one condition)")
    return trials[0]


def read_records_of(path: str | Path, *, array: str | None = None, fs: float | None = None,
                    name: str | None = None) -> list[Trial]:
    """The records of one file (and array): :func:`read_trial`'s record, or one per segment of a REKLAB
    ``segdat`` object picked by ``array`` (named ``FILE:NAME[segment k]``, k from 1 as REKLAB counts them)."""
    path = Path(path)
    where = str(path)
    if fs is not None and not (np.isfinite(fs) and fs > 0):
        raise InputError(f"{where}: sampling rate must be > 0 Hz, got {fs}")
    if not path.exists():
        raise InputError(f"{where}: no such file")
    if path.is_dir():
        raise InputError(f"{where}: is a folder, not a file")
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise InputError(f"{where}: unknown file type {path.suffix or '(no extension)'!r}; "
                         f"supported: {', '.join(SUFFIXES)}")
    if suffix == ".csv":
        if array is not None:
            raise InputError(f"{where}: an array name ({array!r}) applies to .npz and .mat files only; "
                             f"a CSV file needs columns {', '.join(COLUMNS)}")
        variables = _read_csv(path)
    elif suffix == ".npz":
        variables = read_npz(path)
    else:
        variables = read_mat(path)
    name = name or (path.name + (f":{array}" if array else ""))
    if array is not None:
        return _from_array(variables, array, fs, where, name)
    return [_from_columns(variables, fs, where, name)]


def read_trials(sources: Sequence[Source | str | Path], *, fs: float | None = None) -> list[Trial]:
    """Read several records of one condition and check they share one sampling rate.

    Parameters
    ----------
    sources : sequence of Source, str or Path
        Records to read (a plain path means the column layout).
    fs : float or None
        Sampling rate for records that do not carry one (see :func:`read_trial`).
    """
    srcs = [s if isinstance(s, Source) else Source(Path(s)) for s in sources]
    if not srcs:
        raise InputError("no input file given")
    trials = [t for s in srcs for t in read_records_of(s.path, array=s.array, fs=fs, name=s.label)]
    rates = {t.fs for t in trials}
    if len(rates) > 1:
        listing = ", ".join(f"{t.name} at {t.fs:g} Hz" for t in trials)
        raise InputError(f"records have different sampling rates ({listing}); "
                         f"resample them to one rate first")
    return trials


# --- readers: file -> {name: ndarray} ------------------------------------------------------------

def _read_csv(path: Path) -> dict[str, np.ndarray]:
    import pandas as pd

    where = str(path)
    limits.check_csv(path)
    try:
        df = pd.read_csv(path, comment="#", skipinitialspace=True, dtype=str, keep_default_na=False)
    except pd.errors.EmptyDataError:
        raise InputError(f"{where}: the file is empty; expected a header with columns "
                         f"{', '.join(COLUMNS)}") from None
    except (pd.errors.ParserError, UnicodeDecodeError, OSError) as exc:
        raise InputError(f"{where}: cannot read as CSV: {str(exc).strip()}") from None
    out: dict[str, np.ndarray] = {}
    header = _csv_header(path)
    for key in COLUMNS:
        same = [c for c in header if c.strip().lower() == key]
        if len(same) > 1:
            raise InputError(f"{where}: {len(same)} columns are named {key!r} (ignoring case): "
                             f"{', '.join(map(repr, same))}; keep one or rename the others")
    for col in df.columns:
        key = str(col).strip().lower()
        if key not in COLUMNS or key in out:
            continue
        text = df[col].str.strip()
        values = pd.to_numeric(text.replace("", "nan"), errors="coerce").to_numpy(dtype=float)
        bad = np.isnan(values) & ~text.str.lower().isin(["", "nan", "na", "n/a", "null"]).to_numpy()
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(f"{where}: column '{col}' has a non-numeric value {text.iloc[i]!r} "
                             f"at sample {i} (data row {i + 1})")
        out[key] = values
    if not out and len(df.columns):
        first = ", ".join(str(c) for c in df.columns[:6])
        raise InputError(f"{where}: no column named {', '.join(COLUMNS)} in the header (found: {first}); "
                         f"the first line must name the columns")
    out["__columns__"] = np.array([str(c).strip() for c in df.columns])
    return out


def _npy_header(zf: zipfile.ZipFile, member: str) -> tuple[tuple[int, ...], np.dtype]:
    """Shape and dtype of an ``.npy`` member, read from its header alone."""
    from numpy.lib import format as npf

    with zf.open(member) as f:
        version = npf.read_magic(f)
        reader = {(1, 0): npf.read_array_header_1_0, (2, 0): npf.read_array_header_2_0}.get(version)
        if reader is None:
            raise ValueError(f"unsupported .npy version {version}")
        shape, _, dtype = reader(f)
    return tuple(shape), np.dtype(dtype)


def _csv_header(path: Path) -> list[str]:
    """The names of the first non-comment line of a CSV file, as written (pandas renames duplicates)."""
    import csv

    with open(path, newline="", encoding="utf-8", errors="replace") as f:
        for row in csv.reader(f, skipinitialspace=True):
            if row and not row[0].lstrip().startswith("#"):
                return row
    return []


def read_npz(path: Path) -> dict[str, np.ndarray]:
    """Every member of an NPZ archive, each checked before it is loaded.

    A member's header gives its shape and dtype; a member whose data would be larger than what the
    archive stores for it (uncompressed), or than half the memory available, is refused before any
    allocation (a corrupt or hostile header can claim hundreds of GiB).
    """
    where = str(path)
    limits.check_file(path)
    try:
        with zipfile.ZipFile(path) as zf:
            sizes = {i.filename: i.file_size for i in zf.infolist()}
            claims = {}
            for member in sizes:
                if not member.endswith(".npy"):
                    continue
                shape, dtype = _npy_header(zf, member)
                if dtype.hasobject:
                    continue
                claims[member[:-4]] = (shape, int(np.prod(shape, dtype=object)) * dtype.itemsize)
        for name, (shape, nbytes) in claims.items():
            stored = sizes[name + ".npy"]
            shown = "x".join(map(str, shape)) or "scalar"
            if nbytes > stored:
                raise InputError(f"{where}: member '{name}' claims shape {shown} ({size_text(nbytes)}), more than the "
                                 f"{size_text(stored)} the archive holds for it: the file is corrupt")
            if nbytes > limits.available_memory() // 2:
                raise InputError(f"{where}: member '{name}' is {size_text(nbytes)} ({shown}), more than half the "
                                 f"memory available ({size_text(limits.available_memory())}); split the recording")
        with np.load(path, allow_pickle=False) as data:
            out = {}
            for k in data.files:
                try:
                    out[k] = data[k]
                except ValueError:
                    out[k] = np.array([], dtype=object)  # object array: reported if it is used
            return out
    except InputError:
        raise
    except zipfile.BadZipFile:
        try:  # a single .npy file saved under an .npz name
            with open(path, "rb") as f:
                if f.read(6) == b"\x93NUMPY":
                    raise InputError(f"{where}: is a single .npy array, not an .npz archive of named arrays")
        except OSError:
            pass
        raise InputError(f"{where}: cannot read as NPZ: not a zip archive (numpy.savez writes one)") from None
    except (ValueError, OSError, EOFError, KeyError) as exc:
        raise InputError(f"{where}: cannot read as NPZ: {exc}") from None


# --- layouts: {name: ndarray} -> Trial -----------------------------------------------------------

def what_is_there(variables: Mapping[str, np.ndarray]) -> str:
    if "__columns__" in variables:
        cols = list(variables["__columns__"])
        return "columns found: " + (", ".join(cols) if cols else "(none)")
    names = [f"{k} {v.describe() if isinstance(v, (Recording, Unreadable)) else shape_text(v)}"
             for k, v in variables.items()]
    return "variables found: " + (", ".join(names) if names else "(none)")


def shape_text(v) -> str:
    s = np.shape(v)
    return "scalar" if s == () else "×".join(map(str, s))


def numeric(v, what: str, where: str) -> np.ndarray:
    if isinstance(v, Unreadable):
        raise v.error(where)
    a = np.asarray(v)
    if a.dtype.kind not in "biuf":
        raise InputError(f"{where}: {what} is not a numeric array (MATLAB type or dtype {a.dtype})")
    return a.astype(float)


def _series(variables, key: str, where: str) -> np.ndarray:
    a = numeric(variables[key], f"'{key}'", where)
    a = np.squeeze(a) if a.ndim != 1 else a
    if a.ndim != 1:
        raise InputError(f"{where}: '{key}' must squeeze to one dimension, got shape {shape_text(variables[key])}")
    return a


def file_rate(variables, fs: float | None, where: str) -> float | None:
    """Sampling rate from the file's ``fs`` variable, checked against the ``fs`` argument."""
    if "fs" not in variables or "__columns__" in variables:
        return fs
    v = numeric(variables["fs"], "'fs'", where)
    if v.size != 1:
        raise InputError(f"{where}: 'fs' must be a scalar sampling rate, got shape {shape_text(v)}")
    f = float(v.reshape(()))
    if not (np.isfinite(f) and f > 0):
        raise InputError(f"{where}: 'fs' must be > 0 Hz, got {f}")
    if fs is not None and not np.isclose(f, fs, rtol=1e-9):
        raise InputError(f"{where}: the file says fs = {f:g} Hz but {fs:g} Hz was given")
    return f


def _make_trial(where: str, **kw) -> Trial:
    try:
        return Trial(imposed="angle", **kw)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None


def _from_array(variables, array: str, fs: float | None, where: str, name: str) -> list[Trial]:
    if array not in variables:
        two = [k for k, v in variables.items() if np.ndim(v) == 2 and np.shape(v)[1] == 2]
        hint = f"; N×2 arrays there: {', '.join(two)}" if two else ""
        raise InputError(f"{where}: no array {array!r}; {what_is_there(variables)}{hint}")
    if isinstance(variables[array], Recording):
        return _from_recording(variables[array], fs, where, name)
    a = numeric(variables[array], f"array '{array}'", where)
    if a.ndim != 2 or a.shape[1] != 2:
        tip = " (transpose it to N×2)" if a.ndim == 2 and a.shape[0] == 2 else ""
        raise InputError(f"{where}: array '{array}' must be N×2 [angle, torque], got shape {shape_text(a)}{tip}")
    fs = file_rate(variables, fs, where)
    if fs is None:
        raise InputError(f"{where}: no sampling rate for array '{array}': the file has no scalar 'fs' "
                         f"variable; give it with --fs HZ")
    return [_make_trial(where, time=np.arange(a.shape[0]) / fs, angle=a[:, 0], torque=a[:, 1],
                        fs=fs, name=name)]


def _from_recording(rec: Recording, fs: float | None, where: str, name: str) -> list[Trial]:
    """The records of a REKLAB data object: its angle and torque channels (:meth:`Recording.angle_torque`) at
    ``1 / domainIncr`` Hz from ``domainStart``, one record per segment of a ``segdat``."""
    if rec.realizations > 1:
        raise InputError(f"{where}: {rec.classname} '{rec.variable}' holds {rec.realizations} realizations: an "
                         f"ensemble, read as one (give it as the only input)")
    if fs is not None and not np.isclose(rec.fs, fs, rtol=1e-9):
        raise InputError(f"{where}: {rec.classname} '{rec.variable}' is sampled at {rec.fs:g} Hz (domainIncr "
                         f"{rec.increment:g} s) but {fs:g} Hz was given")
    i, j = rec.angle_torque(where)
    out = []
    for k, ((first, n), t0) in enumerate(zip(rec.segments, rec.starts)):
        label = name if len(rec.segments) == 1 else f"{name}[segment {k + 1}]"
        block = rec.data[first:first + n, :, 0]
        out.append(_make_trial(where, time=t0 + np.arange(n) / rec.fs, angle=block[:, i], torque=block[:, j],
                               fs=rec.fs, name=label))
    return out


def _from_columns(variables, fs: float | None, where: str, name: str) -> Trial:
    rate_known = fs is not None or ("fs" in variables and "__columns__" not in variables)
    needed = ("angle", "torque") if rate_known and "time" not in variables else COLUMNS
    missing = [k for k in needed if k not in variables]
    if missing:
        kind = "column" if "__columns__" in variables else "variable"
        two = [k for k, v in variables.items()
               if k != "__columns__" and np.ndim(v) == 2 and np.shape(v)[1] == 2]
        hint = (f"; or pick an N×2 [angle, torque] array with --array NAME or FILE:NAME "
                f"(candidates: {', '.join(two)})") if two else ""
        raise InputError(f"{where}: missing {kind}{'s' if len(missing) > 1 else ''} "
                         f"{', '.join(map(repr, missing))}; {what_is_there(variables)}{hint}")
    angle = _series(variables, "angle", where)
    torque = _series(variables, "torque", where)
    if "time" not in variables:
        fs = file_rate(variables, fs, where)
        return _make_trial(where, time=np.arange(angle.size) / fs, angle=angle, torque=torque,
                           fs=fs, name=name)
    time = _series(variables, "time", where)
    file_fs = file_rate(variables, fs, where)
    rate, time = time_base(time, where)
    if file_fs is not None and not np.isclose(rate, file_fs, rtol=1e-3):
        raise InputError(f"{where}: the time column gives {rate:.6g} Hz but the sampling rate "
                         f"is given as {file_fs:g} Hz")
    return _make_trial(where, time=time, angle=angle, torque=torque,
                       fs=rate if file_fs is None else file_fs, name=name)


def time_base(t: np.ndarray, where: str) -> tuple[float, np.ndarray]:
    """Sampling rate of a time column, and the time base (rebuilt uniform if only rounding differs).

    The rate is ``(n - 1) / (t[-1] - t[0])``, replaced by the number with the fewest significant digits
    that fits the time stamps as well (every ``t[k]`` within twice the rounding seen in the stamps, and
    at least 1e-6 step, of ``t[0] + k / fs``), so that stamps rounded in a text file still give e.g.
    exactly 2048 Hz.
    """
    bad = ~np.isfinite(t)
    if bad.any():
        raise InputError(f"{where}: 'time' has {int(bad.sum())} non-finite value(s) (NaN or inf), "
                         f"first at sample {int(np.argmax(bad))}")
    if t.size < 2:
        raise InputError(f"{where}: needs at least 2 samples, got {t.size}")
    dt = np.diff(t)
    if (dt <= 0).any():
        i = int(np.argmax(dt <= 0))
        raise InputError(f"{where}: time is not increasing: {t[i]:.9g} s at sample {i} is followed by "
                         f"{t[i + 1]:.9g} s at sample {i + 1}")
    step = (t[-1] - t[0]) / (t.size - 1)
    dev = np.abs(dt - step)
    if dev.max() > _TIME_TOL * step:
        i = int(np.argmax(dev))
        raise InputError(f"{where}: time is not uniform: step {dt[i]:.6g} s between samples {i} and "
                         f"{i + 1}, mean step {step:.6g} s (gaps or jitter; resample to a uniform rate)")
    k = np.arange(t.size)
    fs = 1.0 / step
    tol = max(2.0 * np.abs(t - t[0] - k * step).max(), 1e-6 * step)
    for digits in range(1, 16):
        cand = float(f"{1.0 / step:.{digits}g}")
        if np.abs(t - t[0] - k / cand).max() <= tol:
            fs = cand
            break
    if np.abs(dt - 1.0 / fs).max() > 1e-6 / fs + 1e-9 * np.abs(t).max():
        # only the rounding of the time stamps differs (e.g. 6 decimals in a text file): rebuild
        return fs, t[0] + k / fs
    return fs, t
