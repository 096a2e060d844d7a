"""Reading a config file: strict YAML (a key given twice is an error) within limits checked before it is
parsed, every refusal one line naming the file (issue 20).

- a regular UTF-8 file (a UTF-8 byte-order mark is accepted; latin-1 and UTF-16 are refused with the place
  of the first bad byte) of at most :data:`MAX_CONFIG_BYTES`;
- collections nested at most :data:`MAX_YAML_DEPTH` deep (PyYAML's composer recurses once per level) and at
  most :data:`MAX_YAML_NODES` values once every alias is expanded (an alias bomb is a few lines), both
  checked on PyYAML's events, before anything is built;
- YAML syntax errors on one line (line, column, what).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from jointbench.core.errors import ConfigError


class _DuplicateKey(yaml.YAMLError):
    def __init__(self, key: Any, line: int, first: int):
        super().__init__(f"line {line}: duplicate key {key!r} (first given on line {first})")


class _Strict:
    """Rejects a key given twice in one mapping (PyYAML keeps the last one silently). Keys brought in by a
    merge (``<<: *anchor``) may be overridden: that is what merges are for."""

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            seen: dict = {}
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=True)
                line = key_node.start_mark.line + 1
                try:
                    if key in seen:
                        raise _DuplicateKey(key, line, seen[key])
                    seen[key] = line
                except TypeError:         # an unhashable key: PyYAML reports it itself
                    continue
        return super().construct_mapping(node, deep=deep)


class StrictLoader(_Strict, yaml.SafeLoader):
    """``yaml.SafeLoader`` (pure Python) that rejects a key given twice in one mapping: the reference reader,
    whose verdict and messages a config gets."""


#: the same on libyaml's C parser when PyYAML has it (its wheels do): parsing the shipped study configs with
#: the pure-Python parser took most of a second per process. A document it refuses is read again by
#: :class:`StrictLoader`, so a refusal (or an acceptance libyaml would not give) is the pure-Python one.
FastStrictLoader = type("FastStrictLoader", (_Strict, yaml.CSafeLoader), {}) if getattr(yaml, "CSafeLoader", None) \
    else StrictLoader


#: limits of a config file, checked before it is parsed: its size (the largest shipped config is under
#: 100 kB), how deeply its collections nest (the shipped ones nest 8 deep; PyYAML's composer recurses
#: once per level and ends in RecursionError near 1000) and how many values it holds once every alias is
#: expanded (a few thousand in the shipped ones; anchors of anchors grow as the power of the fan-out)
MAX_CONFIG_BYTES = 10_000_000
MAX_YAML_DEPTH = 100
MAX_YAML_NODES = 500_000


def _yaml_error(exc: yaml.YAMLError) -> str:
    """A PyYAML error on one line: what and where (PyYAML prints a snippet with a caret below it)."""
    mark = getattr(exc, "problem_mark", None)
    what = " ".join(str(x) for x in (getattr(exc, "context", None), getattr(exc, "problem", None)) if x)
    if mark is None or not what:
        return " ".join(str(exc).split())
    return f"line {mark.line + 1}, column {mark.column + 1}: {what}"


def _check_size(text: str, path: Path, loader=StrictLoader) -> None:
    """Refuse, from PyYAML's events (no recursion, nothing built), a document nested deeper than
    :data:`MAX_YAML_DEPTH` or holding more than :data:`MAX_YAML_NODES` values with its aliases expanded
    (an 'alias bomb': a few lines of anchors of anchors that expand to billions of values)."""
    sizes: dict[str, int] = {}
    stack: list[list] = []              # [anchor, expanded size] of each open collection
    total = 0
    for ev in yaml.parse(text, Loader=loader):
        if isinstance(ev, (yaml.ScalarEvent, yaml.AliasEvent, yaml.CollectionStartEvent)):
            n = sizes.get(ev.anchor, 1) if isinstance(ev, yaml.AliasEvent) else 1
            total += n
            if isinstance(ev, yaml.CollectionStartEvent):
                stack.append([ev.anchor, 1])
                if len(stack) > MAX_YAML_DEPTH:
                    raise ConfigError(f"{path}: line {ev.start_mark.line + 1}: collections nested more than "
                                      f"{MAX_YAML_DEPTH} deep; a study config needs far fewer levels")
            else:
                if isinstance(ev, yaml.ScalarEvent) and ev.anchor:
                    sizes[ev.anchor] = 1
                if stack:
                    stack[-1][1] += n
            if total > MAX_YAML_NODES:
                raise ConfigError(f"{path}: line {ev.start_mark.line + 1}: the document expands to more than "
                                  f"{MAX_YAML_NODES} values (aliases of anchors that hold aliases: an alias bomb?); "
                                  f"a study config holds a few thousand")
        elif isinstance(ev, yaml.CollectionEndEvent) and stack:
            anchor, n = stack.pop()
            if anchor:
                sizes[anchor] = n
            if stack:
                stack[-1][1] += n


def load_yaml(path: Path) -> Any:
    """Parse a YAML file strictly: duplicate keys are errors naming the file, key and line; the file must
    be a regular UTF-8 file within the limits above (every refusal is one line naming the file)."""
    from jointbench.core.files import decode_text, file_problem

    problem = file_problem(path, MAX_CONFIG_BYTES)
    if problem is not None:
        raise ConfigError(f"{path}: {problem}" + ("" if "allowed" not in problem else " for a config file"))
    try:
        text = decode_text(path.read_bytes(), str(path), ConfigError)
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read ({exc.strerror or exc})") from None
    try:
        try:
            _check_size(text, path, FastStrictLoader)
            return yaml.load(text, Loader=FastStrictLoader)  # noqa: S506 - a SafeLoader subclass
        except (yaml.YAMLError, RecursionError) as exc:
            if isinstance(exc, _DuplicateKey) or FastStrictLoader is StrictLoader:
                raise
        _check_size(text, path)                              # the pure-Python reader's verdict and message
        return yaml.load(text, Loader=StrictLoader)  # noqa: S506 - a SafeLoader subclass
    except _DuplicateKey as exc:
        raise ConfigError(f"{path}: {exc}") from None
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML: {_yaml_error(exc)}") from None
    except RecursionError:           # a nesting the event check let through (it should not)
        raise ConfigError(f"{path}: not valid YAML: nested too deeply") from None
