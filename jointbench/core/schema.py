"""Strict parsing of mappings (YAML, ``--set key=value``) into typed, validated dataclasses: the one config
parser of the project (study, part, grid, tuning, published values, nightly, experiment, estimator settings).

An unknown key, a missing key, a value of the wrong type or unit, or an impossible value raises
:class:`~jointbench.core.errors.ConfigError` naming where it came from, the key and what is allowed. Every
error of a mapping is reported at once, one per line (the fields of nested dataclasses, the entries of
lists and mappings included): one error is one line, as before; several are several lines in one
:class:`~jointbench.core.errors.ConfigError` (:class:`Problems`).

Numeric fields may declare a unit with :func:`param`. Such a field accepts a bare number (read in the
declared unit) or a string ``"<number> <unit>"`` in any unit of the same dimension, e.g. ``"5 kHz"``
for a field in Hz or ``"40 ms"`` for a field in s. A field whose value is read by its own rules (a tagged
choice among registered classes, a list of seeds, ...) names a ``parser`` (:func:`param`, :func:`tagged`).
"""
from __future__ import annotations

import collections.abc
import contextlib
import dataclasses
import difflib
import functools
import inspect
import math
import numbers
import re
import types
import typing
from typing import Any, Callable, Iterator, Literal, Mapping

from jointbench.core.errors import ConfigError

