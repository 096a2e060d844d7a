"""The arguments of the Python API, checked where they enter: one rule per kind of argument.

:mod:`jointbench.api` checks every argument of every public function with these rules before anything else
runs, and the command line's argument types (:mod:`jointbench.cli.common`) apply the same rules to the text
they parsed: the command line parses, the rule decides, once. A wrong argument is one
:class:`~jointbench.core.errors.ConfigError` line naming it as the caller knows it
(:func:`~jointbench.core.errors.argument`: ``fs`` in Python, ``--fs`` on the command line) and what it takes,
never a traceback from deep inside.

What is accepted: whole numbers as Python or numpy integers (not ``True``, not ``2.0``); a rate as a number
in Hz or a text with a unit (``"100 Hz"``, ``"2 kHz"``, read by the settings' unit parser,
:func:`jointbench.core.schema.number`); a list of names as a list or tuple of texts, or one text (one name).
"""
from __future__ import annotations

import math
import numbers
import os
from pathlib import Path
from typing import Any, Mapping

from jointbench.core.errors import ConfigError, argument

#: the largest whole number an argument may be (a run id, a limit): SQLite's and numpy's 64-bit integers
MAX_WHOLE = 2**63 - 1


def _fail(name: str, what: str, value: Any) -> ConfigError:
    shown = repr(value) if len(repr(value)) <= 60 else f"{type(value).__name__} {repr(value)[:50]}..."
    return ConfigError(f"{argument(name)}: expected {what}, got {shown}")


def whole(value: Any, name: str, *, minimum: int = 0, maximum: int = MAX_WHOLE) -> int:
    """``value`` as an ``int`` in ``[minimum, maximum]`` (a Python or numpy integer, not a bool)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or int(value) < minimum:
        raise _fail(name, f"a whole number >= {minimum}", value)
    if int(value) > maximum:
        raise _fail(name, f"a whole number from {minimum} to {'2**63 - 1' if maximum == MAX_WHOLE else maximum}",
                    value)
    return int(value)


def optional_whole(value: Any, name: str, *, minimum: int = 0, maximum: int = MAX_WHOLE) -> int | None:
    """:func:`whole`, or ``None``."""
    return None if value is None else whole(value, name, minimum=minimum, maximum=maximum)


#: how a message names a quantity > 0 of a unit
_POSITIVE = {"min": "minutes > 0", "Hz": "a rate > 0 Hz"}


def positive(value: Any, name: str, unit: str) -> float:
    """``value`` as a finite ``float`` > 0 (a number, or a text with a unit of ``unit``'s kind: ``"2 h"``)."""
    from jointbench.core.schema import number

    what = _POSITIVE.get(unit, f"a finite number > 0 {unit}")
    if isinstance(value, bool) or not isinstance(value, (numbers.Real, str)):
        raise _fail(name, what, value)
    try:
        x = number(value, unit, "", name)
    except ConfigError:
        raise _fail(name, what, value) from None
    if not (math.isfinite(x) and x > 0):
        raise _fail(name, what, value)
    return float(x)


def rate(value: Any, name: str = "fs") -> float | None:
    """A sampling rate in Hz (:func:`positive`: ``100``, ``"100 Hz"``, ``"1 kHz"``), or ``None``."""
    return None if value is None else positive(value, name, "Hz")


def text(value: Any, name: str, *, optional: bool = False) -> str | None:
    """``value`` when it is a non-empty text (or ``None`` when ``optional``)."""
    if value is None and optional:
        return None
    if not isinstance(value, str) or not value.strip():
        raise _fail(name, "a non-empty text" + (" or None" if optional else ""), value)
    return value


def choice(value: Any, name: str, options: tuple[str, ...]) -> str:
    """``value`` when it is one of the texts ``options``."""
    if not isinstance(value, str) or value not in options:
        raise _fail(name, "one of " + ", ".join(repr(o) for o in options), value)
    return value


def texts(value: Any, name: str) -> tuple[str, ...]:
    """A list or tuple of non-empty texts (one text: one item), as a tuple; ``None``: empty."""
    if value is None:
        return ()
    if isinstance(value, str):
        value = (value,)
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) and v.strip() for v in value):
        raise _fail(name, "a list of non-empty texts", value)
    return tuple(value)


def flag(value: Any, name: str, *, optional: bool = False) -> bool | None:
    """``value`` when it is ``True`` or ``False`` (or ``None`` when ``optional``)."""
    if value is None and optional:
        return None
    if not isinstance(value, bool):
        raise _fail(name, "True or False" + (" or None" if optional else ""), value)
    return value


def mapping(value: Any, name: str, example: str) -> Mapping | None:
    """``value`` when it is a mapping (or ``None``); a text such as ``"lag_before=40ms"`` is refused with the
    mapping it should be (``example``)."""
    if value is None or isinstance(value, Mapping):
        return value
    raise _fail(name, f"a mapping such as {example}", value)


def path(value: Any, name: str, *, optional: bool = False) -> Path | None:
    """``value`` as a :class:`~pathlib.Path` (a text or a path-like object; ``None`` when ``optional``)."""
    if value is None and optional:
        return None
    if isinstance(value, os.PathLike) or (isinstance(value, str) and value.strip()):
        return Path(value)
    raise _fail(name, "a path (text or pathlib.Path)" + (" or None" if optional else ""), value)


def paths(value: Any, name: str) -> list[Path]:
    """One path or a non-empty list of paths (:func:`path`)."""
    if isinstance(value, (list, tuple)) and value:
        return [path(v, name) for v in value]
    return [path(value, name)]
