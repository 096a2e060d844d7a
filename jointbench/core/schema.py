"""Strict parsing of mappings (YAML, ``--set key=value``) into typed, validated dataclasses.

An unknown key, a value of the wrong type or unit, or an impossible value raises
:class:`~jointbench.core.errors.ConfigError` naming where it came from, the key and what is allowed.

Numeric fields may declare a unit with :func:`param`. Such a field accepts a bare number (read in the
declared unit) or a string ``"<number> <unit>"`` in any unit of the same dimension, e.g. ``"5 kHz"``
for a field in Hz or ``"40 ms"`` for a field in s.
"""
from __future__ import annotations

import dataclasses
import functools
import inspect
import math
import numbers
import re
import types
import typing
from typing import Any, Literal, Mapping

from jointbench.core.errors import ConfigError

# normalised unit spelling -> (dimension, factor to the dimension's SI unit)
_UNITS: dict[str, tuple[str, float]] = {
    "hz": ("frequency", 1.0), "khz": ("frequency", 1e3),
    "s": ("time", 1.0), "ms": ("time", 1e-3),
    "rad": ("angle", 1.0), "mrad": ("angle", 1e-3), "deg": ("angle", math.pi / 180),
    "n.m": ("torque", 1.0), "nm": ("torque", 1.0),
    "n.m/rad": ("stiffness", 1.0), "nm/rad": ("stiffness", 1.0),
    "n.m.s/rad": ("damping", 1.0), "nms/rad": ("damping", 1.0),
    "kg.m2": ("inertia", 1.0), "n.m.s2/rad": ("inertia", 1.0), "g.m2": ("inertia", 1e-3),
    "db": ("decibel", 1.0),
    "1/s": ("rate", 1.0),
    "kg": ("mass", 1.0),
    "m": ("length", 1.0), "cm": ("length", 1e-2), "mm": ("length", 1e-3),
    "m/s2": ("acceleration", 1.0),
}


def _norm_unit(u: str) -> str:
    u = u.strip().lower().replace("·", ".").replace("*", ".").replace("²", "2").replace("^", "")
    return re.sub(r"\s+", ".", u)


