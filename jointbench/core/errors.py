"""Exceptions that carry a message meant for a person, not a traceback.

The CLI and the runner catch :class:`JointBenchError` and print its message; anything else is a bug.
"""


class JointBenchError(Exception):
    """Base class for errors caused by the user's input, config or data."""


class ConfigError(JointBenchError, ValueError):
    """A configuration value is unknown, mistyped, in the wrong unit or impossible."""


class InputError(JointBenchError, ValueError):
    """A data record cannot be used (NaN, non-uniform time, mismatched lengths, too short...)."""


class OutputError(JointBenchError, OSError):
    """A result or output file cannot be written (read-only folder, full disk, a path outside the
    results folder...)."""


class Incompatible(ConfigError):
    """Two valid settings that cannot go together (a rate that does not divide the simulation rate, a joint
    with a hand contact on an apparatus without a handle, a backend that cannot simulate the experiment).
    A comparison grid skips such a combination, with the reason; any other config error stops the run."""
