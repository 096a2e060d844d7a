"""MATLAB .mat files: v4 to v7.2 through :func:`scipy.io.loadmat`, v7.3 (HDF5) through h5py (an extra: ``pip install
'jointbench[hdf5]'``), and MATLAB class objects in either: the REKLAB toolbox's data objects ``nldat``, ``segdat``
and ``tvdat`` (:func:`read_mat`).

MATLAB saves a ``classdef`` object (MCOS) as opaque class data that :func:`scipy.io.loadmat` cannot decode (it
returns a variable named ``None`` and a warning). When a file holds such objects its variables are read with
mat-io (``matio.load_from_mat``, an extra: ``pip install 'jointbench[matlab]'``), which decodes MCOS objects of
v7 and v7.3 files into their property maps. A REKLAB data object becomes a :class:`Recording`: its ``dataSet``
(samples x channels x realizations), ``chanNames``, ``domainIncr`` (the sampling increment, s) and
``domainStart``; a ``segdat`` adds its segments (``onsetPointer``, ``segLength`` of its ``parameterSet``). Any
other object is an :class:`Unreadable` naming its class, reported in one line when it is used.

The toolbox's class definitions (``@nldat/nldat.m``, ``@segdat/segdat.m``, ``@tvdat/tvdat.m``, ``@param``) were
read to learn the property names; no toolbox code is used.

References
----------
Kearney, R. E. et al. REKLAB NLID toolbox (reklab/reklab_public, GPL-2): the ``nldat`` data class (``dataSet``
of size samples x channels x realizations, ``domainIncr``, ``domainStart``, ``chanNames``), ``segdat`` (segments
by ``onsetPointer`` and ``segLength``, one ``domainStart`` per segment) and ``tvdat`` (realizations along a
second domain).
"""
from __future__ import annotations

import dataclasses
import re
import warnings
from pathlib import Path

import numpy as np

from jointbench.core.errors import InputError
from jointbench.fitting import read_limits
from jointbench.fitting.read_limits import size_text

#: the REKLAB data classes read as recordings
CLASSES = ("nldat", "segdat", "tvdat")
#: how to get the reader
INSTALL = "pip install 'jointbench[matlab]' (mat-io, Python >= 3.11)"

#: channel names that say which channel is the angle and which the torque (REKLAB's own: pos1/tq1, posPert1/tqPert1)
ANGLE_NAME = re.compile(r"pos|ang|theta|displ", re.IGNORECASE)
TORQUE_NAME = re.compile(r"tq|torq|trq|moment", re.IGNORECASE)


@dataclasses.dataclass(frozen=True, eq=False)
class Recording:
    """A REKLAB data object (``nldat``, ``segdat``, ``tvdat``) as arrays.

    Attributes
    ----------
    variable, classname : str
        The variable's name in the file and its MATLAB class.
    data : ndarray
        ``dataSet`` as samples x channels x realizations.
    channels : tuple of str
        ``chanNames``, one per channel.
    increment : float
        ``domainIncr``: the sampling increment (s).
    starts : ndarray
        ``domainStart``: the time of the first sample (s), one per segment.
    segments : tuple of (int, int)
        ``(first sample, length)`` of each segment (0-based); one segment spanning the data for ``nldat`` and
        ``tvdat``.
    """

    variable: str
    classname: str
    data: np.ndarray
    channels: tuple[str, ...]
    increment: float
    starts: np.ndarray
    segments: tuple[tuple[int, int], ...]

    def __array__(self, dtype=None, copy=None):
        """The data as a plain array (samples x channels, or x realizations when there are several), so that a
        recording can stand wherever a variable's array is read (a scheduling channel of one column)."""
        a = self.data[:, :, 0] if self.data.shape[2] == 1 else self.data
        return a if dtype is None else a.astype(dtype)

    @property
    def realizations(self) -> int:
        return int(self.data.shape[2])

    @property
    def fs(self) -> float:
        """The sampling rate ``1 / domainIncr`` (Hz), to 12 significant digits (``1 / 0.001`` is 1000)."""
        return float(f"{1.0 / self.increment:.12g}")

    def describe(self) -> str:
        """``nldat 60000×2 (pos1, tq1)``: for the list of variables in an error message."""
        n, c, r = self.data.shape
        size = f"{n}×{c}" + (f"×{r}" if r > 1 else "")
        segs = f", {len(self.segments)} segments" if len(self.segments) > 1 else ""
        return f"{self.classname} {size} ({', '.join(self.channels)}{segs})"

    def angle_torque(self, where: str) -> tuple[int, int]:
        """The channels of the angle and the torque: by name (one channel named like a position, ``pos``,
        ``angle``, ``theta``, and another like a torque, ``tq``, ``torque``), else, for two channels, in
        REKLAB's order of an identification's data, ``[input, output]``; one line naming the channels
        otherwise."""
        names = self.channels
        ang = [i for i, n in enumerate(names) if ANGLE_NAME.search(n) and not TORQUE_NAME.search(n)]
        tq = [i for i, n in enumerate(names) if TORQUE_NAME.search(n) and not ANGLE_NAME.search(n)]
        if len(ang) == 1 and len(tq) == 1:
            return ang[0], tq[0]
        if len(names) == 2 and not ang and not tq:
            return 0, 1
        raise InputError(f"{where}: {self.classname} '{self.variable}' has channels {', '.join(map(repr, names))}: "
                         f"their names do not say which one is the angle and which the torque (names with pos, "
                         f"angle or theta; tq or torque); save the two as one {self.classname} [angle, torque]")


