"""Profile ``file``: a time variation recorded or designed elsewhere, read from a CSV or NPY file.

YAML: ``K: {shape: file, path: data/stiffness.csv}`` with, in the file, a header line ``time,value``
then one ``time,value`` row per sample (times in seconds, increasing); or a ``.npy`` array of shape
(n, 2) holding the same two columns. Lines starting with ``#`` are comments.
"""
from __future__ import annotations

import csv
import dataclasses
import functools
import hashlib
from pathlib import Path
from typing import ClassVar, Literal

import numpy as np

from jointbench.core.errors import ConfigError
from jointbench.core.schema import param
from jointbench.sims.registries import PROFILES
from jointbench.sims.profile import interpolate


@PROFILES.register("file")
@dataclasses.dataclass(frozen=True)
class FromFile:
    """Values at the times listed in a file, joined by straight lines (``interpolate: linear``, the
    default) or each held until the next time (``step``).

    Outside the file's time range the profile is undefined: evaluating it there is an error naming the
    file and the range (``outside: error``, the default), unless ``outside: hold`` holds the first and
    last values. The minimum is the smallest value in the file (both interpolations stay between the
    listed values), so a joint checks positivity from it when the config is read.

    Parameters
    ----------
    path : str
        The file, ``.csv`` (header ``time,value``) or ``.npy`` (shape (n, 2): time, value); a relative
        path is taken from the working directory. At least two rows, finite, times strictly increasing.
    interpolate : {'linear', 'step'}
        Between the listed times.
    outside : {'error', 'hold'}
        Before the first and after the last time.
    sha256 : str, optional
        The file's SHA-256 (hex); when given, a file with other contents is refused. Without it an edited
        file is simply a new input: the harness keys finished cases by the contents of the files they read
        (:func:`benchmarks.harness.case.input_files`), so an edit is recomputed, never served from the cache.
    """

    path: str = param(doc="CSV (header 'time,value') or NPY (n x 2) file; relative to the working directory")
    interpolate: Literal["linear", "step"] = param("linear", doc="straight lines or held values between rows")
    outside: Literal["error", "hold"] = param("error", doc="outside the file's times: an error, or hold the end values")
    sha256: str | None = param(None, doc="expected SHA-256 of the file (hex); none = not checked")

    shape: ClassVar[str] = "file"

    def __post_init__(self):
        t, v = _load(self.path, self.sha256)
        object.__setattr__(self, "_times", t)
        object.__setattr__(self, "_values", v)

    @property
    def times(self) -> np.ndarray:
        """The file's times (s)."""
        return self._times

    @property
    def values(self) -> np.ndarray:
        """The file's values."""
        return self._values

    def at(self, t: np.ndarray) -> np.ndarray:
        tt = np.asarray(t, float)
        knots, vals = self._times, self._values
        if self.outside == "error" and tt.size and (tt.min() < knots[0] or tt.max() > knots[-1]):
            bad = tt.min() if tt.min() < knots[0] else tt.max()
            raise ConfigError(f"profile file {self.path}: asked for t = {bad:g} s, outside the file's times "
                              f"{knots[0]:g} ... {knots[-1]:g} s (give outside: hold to hold the end values)")
        return interpolate(knots, vals, tt, self.interpolate)

    @property
    def minimum(self) -> float:
        """The smallest value in the file: the smallest the profile takes."""
        return float(self._values.min())

    @property
    def constant(self) -> bool:
        return bool(np.all(self._values == self._values[0]))


#: a profile file's limits, checked before it is parsed: its size and rows (a profile is interpolated
#: where the simulation needs it; a million rows is 1 ms resolution over 17 minutes, longer than any trial)
MAX_PROFILE_BYTES = 64_000_000
MAX_PROFILE_ROWS = 1_000_000