def param(default: Any = dataclasses.MISSING, *, unit: str | None = None, gt: float | None = None,
          ge: float | None = None, lt: float | None = None, le: float | None = None,
          doc: str = "", default_factory: Any = dataclasses.MISSING, allow_inf: bool = False) -> Any:
    """A dataclass field with an optional unit and bounds, checked by :func:`parse`.

    Numbers must be finite unless ``allow_inf`` (e.g. an SNR of ``.inf`` meaning no noise): an infinite
    lag or segment length only overflows further on.
    """
    meta = {"unit": unit, "gt": gt, "ge": ge, "lt": lt, "le": le, "doc": doc, "allow_inf": allow_inf}
    if default_factory is not dataclasses.MISSING:
        return dataclasses.field(default_factory=default_factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def _fail(where: str, key: str, msg: str) -> ConfigError:
    return ConfigError(f"{where}: key '{key}': {msg}")


def _number(value: Any, unit: str | None, where: str, key: str, integer: bool,
            allow_inf: bool = False) -> float | int:
    kind = "a whole number" if integer else "a number"
    if isinstance(value, bool):
        raise _fail(where, key, f"expected {kind}, got {value!r}")
    if isinstance(value, str):
        m = re.fullmatch(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?inf)\s*(.*?)\s*", value)
        if not m:
            raise _fail(where, key, f"expected {kind}" + (f" in {unit}" if unit else "") + f", got {value!r}")
        num, u = float(m.group(1)), m.group(2)
        if u:
            if unit is None:
                raise _fail(where, key, f"takes a plain number without a unit, got {value!r}")
            got = _UNITS.get(_norm_unit(u))
            want = _UNITS[_norm_unit(unit)]
            if got is None or got[0] != want[0]:
                same = sorted(k for k, v in _UNITS.items() if v[0] == want[0])
                raise _fail(where, key, f"unit {u!r} is not a {want[0]} unit; allowed: {', '.join(same)}")
            num = num * got[1] / want[1]
        value = num
    if not isinstance(value, numbers.Real):      # numpy scalars too (a value computed by code, not read)
        raise _fail(where, key, f"expected {kind}" + (f" in {unit}" if unit else "") + f", got {value!r}")
    if isinstance(value, float) and math.isnan(value):
        raise _fail(where, key, "NaN is not allowed")
    if isinstance(value, float) and math.isinf(value) and not allow_inf:
        raise _fail(where, key, f"must be a finite number, got {value!r}")
    if integer:
        if float(value) != int(value):
            raise _fail(where, key, f"expected a whole number, got {value!r}")
        return int(value)
    return float(value)


def _convert(tp: Any, value: Any, meta: Mapping[str, Any], where: str, key: str) -> Any:
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if tp is Any:
        return value
    if dataclasses.is_dataclass(tp) and isinstance(value, tp):   # already built (and checked)
        return value
    if origin in (typing.Union, types.UnionType):
        if type(None) in args and (value is None or (isinstance(value, str) and
                                                       value.strip().lower() in ("none", "null", "off"))):
            return None
        inner = [a for a in args if a is not type(None)]
        errors = []
        for a in inner:
            try:
                return _convert(a, value, meta, where, key)
            except ConfigError as exc:
                errors.append(exc)
        raise errors[0] if len(errors) == 1 else _fail(where, key, f"{value!r} matches none of {inner}")
    if origin is Literal:
        if value not in args:
            raise _fail(where, key, f"{value!r} is not allowed; allowed: {', '.join(map(repr, args))}")
        return value
    if tp is float or tp is int:
        x = _number(value, meta.get("unit"), where, key, integer=tp is int, allow_inf=bool(meta.get("allow_inf")))
        for bound, op, text in (("gt", float.__gt__, ">"), ("ge", float.__ge__, ">="),
                                ("lt", float.__lt__, "<"), ("le", float.__le__, "<=")):
            b = meta.get(bound)
            if b is not None and not op(float(x), float(b)):
                u = f" {meta['unit']}" if meta.get("unit") else ""
                raise _fail(where, key, f"must be {text} {b}{u}, got {x}{u}")
        return x
    if tp is bool:
        if isinstance(value, bool):
            return value
        if isinstance(value, str) and value.lower() in ("true", "false", "yes", "no", "1", "0"):
            return value.lower() in ("true", "yes", "1")
        raise _fail(where, key, f"expected true or false, got {value!r}")
    if tp is str:
        if not isinstance(value, str):
            raise _fail(where, key, f"expected text, got {value!r}")
        return value
    if origin in (tuple, list):
        if isinstance(value, str):
            value = [v for v in re.split(r"[,\s]+", value.strip("[]() ")) if v]
        if not isinstance(value, (list, tuple)):
            value = [value]
        elem = args[0] if args else Any
        out = [_convert(elem, v, meta, where, f"{key}[{i}]") for i, v in enumerate(value)]
        return tuple(out) if origin is tuple else out
    if origin is dict or tp is dict:
        if not isinstance(value, Mapping):
            raise _fail(where, key, f"expected a mapping, got {value!r}")
        return dict(value)
    if dataclasses.is_dataclass(tp):
        return parse(tp, value, f"{where}: {key}")
    raise TypeError(f"schema cannot parse type {tp!r}")  # a programming error, not a user error


@functools.lru_cache(maxsize=None)
def _hints(cls: type) -> dict[str, Any]:
    """``typing.get_type_hints(cls)``, resolved once per class (it evaluates every annotation: a third of
    the time of a parse)."""
    return typing.get_type_hints(cls)


def parse(cls: type, data: Mapping[str, Any] | None, where: str) -> Any:
    """Build dataclass ``cls`` from ``data``, strictly.

    Parameters
    ----------
    cls : dataclass type
        Target type; fields made with :func:`param` carry units and bounds.
    data : mapping or None
        Values by field name; ``None`` means all defaults.
    where : str
        Where the values came from (file and section), prefixed to every error message.
    """
    data = {} if data is None else data
    if not isinstance(data, Mapping):
        raise ConfigError(f"{where}: expected a mapping of settings, got {data!r}")
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    unknown = sorted(set(data) - set(fields))
    if unknown:
        raise ConfigError(f"{where}: unknown key {unknown[0]!r}; allowed: {', '.join(fields)}")
    hints = _hints(cls)
    kwargs = {}
    for name, f in fields.items():
        if name in data:
            kwargs[name] = _convert(hints[name], data[name], f.metadata, where, name)
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise ConfigError(f"{where}: missing required key {name!r}")
    try:
        return cls(**kwargs)
    except (ValueError, TypeError) as exc:
        raise ConfigError(f"{where}: {exc}") from None


def checked(cls: type) -> type:
    """Make constructing dataclass ``cls`` check its arguments as :func:`parse` does (types, units, bounds).

    ``Settings(lag_before=-5.0)`` is then refused with the same message as ``make(name, {"lag_before":
    -5.0})``, and a value with a unit (``Settings(lag_before="40 ms")``) is converted. Only the arguments
    given are checked (the defaults are the class's own); the class's ``__post_init__`` runs after the
    check. Every estimator's ``Settings`` is checked this way (:class:`jointbench.estimators.Estimator`
    applies it to its subclasses): one mechanism for every settings class. Returns ``cls``.
    """
    if not dataclasses.is_dataclass(cls) or cls.__dict__.get("_schema_checked"):
        return cls
    init = cls.__init__
    signature = inspect.signature(init)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    where = cls.__qualname__

    @functools.wraps(init)
    def __init__(self, *args, **kwargs):
        given = signature.bind(self, *args, **kwargs).arguments
        hints = _hints(cls)
        values = {name: _convert(hints[name], v, fields[name].metadata, where, name) if name in fields else v
                  for name, v in list(given.items())[1:]}
        init(self, **values)

    cls.__init__ = __init__
    cls._schema_checked = True
    return cls


def _type_text(t: Any) -> str:
    """``float | None``, ``'a' | 'b'``, ``float | 'auto'``, ``tuple[float, ...]``: a type as a user reads it."""
    origin = typing.get_origin(t)
    if origin is Literal:
        return " | ".join(map(repr, typing.get_args(t)))
    if origin in (typing.Union, types.UnionType):
        return " | ".join(_type_text(a) for a in typing.get_args(t))
    if t is type(None):
        return "None"
    return getattr(t, "__name__", str(t)).replace("typing.", "") if origin is None else str(t).replace("typing.", "")


def describe(cls: type) -> list[tuple[str, str, str, str]]:
    """(name, type, default, doc) rows for help texts."""
    rows = []
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        default = "required" if f.default is dataclasses.MISSING else repr(f.default)
        unit = f.metadata.get("unit")
        tp = _type_text(hints[f.name])
        rows.append((f.name, tp + (f" [{unit}]" if unit else ""), default, f.metadata.get("doc", "")))
    return rows


def parse_assignments(items: list[str] | None, where: str) -> dict[str, str]:
    """Turn ``["a=1", "b=2 Hz"]`` into a mapping (values parsed later by :func:`parse`)."""
    out: dict[str, str] = {}
    for item in items or []:
        if "=" not in item:
            raise ConfigError(f"{where}: expected key=value, got {item!r}")
        k, v = item.split("=", 1)
        out[k.strip()] = v.strip()
    return out