@dataclasses.dataclass(frozen=True)
class Unreadable:
    """A MATLAB object this reader cannot turn into a recording: its class and why (reported when used)."""

    variable: str
    classname: str
    reason: str

    def __array__(self, dtype=None, copy=None):
        return np.array([], dtype=object)

    def describe(self) -> str:
        return f"{self.classname} object"

    def error(self, where: str) -> InputError:
        return InputError(f"{where}: '{self.variable}' is a MATLAB object of class {self.classname}: {self.reason}")


def read_mat(path: Path) -> dict[str, np.ndarray]:
    """The variables of a MATLAB .mat file: v4-v7.2 through SciPy, v7.3 through h5py (:func:`read_mat73`),
    a file holding MATLAB class objects (which SciPy returns undecoded, as a variable ``None``) through mat-io
    (:func:`read_objects`)."""
    import warnings

    from scipy import io as sio

    where = str(path)
    read_limits.check_file(path)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", sio.matlab.MatReadWarning)    # objects: "Duplicate variable name None"
            data = sio.loadmat(path)
    except NotImplementedError:        # version 7.3: HDF5
        return read_mat73(path)
    except (sio.matlab.MatReadError, ValueError, TypeError, OSError, EOFError) as exc:
        raise InputError(f"{where}: cannot read as a MATLAB .mat file: {exc}") from None
    classes = opaque_classes(data)
    plain = {k: v for k, v in data.items() if not k.startswith("__") and k != "None"}
    if classes:
        return read_objects(path, classes, plain)
    return plain


def read_mat73(path: Path) -> dict[str, np.ndarray]:
    """Top-level numeric variables of a MATLAB v7.3 (HDF5) file, with MATLAB's shapes.

    MATLAB stores arrays column-major, so HDF5 sees them transposed: an N x 2 matrix is a 2 x N
    dataset; they are transposed back. Variables that are not numeric arrays (char, cell, struct,
    sparse, ...) are kept as empty object arrays, reported only if used.
    """
    where = str(path)
    try:
        import h5py
    except ImportError:  # h5py is an extra: pip install 'jointbench[hdf5]'
        raise InputError(f"{where}: MATLAB v7.3 (HDF5) file: reading it needs h5py, not installed: pip install "
                         f"'jointbench[hdf5]' (or save with: save(file, ..., '-v7'))") from None
    try:
        with h5py.File(path, "r") as f:
            out = {}
            objects = {}
            for name, obj in f.items():
                if name.startswith("#"):
                    continue                  # MATLAB's internal references group
                cls = obj.attrs.get("MATLAB_class", b"")
                cls = cls.decode() if isinstance(cls, bytes) else str(cls)
                if "MATLAB_object_decode" in obj.attrs:
                    objects[name] = cls       # a class object (MCOS): mat-io decodes it
                    continue
                numeric = isinstance(obj, h5py.Dataset) and obj.dtype.kind in "biuf" and cls not in ("char", "logical")
                if not numeric or obj.attrs.get("MATLAB_empty", 0):
                    out[name] = np.array([], dtype=object)
                    continue
                nbytes = int(np.prod(obj.shape, dtype=object)) * obj.dtype.itemsize
                if nbytes > read_limits.available_memory() // 2:
                    raise InputError(f"{where}: variable '{name}' is {size_text(nbytes)}, more than half the "
                                     f"memory available; split the recording")
                out[name] = np.asarray(obj[()]).T
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - h5py on a damaged file raises RuntimeError, AttributeError, ...
        text = " ".join(str(exc).split()) or type(exc).__name__
        raise InputError(f"{where}: cannot read as a MATLAB v7.3 (HDF5) .mat file (damaged?): {text}") from None
    return read_objects(path, objects, out) if objects else out


