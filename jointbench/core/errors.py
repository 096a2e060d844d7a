"""Exceptions that carry a message meant for a person, not a traceback.

The CLI and the runner catch :class:`JointBenchError` and print its message; anything else is a bug.
"""
from __future__ import annotations

import contextlib
import contextvars
from typing import Iterator, Mapping


class JointBenchError(Exception):
    """Base class for errors caused by the user's input, config or data."""


class ConfigError(JointBenchError, ValueError):
    """A configuration value is unknown, mistyped, in the wrong unit or impossible."""


class InputError(JointBenchError, ValueError):
    """A data record cannot be used (NaN, non-uniform time, mismatched lengths, too short...)."""


class Refused(InputError):
    """An estimate was computed but is not returned as a result: it cannot be trusted (the output gate of
    :func:`jointbench.fitting.pipeline.fit`). Its prediction of the record it was fitted on is worse than a
    constant (VAF < 0), a parameter or a bound is not finite, or an interval has zero or non-finite width.

    Attributes
    ----------
    reason : str
        A short code: ``"negative_vaf"``, ``"non_finite"``, ``"degenerate_interval"``, ``"invalid_estimate"``.
    diagnostics : dict
        The numbers behind the refusal (e.g. ``{"vaf": [-303.4], "record": ["trial1"]}``), for a notebook.

    The message is one line naming the cause and the setting to change; the CLI prints it and exits 2, the
    harness records the case as ``refused`` with it.
    """

    def __init__(self, message: str, *, reason: str, diagnostics: Mapping | None = None):
        super().__init__(message)
        self.reason = reason
        self.diagnostics = dict(diagnostics or {})


class OutputError(JointBenchError, OSError):
    """A result or output file cannot be written (read-only folder, full disk, a path outside the
    results folder...)."""


class Incompatible(ConfigError):
    """Two valid settings that cannot go together (a rate that does not divide the simulation rate, a joint
    with a hand contact on an apparatus without a handle, a backend that cannot simulate the experiment).
    A comparison grid skips such a combination, with the reason; any other config error stops the run."""


# ------------------------------------------------------------------------------------------------ wording
# A message about an argument names it as the caller knows it: the Python API's keyword (``decimate=4``) by
# default, the command line's flag (``--decimate 4``) inside :func:`worded_as` (``jointbench estimate``). The
# code that raises says which argument it means (:func:`argument`); it never receives the caller's wording.
_FLAGS: contextvars.ContextVar[Mapping[str, str] | None] = contextvars.ContextVar("jointbench_flags", default=None)
_NO_VALUE = object()


def argument(name: str, value=_NO_VALUE) -> str:
    """Argument ``name`` (with ``value`` when given) as a message names it: ``decimate`` / ``decimate=4``
    in Python, ``--decimate`` / ``--decimate 4`` on the command line (:func:`worded_as`). A ``window`` value
    ``(start, end)`` in seconds reads ``window=(5.000, 45.000)`` or ``--window 5.000s:45.000s``."""
    flag = (_FLAGS.get() or {}).get(name)
    if value is _NO_VALUE:
        return flag or name
    if name == "window":
        a, b = value
        return f"{flag} {a:.3f}s:{b:.3f}s" if flag else f"window=({a:.3f}, {b:.3f})"
    return f"{flag} {value}" if flag else f"{name}={value!r}"


@contextlib.contextmanager
def worded_as(flags: Mapping[str, str]) -> Iterator[None]:
    """Within this block, messages name the arguments of ``flags`` (Python keyword -> command-line flag) by
    their flags: how the command line words the errors of the API it calls."""
    token = _FLAGS.set(dict(flags))
    try:
        yield
    finally:
        _FLAGS.reset(token)