def _load(path: str, sha256: str | None) -> tuple[np.ndarray, np.ndarray]:
    """``(times, values)`` of a profile file, checked; every error names the file."""
    from jointbench.core.files import file_problem

    p = Path(path)
    problem = file_problem(p, MAX_PROFILE_BYTES)
    if problem == "file not found":
        raise ConfigError(f"profile file {path}: not found (relative paths are taken from the working directory "
                          f"{Path.cwd()})")
    if problem is not None:
        raise ConfigError(f"profile file {path}: {problem}" + (" for a profile" if "allowed" in problem else ""))
    if sha256 is not None:
        got = hashlib.sha256(p.read_bytes()).hexdigest()
        if got != sha256.strip().lower():
            raise ConfigError(f"profile file {path}: its SHA-256 is {got}, not the {sha256} of the config "
                              f"(the file changed?)")
    return _read(str(p.resolve()), p.stat().st_mtime_ns, path)


@functools.lru_cache(maxsize=16)
def _read(resolved: str, mtime_ns: int, shown: str) -> tuple[np.ndarray, np.ndarray]:
    """Parse and check a profile file (cached by path and modification time; arrays read-only)."""
    suffix = Path(resolved).suffix.lower()
    if suffix == ".npy":
        try:                           # mapped, not read: a header claiming more than the file holds fails here
            data = np.load(resolved, allow_pickle=False, mmap_mode="r")
        except (ValueError, OSError, EOFError) as exc:
            raise ConfigError(f"profile file {shown}: not a readable .npy array ({exc})") from None
        if data.ndim != 2 or data.shape[1] != 2 or not np.issubdtype(data.dtype, np.number):
            raise ConfigError(f"profile file {shown}: expected a numeric array of shape (n, 2) (time, value), "
                              f"got {data.dtype} {data.shape}")
        if data.shape[0] > MAX_PROFILE_ROWS:
            raise ConfigError(f"profile file {shown}: {data.shape[0]} rows, more than the {MAX_PROFILE_ROWS} a "
                              f"profile may have; resample it")
        t, v = np.array(data[:, 0], float), np.array(data[:, 1], float)
    elif suffix == ".csv":
        t, v = _read_csv(resolved, shown)
    else:
        raise ConfigError(f"profile file {shown}: unsupported type {suffix or '(none)'!r}; use .csv (header "
                          f"'time,value') or .npy (n x 2)")
    if len(t) < 2:
        raise ConfigError(f"profile file {shown}: needs at least 2 rows (time, value), got {len(t)}")
    bad = np.flatnonzero(~(np.isfinite(t) & np.isfinite(v)))
    if bad.size:
        raise ConfigError(f"profile file {shown}: row {bad[0] + 1} of the data is not finite "
                          f"(time {t[bad[0]]}, value {v[bad[0]]})")
    step = np.flatnonzero(np.diff(t) <= 0)
    if step.size:
        i = step[0]
        raise ConfigError(f"profile file {shown}: times must increase strictly; data rows {i + 1} and {i + 2} have "
                          f"times {t[i]:g} and {t[i + 1]:g} s")
    t.flags.writeable = False
    v.flags.writeable = False
    return t, v


def _read_csv(path: str, shown: str) -> tuple[np.ndarray, np.ndarray]:
    import io

    from jointbench.core.files import decode_text

    data = Path(path).read_bytes()
    n_lines = data.count(b"\n")
    if n_lines > MAX_PROFILE_ROWS + 1000:
        raise ConfigError(f"profile file {shown}: {n_lines} lines, more than the {MAX_PROFILE_ROWS} rows a profile "
                          f"may have; resample it")
    text = decode_text(data, f"profile file {shown}", ConfigError)
    rows = [(i, r) for i, r in enumerate(csv.reader(io.StringIO(text, newline="")), start=1)
            if r and any(c.strip() for c in r) and not r[0].lstrip().startswith("#")]
    if not rows:
        raise ConfigError(f"profile file {shown}: empty; expected a header 'time,value' and rows")
    line, header = rows[0]
    if [c.strip() for c in header] != ["time", "value"]:
        raise ConfigError(f"profile file {shown}: line {line}: expected the header 'time,value' (time in s), "
                          f"got {','.join(header)!r}")
    t, v = [], []
    for line, r in rows[1:]:
        if len(r) != 2:
            raise ConfigError(f"profile file {shown}: line {line}: expected 2 fields (time,value), got {len(r)}")
        try:
            t.append(float(r[0]))
            v.append(float(r[1]))
        except ValueError:
            raise ConfigError(f"profile file {shown}: line {line}: not two numbers: {','.join(r)!r}") from None
    return np.array(t), np.array(v)
