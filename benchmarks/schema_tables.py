"""A spec (a dataclass read by :func:`jointbench.core.schema.parse`) as a Markdown table of its keys: type, unit,
default, allowed values and meaning, from the fields and their :func:`~jointbench.core.schema.param` metadata (the
meaning falls back on the class's numpydoc ``Parameters``); and the keys a reference documents, read back from
its text. The reference of a study's files (:mod:`benchmarks.study_reference`) is made of these tables.

Each table follows a comment naming its spec (``<!-- schema: module.Class -->``), so that a reference can be
checked against the parser (:func:`documented`).
"""
from __future__ import annotations

import collections.abc
import dataclasses
import inspect
import math
import re
import types
import typing
from typing import Any, Callable, Literal

from jointbench.core import schema
from jointbench.core.errors import ConfigError


@dataclasses.dataclass
class Section:
    """One table of keys: a spec (dataclass) under a heading, with a paragraph before it."""

    title: str
    cls: type
    intro: str = ""
    level: int = 3
    #: key -> {'type': ..., 'allowed': ..., 'link': ...}: what the spec's types cannot say (a registry's names,
    #: the spec a custom parser reads the value with)
    notes: dict = dataclasses.field(default_factory=dict)

    @property
    def anchor(self) -> str:
        return anchor_of(self.cls)


def qualified(cls: type) -> str:
    return f"{cls.__module__}.{cls.__qualname__}"


def anchor_of(cls: type) -> str:
    return "spec-" + re.sub(r"[^a-z0-9]+", "-", qualified(cls).removeprefix("jointbench.").lower()).strip("-")


# ---------------------------------------------------------------------------------------------- cells
def value_text(v: Any) -> str:
    """A value as YAML writes it (``none``, ``true``, ``[a, b]``, ``.inf``)."""
    if v is None:
        return "none"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        if math.isinf(v):
            return ".inf" if v > 0 else "-.inf"
        return f"{v:g}"
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(value_text(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k}: {value_text(x)}" for k, x in v.items()) + "}"
    if isinstance(v, str):
        return v if v else '""'
    return str(v)


def _args(tp: Any) -> tuple:
    return typing.get_args(tp)


def _is_union(tp: Any) -> bool:
    return typing.get_origin(tp) in (typing.Union, types.UnionType)


def nested_specs(tp: Any) -> list[type]:
    """The dataclasses a field of type ``tp`` holds (itself, in an optional, a list or a mapping's values)."""
    if dataclasses.is_dataclass(tp) and isinstance(tp, type):
        return [tp]
    out = []
    for a in _args(tp):
        if a is not Ellipsis and a is not type(None):
            out += nested_specs(a)
    return out


def type_text(tp: Any, nested: bool = False) -> str:
    """A field's type as a study author reads it (``nested``: inside another type, a union in brackets)."""
    if tp is Any:
        return "see meaning"
    if tp is tuple or tp is list:
        return "list"
    if tp is float:
        return "number"
    if tp is int:
        return "whole number"
    if tp is str:
        return "text"
    if tp is bool:
        return "true or false"
    if dataclasses.is_dataclass(tp) and isinstance(tp, type):
        return f"mapping ([{tp.__name__.lstrip('_')}](#{anchor_of(tp)}))"
    origin = typing.get_origin(tp)
    if origin is Literal:
        return "one of the words"
    if _is_union(tp):
        inner = [a for a in _args(tp) if a is not type(None)]
        text = " or ".join(type_text(a, True) for a in inner) + (", or none" if len(inner) < len(_args(tp)) else "")
        return f"({text})" if nested else text
    if origin in (tuple, list):
        args = _args(tp)
        if origin is tuple and len(args) > 1 and args[1] is not Ellipsis:
            return "[" + ", ".join(type_text(a, True) for a in args) + "]"
        return f"list of {type_text(args[0], True)}" if args else "list"
    if origin in (dict, collections.abc.Mapping) or tp is dict:
        args = _args(tp)
        return f"mapping name -> {type_text(args[1], True)}" if args else "mapping"
    return getattr(tp, "__name__", str(tp))


def _literal_values(tp: Any) -> list:
    if typing.get_origin(tp) is Literal:
        return list(_args(tp))
    if _is_union(tp):
        return [v for a in _args(tp) for v in _literal_values(a)]
    return []


def _bounds_text(meta: typing.Mapping, unit: str) -> str:
    u = f" {unit}" if unit else ""
    parts = [f"{op} {meta[k]:g}{u}" for k, op in (("gt", ">"), ("ge", ">="), ("lt", "<"), ("le", "<="))
             if meta.get(k) is not None]
    return ", ".join(parts)


def tagged_choices(parser: Callable | None) -> tuple[str, list[str]] | None:
    """``(tag, names)`` of a field read by :func:`jointbench.core.schema.tagged` (``{kind: name, ...}``)."""
    if parser is None or getattr(parser, "__qualname__", "") != "tagged.<locals>.parser":
        return None
    free = inspect.getclosurevars(parser).nonlocals
    choices = free["choices"]
    names = list(choices.names()) if hasattr(choices, "names") else list(choices)
    return free["tag"], names


def _clean(text: str) -> str:
    """Docstring markup as plain Markdown: ``x`` -> `x`, :func:`a.b` -> `a.b`."""
    text = re.sub(r":\w+:`~?([^`]+)`", r"`\1`", text)
    return text.replace("``", "`")