def opaque_classes(data: dict) -> dict[str, str]:
    """Variable name -> class of the MATLAB objects that :func:`scipy.io.loadmat` returned undecoded
    (``scipy.io.matlab.MatlabOpaque``: fields ``s0`` the name, ``s2`` the class)."""
    from scipy.io.matlab import MatlabOpaque

    out = {}
    for value in data.values():
        if isinstance(value, MatlabOpaque) and value.size:
            rec = value.reshape(-1)[0]
            name, cls = (_text(rec["s0"]), _text(rec["s2"])) if value.dtype.names else ("", "")
            out[name or f"object {len(out) + 1}"] = cls or "unknown"
    return out


def without_reader(path: Path, classes: dict[str, str], plain: dict) -> dict:
    """The variables of a file with objects when mat-io is not installed: its plain arrays, and each object an
    :class:`Unreadable` saying what to install."""
    out = dict(plain)
    for name, cls in classes.items():
        out[name] = Unreadable(name, cls, f"reading MATLAB objects needs mat-io, not installed: {INSTALL}")
    return out


def load_matio():
    """``matio`` (mat-io), imported without its side effects on pandas (its table converter sets
    ``pandas.options.future.infer_string`` on import); None when not installed."""
    import importlib.util

    if importlib.util.find_spec("matio") is None:
        return None
    import pandas as pd

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            before = pd.get_option("future.infer_string")
        except Exception:  # noqa: BLE001 - an option a later pandas removes
            before = None
        try:
            import matio
        except ImportError:          # installed without what it needs (h5py): as if absent
            return None
        if before is not None and pd.get_option("future.infer_string") != before:
            pd.set_option("future.infer_string", before)
    return matio


def read_objects(path: Path, classes: dict[str, str], plain: dict | None = None) -> dict:
    """Every variable of a .mat file (v7 or v7.3) that holds MATLAB objects, read with mat-io: numeric arrays as
    they are, REKLAB data objects as :class:`Recording`, other objects as :class:`Unreadable`, anything else
    (text, cells, structs, tables) as an empty object array (reported only if used). Without mat-io:
    :func:`without_reader`."""
    where = str(path)
    matio = load_matio()
    if matio is None:
        return without_reader(path, classes, plain or {})
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            data = matio.load_from_mat(str(path))
    except Exception as exc:  # noqa: BLE001 - mat-io raises many kinds on a damaged or unusual file
        text = " ".join(str(exc).split()) or type(exc).__name__
        raise InputError(f"{where}: cannot read the MATLAB objects in it ({', '.join(sorted(set(classes.values())))}) "
                         f"with mat-io: {text}") from None
    out = {}
    for name, value in data.items():
        if name.startswith("__"):
            continue
        cls = getattr(value, "classname", None)
        if cls is not None and isinstance(value, np.ndarray):      # an array of objects (MatlabOpaqueArray)
            if value.size != 1:
                out[name] = Unreadable(name, cls, f"an array of {value.size} objects; jointbench reads one object "
                                                  f"per variable (save each as its own variable)")
                continue
            value = value.reshape(-1)[0]
        if cls is not None:
            out[name] = recording(name, value, where) if cls in CLASSES else Unreadable(
                name, cls, f"not a data class jointbench reads (it reads REKLAB's {', '.join(CLASSES)})")
        elif isinstance(value, np.ndarray) and value.dtype.kind in "biuf":
            out[name] = value
        elif isinstance(value, np.ndarray) or value is None:
            out[name] = np.array([], dtype=object)          # text, cell, struct: reported if used
        else:                                               # an object mat-io converted (table, datetime, ...)
            cls = "table" if type(value).__name__ == "DataFrame" else type(value).__name__
            out[name] = Unreadable(name, cls, f"not a data class jointbench reads (it reads numeric arrays and "
                                              f"REKLAB's {', '.join(CLASSES)}); save its columns as arrays")
    return out