# normalised unit spelling -> (dimension, factor to the dimension's SI unit)
_UNITS: dict[str, tuple[str, float]] = {
    "hz": ("frequency", 1.0), "khz": ("frequency", 1e3),
    "s": ("time", 1.0), "ms": ("time", 1e-3), "min": ("time", 60.0), "h": ("time", 3600.0),
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


@dataclasses.dataclass(frozen=True)
class Tune:
    """The declaration that a setting is its estimator's smoothing setting (the one that trades following a
    fast change of K(t) against noise), with the candidates a comparison's ``tuned`` column tries by default.

    The candidates are the setting as configured (a study's paper setting: always the first) and
    ``factors`` times it, for a setting whose configured value is a number (else, e.g. ``auto``, times the
    field's default); an integer setting is rounded half up; every candidate is kept within the field's
    bounds. ``factors`` scale with the value a study gives each scenario (a forgetting rate set to 40 / the
    period of the stiffness's variation), so every method gets the same relative search, whatever the
    time scale of the scenario. A study's ``tuning:`` entry for the estimator replaces its declaration
    (:func:`jointbench.benchmarks.compare.tuning.search_for`).

    Examples
    --------
    ``window: float = param(1.0, unit="s", gt=0, tune=Tune(factors=(0.5, 2.0)))``: a tuned case tries the
    configured window, half and twice it.
    """

    factors: tuple[float, ...] = (0.5, 2.0)

    def __post_init__(self):
        f = tuple(float(x) for x in self.factors)
        if not f or not all(math.isfinite(x) and x > 0 for x in f):
            raise ValueError(f"Tune: factors must be finite numbers > 0, at least one, got {self.factors!r}")
        object.__setattr__(self, "factors", f)

    def text(self) -> str:
        """``x0.5, x2`` (for help texts)."""
        return ", ".join(f"x{f:g}" for f in self.factors)


def param(default: Any = dataclasses.MISSING, *, unit: str | None = None, gt: float | None = None,
          ge: float | None = None, lt: float | None = None, le: float | None = None,
          doc: str = "", default_factory: Any = dataclasses.MISSING, allow_inf: bool = False,
          parser: Callable[[Any, str, str], Any] | None = None, tune: Tune | None = None) -> Any:
    """A dataclass field with an optional unit and bounds, checked by :func:`parse`.

    Numbers must be finite unless ``allow_inf`` (e.g. an SNR of ``.inf`` meaning no noise): an infinite
    lag or segment length only overflows further on. ``parser(value, where, key)`` reads a value by rules
    of its own instead of the field's type (raising :class:`ConfigError`, e.g. made by :func:`error`).
    ``tune`` declares the estimator's smoothing setting and its default tuning candidates (:class:`Tune`;
    :func:`tuned_fields` reads them).
    """
    if tune is not None and not isinstance(tune, Tune):
        raise TypeError(f"param(tune=...): expected a jointbench.core.schema.Tune, got {tune!r}")
    meta = {"unit": unit, "gt": gt, "ge": ge, "lt": lt, "le": le, "doc": doc, "allow_inf": allow_inf,
            "parser": parser, "tune": tune}
    if default_factory is not dataclasses.MISSING:
        return dataclasses.field(default_factory=default_factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def error(where: str, key: str, msg: str) -> ConfigError:
    """The error of key ``key`` read from ``where``: ``"<where>: key '<key>': <msg>"``."""
    return ConfigError(f"{where}: key '{key}': {msg}")


class Problems:
    """The errors found while reading one file, raised together by :meth:`raise_all`.

    ``with problems.catch(): ...`` records a :class:`ConfigError` raised inside and goes on. One error is
    raised as it is (its message and type unchanged, e.g. :class:`~jointbench.core.errors.Incompatible`);
    several become one :class:`ConfigError` listing them one per line, in the order found.
    """

    def __init__(self) -> None:
        self.errors: list[ConfigError] = []

    def add(self, exc: ConfigError) -> None:
        self.errors.append(exc)

    @contextlib.contextmanager
    def catch(self) -> Iterator[None]:
        try:
            yield
        except ConfigError as exc:
            self.errors.append(exc)

    def raise_all(self) -> None:
        if len(self.errors) == 1:
            raise self.errors[0]
        if self.errors:
            lines = dict.fromkeys(line for exc in self.errors for line in str(exc).splitlines())
            raise ConfigError("\n".join(lines))


def number(value: Any, unit: str | None, where: str, key: str, integer: bool = False,
           allow_inf: bool = False) -> float | int:
    """A number read from ``value``: a number, or a string ``"<number> [<unit>]"`` converted to ``unit``
    (errors name ``where`` and ``key``)."""
    kind = "a whole number" if integer else "a number"
    if isinstance(value, bool):
        raise error(where, key, f"expected {kind}, got {value!r}")
    if isinstance(value, str):
        m = re.fullmatch(r"\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?inf)\s*(.*?)\s*", value)
        if not m:
            raise error(where, key, f"expected {kind}" + (f" in {unit}" if unit else "") + f", got {value!r}")
        num, u = float(m.group(1)), m.group(2)
        if u:
            if unit is None:
                raise error(where, key, f"takes a plain number without a unit, got {value!r}")
            got = _UNITS.get(_norm_unit(u))
            want = _UNITS[_norm_unit(unit)]
            if got is None or got[0] != want[0]:
                same = sorted(k for k, v in _UNITS.items() if v[0] == want[0])
                raise error(where, key, f"unit {u!r} is not a {want[0]} unit; allowed: {', '.join(same)}")
            num = num * got[1] / want[1]
        value = num
    if not isinstance(value, numbers.Real):      # numpy scalars too (a value computed by code, not read)
        raise error(where, key, f"expected {kind}" + (f" in {unit}" if unit else "") + f", got {value!r}")
    if isinstance(value, float) and math.isnan(value):
        raise error(where, key, "NaN is not allowed")
    if isinstance(value, float) and math.isinf(value) and not allow_inf:
        raise error(where, key, f"must be a finite number, got {value!r}")
    if integer:
        if float(value) != int(value):
            raise error(where, key, f"expected a whole number, got {value!r}")
        return int(value)
    return float(value)


def boolean(value: Any, where: str, key: str) -> bool:
    """A yes/no value: ``True``/``False``, or the text ``true``/``yes``/``1`` or ``false``/``no``/``0`` (any
    case, e.g. from ``--set``); the one reading of a flag in the project."""
    if isinstance(value, bool):
        return value
    if isinstance(value, str) and value.strip().lower() in ("true", "false", "yes", "no", "1", "0"):
        return value.strip().lower() in ("true", "yes", "1")
    raise error(where, key, f"expected true or false, got {value!r}")


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
        raise errors[0] if len(errors) == 1 else error(where, key, f"{value!r} matches none of {inner}")
    if origin is Literal:
        if value not in args:
            raise error(where, key, f"{value!r} not allowed; allowed: {', '.join(map(str, args))}")
        return value
    if tp is float or tp is int:
        x = number(value, meta.get("unit"), where, key, integer=tp is int, allow_inf=bool(meta.get("allow_inf")))
        for bound, op, text in (("gt", float.__gt__, ">"), ("ge", float.__ge__, ">="),
                                ("lt", float.__lt__, "<"), ("le", float.__le__, "<=")):
            b = meta.get(bound)
            if b is not None and not op(float(x), float(b)):
                u = f" {meta['unit']}" if meta.get("unit") else ""
                raise error(where, key, f"must be {text} {b}{u}, got {x}{u}")
        return x
    if tp is bool:
        return boolean(value, where, key)
    if tp is str:
        if not isinstance(value, str):
            raise error(where, key, f"expected text, got {value!r}")
        return value
    if origin in (tuple, list):
        return _sequence(origin, args, value, meta, where, key)
    if origin in (dict, collections.abc.Mapping) or tp is dict:
        if not isinstance(value, Mapping):
            raise error(where, key, f"expected a mapping, got {value!r}")
        if not args:
            return dict(value)
        problems, out = Problems(), {}
        for k, v in value.items():
            with problems.catch():
                out[_convert(args[0], k, {}, where, f"{key}.{k}")] = _convert(args[1], v, meta, where, f"{key}.{k}")
        problems.raise_all()
        return out
    if dataclasses.is_dataclass(tp):
        return parse(tp, value, f"{where}: {key}")
    raise TypeError(f"schema cannot parse type {tp!r}")  # a programming error, not a user error


def _sequence(origin: Any, args: tuple, value: Any, meta: Mapping[str, Any], where: str, key: str) -> Any:
    """A list or tuple of ``args[0]`` (every entry checked, every error kept); ``tuple[a, b]`` has that
    length. A string is a comma- or space-separated list of numbers (``--set lags=1,2``); any other single
    value is a list of one."""
    numeric = bool(args) and all(a in (int, float) for a in args if a is not Ellipsis)
    if isinstance(value, str) and numeric:
        value = [v for v in re.split(r"[,\s]+", value.strip("[]() ")) if v]
    if not isinstance(value, (list, tuple)):
        value = [value]
    fixed = origin is tuple and len(args) > 1 and args[1] is not Ellipsis
    if fixed and len(value) != len(args):
        raise error(where, key, f"expected {len(args)} values, got {len(value)}: {list(value)!r}")
    problems, out = Problems(), []
    for i, v in enumerate(value):
        with problems.catch():
            out.append(_convert(args[i] if fixed else (args[0] if args else Any), v, meta, where, f"{key}[{i}]"))
    problems.raise_all()
    return tuple(out) if origin is tuple else out


def _field(tp: Any, value: Any, meta: Mapping[str, Any], where: str, key: str) -> Any:
    """The value of one field: read by the field's ``parser`` when it has one, else by its type."""
    parser = meta.get("parser")
    return parser(value, where, key) if parser is not None else _convert(tp, value, meta, where, key)


@functools.lru_cache(maxsize=None)
def _hints(cls: type) -> dict[str, Any]:
    """``typing.get_type_hints(cls)``, resolved once per class (it evaluates every annotation: a third of
    the time of a parse)."""
    return typing.get_type_hints(cls)


def parse(cls: type, data: Mapping[str, Any] | None, where: str, document: bool = False) -> Any:
    """Build dataclass ``cls`` from ``data``, strictly.

    Parameters
    ----------
    cls : dataclass type
        Target type; fields made with :func:`param` carry units and bounds.
    data : mapping or None
        Values by field name; ``None`` means all defaults (but an empty file when ``document``).
    where : str
        Where the values came from (file and section), prefixed to every error message.
    document : bool
        ``data`` is a whole file (``None``: the file is empty, an error).

    Raises
    ------
    ConfigError
        Every unknown key, missing key and bad value of ``data`` and of the mappings nested in it, one per
        line (one error: its message alone; a misspelt required key is one error, the unknown key, saying
        which it resembles); then an error of ``cls``'s own checks (``__post_init__``).
    """
    if data is None and document:
        raise ConfigError(f"{where}: the file is empty; expected a mapping of settings")
    data = {} if data is None else data
    if not isinstance(data, Mapping):
        raise ConfigError(f"{where}: expected a mapping of settings, got {data!r}")
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
    missing = [name for name, f in fields.items() if name not in data and f.default is dataclasses.MISSING
               and f.default_factory is dataclasses.MISSING]
    problems, meant = Problems(), {}
    for key in sorted((k for k in data if k not in fields), key=str):
        close = difflib.get_close_matches(str(key), [m for m in missing if m not in meant.values()], 1, 0.75)
        hint = f" (a misspelt {close[0]!r}, which is missing?)" if close else ""
        meant.update({key: close[0]} if close else {})
        problems.add(ConfigError(f"{where}: unknown key {key!r}; allowed: {', '.join(fields)}{hint}"))
    hints = _hints(cls)
    kwargs = {}
    for name, f in fields.items():
        if name in data:
            with problems.catch():
                kwargs[name] = _field(hints[name], data[name], f.metadata, where, name)
        elif name in missing and name not in meant.values():
            problems.add(ConfigError(f"{where}: missing required key {name!r}"))
    problems.raise_all()
    try:
        return cls(**kwargs)
    except (ValueError, TypeError) as exc:            # a check of the spec's own (__post_init__): each line
        raise ConfigError("\n".join(f"{where}: {line}" for line in str(exc).splitlines())) from None


def parse_tagged(data: Any, tag: str, choices: Any, what: str, where: str, default: str | None = None) -> Any:
    """Parse ``{tag: name, **settings}``: ``name`` picks a class of ``choices`` whose settings dataclass
    parses the rest (:func:`parse`).

    ``choices`` is a registry (``names()``, ``get(name)``, e.g. :data:`jointbench.sims.JOINTS`) or a mapping
    name -> class. The class is its own settings dataclass, or has a ``Settings`` attribute, in which case
    the result is ``cls(settings)``. ``default``: the name when the tag is left out (``None`` data too).
    """
    known = list(choices.names()) if hasattr(choices, "names") else list(choices)
    if data is None and default is not None:
        data = {}
    if not isinstance(data, Mapping):
        raise ConfigError(f"{where}: expected a mapping with key '{tag}' (one of: {', '.join(known)}), "
                          f"got {data!r}")
    name = data.get(tag, default)
    if name is None:
        raise ConfigError(f"{where}: missing key '{tag}'; known {what}s: {', '.join(known)}")
    if not isinstance(name, str) or name not in known:
        raise ConfigError(f"{where}: key '{tag}': unknown {what} {name!r}; known: {', '.join(known)}")
    cls = choices.get(name)
    settings_cls = getattr(cls, "Settings", cls)
    settings = parse(settings_cls, {k: v for k, v in data.items() if k != tag}, where)
    return settings if settings_cls is cls else cls(settings)


def tagged(tag: str, choices: Any, what: str, default: str | None = None) -> Callable[[Any, str, str], Any]:
    """The ``parser`` (:func:`param`) of a field holding ``{tag: name, **settings}`` (:func:`parse_tagged`);
    its errors are placed under ``<where>: <key>``."""
    def parser(value: Any, where: str, key: str) -> Any:
        return parse_tagged(value, tag, choices, what, f"{where}: {key}", default)
    return parser


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
        values = {name: _field(hints[name], v, fields[name].metadata, where, name) if name in fields else v
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
    """(name, type, default, doc) rows for help texts; a smoothing setting's doc ends with its declared
    tuning candidates (:class:`Tune`)."""
    rows = []
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        default = "required" if f.default is dataclasses.MISSING else repr(f.default)
        unit = f.metadata.get("unit")
        tp = _type_text(hints[f.name])
        doc = f.metadata.get("doc", "")
        tune = f.metadata.get("tune")
        if tune is not None:
            doc += f" [smoothing setting: tuned over {tune.text()} the configured value]"
        rows.append((f.name, tp + (f" [{unit}]" if unit else ""), default, doc))
    return rows


def tuned_fields(cls: type) -> dict[str, tuple[dataclasses.Field, Tune]]:
    """The fields of settings dataclass ``cls`` declared as smoothing settings (``param(tune=...)``):
    name -> (field, :class:`Tune`), in field order."""
    if not dataclasses.is_dataclass(cls):
        return {}
    return {f.name: (f, f.metadata["tune"]) for f in dataclasses.fields(cls)
            if f.metadata.get("tune") is not None}


def parse_assignments(items: list[str] | None, where: str) -> dict[str, str]:
    """Turn ``["a=1", "b=2 Hz"]`` into a mapping (values parsed later by :func:`parse`)."""
    out: dict[str, str] = {}
    for item in items or []:
        if "=" not in item:
            raise ConfigError(f"{where}: expected key=value, got {item!r}")
        k, v = item.split("=", 1)
        out[k.strip()] = v.strip()
    return out
