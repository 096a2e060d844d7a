"""Dotted-path overrides of a study config (``jointbench run STUDY --set part.key=value``).

An override ``table1.seeds=3`` or ``matrix.grid.noise=[0.1]`` replaces one value of a part's YAML before
the strict parse, so any key a part has (seeds, sweeps, parameters, estimator settings, the experiment,
grid axes) can be changed from the command line without editing files, and the strict parse then judges
the result exactly as it judges the file. The value is read as YAML (``3``, ``[0.1, 0.2]``, ``.inf``,
``20 Hz``, ``{shape: square}``). ``*`` as the part name applies the override to every part.

Nothing in the loaded YAML is changed in place: the path to the replaced value is copied first, so a
value shared by several parts through a YAML anchor (``*elbow``) changes only in the part named.
"""
from __future__ import annotations

import dataclasses
from typing import Any, Callable, Mapping, Sequence

import yaml

from jointbench.core.errors import ConfigError


@dataclasses.dataclass(frozen=True)
class Override:
    """One ``PART.KEY[.KEY...]=VALUE`` of the command line."""

    text: str
    part: str
    keys: tuple[str, ...]
    value: Any


def parse_override(text: str) -> Override:
    """Split ``PART.KEY.SUB=VALUE`` and read the value as YAML; a one-line error otherwise."""
    if "=" not in text:
        raise ConfigError(f"--set {text}: expected PART.KEY=VALUE (e.g. table1.seeds=3)")
    path, raw = text.split("=", 1)
    keys = tuple(k.strip() for k in path.strip().split("."))
    if len(keys) < 2 or not all(keys):
        raise ConfigError(f"--set {text}: name the part and the key, PART.KEY=VALUE (e.g. table1.seeds=3, "
                          f"'*.seeds=2' for every part)")
    try:
        value = yaml.safe_load(raw) if raw.strip() else None
    except yaml.YAMLError as exc:
        raise ConfigError(f"--set {text}: the value is not valid YAML: {str(exc).splitlines()[0]}") from None
    return Override(text, keys[0], keys[1:], value)


def for_parts(overrides: Sequence[str | Override], parts: Sequence[str], where: str) -> dict[str, list[Override]]:
    """The overrides of each part (``*`` names every part); an unknown part is a one-line error."""
    out: dict[str, list[Override]] = {p: [] for p in parts}
    for o in overrides:
        o = o if isinstance(o, Override) else parse_override(o)
        if o.part == "*":
            for p in parts:
                out[p].append(o)
        elif o.part in out:
            out[o.part].append(o)
        else:
            raise ConfigError(f"--set {o.text}: {where} has no part {o.part!r}; parts: {', '.join(parts)}")
    return out


def apply(data: Mapping, overrides: Sequence[Override], where: str,
          expand: Callable[[tuple[str, ...], Any], Any] | None = None) -> dict:
    """``data`` (one part's mapping) with the overrides applied, copied along each path (never in place).

    ``expand(path, value)`` may turn a value met on the way into a mapping before descending into it (the
    study loader resolves a joint model given by name, so that ``experiment.joint.K.mean`` can be set).
    """
    out = dict(data)
    for o in overrides:
        node = out
        for depth, key in enumerate(o.keys[:-1]):
            here = ".".join((o.part, *o.keys[:depth + 1]))
            child = node.get(key) if isinstance(node, Mapping) else None
            if expand is not None and child is not None:
                child = expand(o.keys[:depth + 1], child)
            if child is None:
                child = {}
            if not isinstance(child, Mapping):
                raise ConfigError(f"--set {o.text}: {where}: '{here}' is {child!r}, not a mapping, so it has no "
                                  f"key {o.keys[depth + 1]!r}")
            child = dict(child)
            node[key] = child
            node = child
        node[o.keys[-1]] = o.value
    return out


def describe(overrides: Sequence[Override]) -> str:
    """`` (--set a=1, --set b=2)`` for the place names of error messages ('' without overrides)."""
    return "" if not overrides else " (with " + ", ".join(f"--set {o.text}" for o in overrides) + ")"