def recording(name: str, obj, where: str) -> Recording | Unreadable:
    """A REKLAB data object's properties as a :class:`Recording`, or an :class:`Unreadable` saying what is
    missing or not a uniformly sampled time series."""
    props = getattr(obj, "properties", None) or {}
    cls = obj.classname
    bad = lambda why: Unreadable(name, cls, why)  # noqa: E731
    data = props.get("dataSet")
    if not isinstance(data, np.ndarray) or data.dtype.kind not in "biuf" or data.size == 0:
        return bad("its dataSet is not a numeric array (an empty or unfinished object?)")
    data = np.asarray(data, float)
    if data.ndim == 1:
        data = data[:, None]
    if data.ndim == 2:
        data = data[:, :, None]
    if data.ndim != 3:
        return bad(f"its dataSet has {data.ndim} dimensions; a recording is samples x channels (x realizations)")
    incr = _number(props.get("domainIncr"))
    if incr is None or not incr > 0:
        return bad(f"its domainIncr ({incr}) is not a positive sampling increment")
    values = np.asarray(props.get("domainValues", np.nan), float).reshape(-1)
    if values.size > 1 or (values.size == 1 and np.isfinite(values[0])):
        return bad("it is sampled irregularly (domainValues set); resample it to a uniform rate (REKLAB's "
                   "resampleSeg or interp1) first")
    domain = " ".join(_strings(props.get("domainName"))).lower()
    if re.search(r"freq|lag|hz", domain):
        return bad(f"its domain is {domain!r}, not time: not a recording")
    channels = tuple(_strings(props.get("chanNames")))
    if len(channels) != data.shape[1]:
        channels = tuple(f"channel {i + 1}" for i in range(data.shape[1]))
    starts = np.asarray(props.get("domainStart", 0.0), float).reshape(-1)
    if starts.size == 0 or not np.all(np.isfinite(starts)):
        starts = np.zeros(1)
    segments: tuple[tuple[int, int], ...] = ((0, data.shape[0]),)
    if cls == "segdat":
        onsets = _parameter(props.get("parameterSet"), "onsetPointer")
        lengths = _parameter(props.get("parameterSet"), "segLength")
        if onsets is None or lengths is None or onsets.size != lengths.size or not onsets.size:
            return bad("its parameterSet has no onsetPointer and segLength of equal size")
        segments = tuple((int(o) - 1, int(n)) for o, n in zip(onsets, lengths))
        if any(o < 0 or n < 1 or o + n > data.shape[0] for o, n in segments):
            return bad(f"its segments (onsetPointer, segLength) do not lie in its {data.shape[0]} samples")
        if starts.size != len(segments):
            return bad(f"it has {len(segments)} segments but {starts.size} domainStart values")
    return Recording(name, cls, data, channels, float(incr), starts[:len(segments)], segments)


def _text(x) -> str:
    """A MATLAB char array (or bytes) as text."""
    a = np.asarray(x).reshape(-1)
    if a.size == 0:
        return ""
    v = a[0] if a.size == 1 else "".join(str(c) for c in a)
    return v.decode(errors="replace") if isinstance(v, bytes) else str(v)


def _strings(x) -> list[str]:
    """The texts of a char array or a cell array of char arrays (``chanNames``), in order."""
    if x is None:
        return []
    if isinstance(x, (str, bytes)):
        return [_text(x)]
    a = np.asarray(x)
    if a.dtype.kind in "US":
        single_chars = a.size > 1 and a.dtype.itemsize == (4 if a.dtype.kind == "U" else 1)
        return ["".join(_text(v) for v in a.reshape(-1))] if single_chars else [_text(v) for v in a.reshape(-1)]
    if a.dtype == object:
        return [s for v in a.reshape(-1, order="F") for s in _strings(v)]
    return []


def _number(x) -> float | None:
    try:
        a = np.asarray(x, float).reshape(-1)
    except (TypeError, ValueError):
        return None
    return float(a[0]) if a.size == 1 and np.isfinite(a[0]) else None


def _parameter(param_set, name: str) -> np.ndarray | None:
    """``paramValue`` of the ``param`` object called ``name`` in a REKLAB ``parameterSet`` (``paramDefault``
    when the value was never set)."""
    if param_set is None:
        return None
    items = list(np.asarray(param_set, object).reshape(-1)) if isinstance(param_set, np.ndarray) else [param_set]
    for p in items:
        props = getattr(p, "properties", None) or {}
        if " ".join(_strings(props.get("paramName"))) != name:
            continue
        for key in ("paramValue", "paramDefault"):
            try:
                v = np.asarray(props.get(key), float).reshape(-1)
            except (TypeError, ValueError):
                continue
            if v.size and np.all(np.isfinite(v)):
                return v
    return None