def allowed_text(f: dataclasses.Field, tp: Any) -> str:
    """What values a field takes beyond its type: its words, bounds, infinity, the names a tag picks."""
    meta = f.metadata
    parts = []
    words = _literal_values(tp)
    if words:
        parts.append(", ".join(f"`{value_text(w)}`" for w in words))
    bounds = _bounds_text(meta, meta.get("unit") or "")
    if bounds:
        parts.append(bounds)
    if meta.get("allow_inf"):
        parts.append("`.inf` allowed")
    tag = tagged_choices(meta.get("parser"))
    if tag is not None:
        parts.append(f"`{tag[0]}`: " + ", ".join(f"`{n}`" for n in tag[1]))
    return "; ".join(parts)


def default_text(f: dataclasses.Field) -> str:
    if f.default is not dataclasses.MISSING:
        return value_text(f.default)
    if f.default_factory is not dataclasses.MISSING:
        factory = f.default_factory
        if dataclasses.is_dataclass(factory):
            return f"its defaults ([{factory.__name__}](#{anchor_of(factory)}))"
        return value_text(factory())
    return "**required**"


def numpydoc_parameters(cls: type) -> dict[str, str]:
    """``name -> description`` from the numpydoc ``Parameters`` sections of ``cls`` and its bases (``a, b : float``
    describes both); a subclass's description wins."""
    out: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        doc = inspect.cleandoc(klass.__dict__.get("__doc__") or "")
        m = re.search(r"^Parameters\n-+\n(.*?)(?=\n\n\S[^\n]*\n-+\n|\Z)", doc, re.S | re.M)
        if not m:
            continue
        # an entry: 'name[, name] : type' at the margin, then its indented description
        for names, text in re.findall(r"^(\w[\w, ]*?) :[^\n]*\n((?:[ \t]+\S[^\n]*\n?)*)", m.group(1), re.M):
            for name in names.split(","):
                out[name.strip()] = " ".join(text.split())
    return out


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def key_rows(section: Section) -> list[str]:
    """The table of a section: one row per key the spec's parser accepts."""
    cls = section.cls
    hints = typing.get_type_hints(cls)
    fallback = numpydoc_parameters(cls)
    fields = [f for f in dataclasses.fields(cls) if f.init]
    if not fields:
        return ["No keys of its own."]
    rows = ["| key | type | unit | default | allowed | meaning |", "|---|---|---|---|---|---|"]
    for f in fields:
        tp = hints[f.name]
        note = section.notes.get(f.name, {})
        meaning = _clean(f.metadata.get("doc") or fallback.get(f.name, "") or note.get("meaning", ""))
        allowed = "; ".join(x for x in (allowed_text(f, tp), note.get("allowed", "")) if x)
        tag = tagged_choices(f.metadata.get("parser"))
        kind = note.get("type") or (f"mapping `{{{tag[0]}: NAME, ...}}`" if tag else type_text(tp))
        link = note.get("link", "")
        if link and "](#" not in kind:
            kind += f" ({link})"
        rows.append("| " + " | ".join(_cell(x) for x in (f"`{f.name}`", kind, f.metadata.get("unit") or "",
                                                           default_text(f), allowed, meaning)) + " |")
    return rows


def render_section(section: Section) -> list[str]:
    out = [f"<a id=\"{section.anchor}\"></a>", "", "#" * section.level + " " + section.title, "",
           f"<!-- schema: {qualified(section.cls)} -->"]
    if section.intro:
        out += ["", _clean(section.intro)]
    return out + [""] + key_rows(section) + [""]


def first_paragraph(obj: Any) -> str:
    """The first paragraph of ``obj``'s docstring, on one line."""
    doc = inspect.getdoc(obj) or ""
    return " ".join(doc.split("\n\n")[0].split())


def with_nested(secs: list[Section], known: set[type]) -> list[Section]:
    """``secs`` with a section after each for every spec its fields hold (by type) that has none yet, e.g. a
    scenario's ``stiffness``; ``known`` (the specs with a section) is updated."""
    out = []
    for sec in secs:
        out.append(sec)
        hints = typing.get_type_hints(sec.cls)
        for f in dataclasses.fields(sec.cls):
            for spec in nested_specs(hints[f.name]):
                if spec not in known:
                    known.add(spec)
                    nested = Section(f"`{f.name}`", spec, level=sec.level, intro=first_paragraph(spec))
                    out += with_nested([nested], known)
    return out


def unit_dimension(unit: str) -> tuple[str, list[str]]:
    """``(dimension, its units)`` of a declared unit (``Hz`` -> ``('frequency', ['hz', 'khz'])``), as the parser
    itself says them when it refuses a unit (:func:`jointbench.core.schema.number`)."""
    try:
        schema.number("1 ?", unit, "", "")
    except ConfigError as exc:
        m = re.search(r"is not an? (\w+) unit; allowed: (.*)$", str(exc))
        if m:
            return m.group(1), m.group(2).split(", ")
    raise ValueError(f"unit {unit!r}: the parser did not name its dimension")


def units_table(sections: list[Section]) -> list[str]:
    """The units a number of ``sections`` may be written in, by dimension."""
    declared = {f.metadata.get("unit") for s in sections for f in dataclasses.fields(s.cls)} - {None}
    dims = dict(sorted(unit_dimension(u) for u in declared))
    return (["| dimension | units |", "|---|---|"]
            + [f"| {d} | {', '.join(f'`{u}`' for u in us)} |" for d, us in dims.items()])


def documented(text: str) -> dict[str, list[str]]:
    """``spec -> keys`` of a reference's text: the keys of the table after each ``<!-- schema: ... -->``."""
    out: dict[str, list[str]] = {}
    spec = None
    for line in text.splitlines():
        m = re.match(r"<!-- schema: ([\w.]+) -->", line)
        if m:
            spec = m.group(1)
            out.setdefault(spec, [])
            continue
        m = re.match(r"\| `([^`]+)` \|", line)
        if spec and m:
            out[spec].append(m.group(1))
        elif spec and line.startswith("#"):
            spec = None
    return out
