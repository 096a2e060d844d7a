"""The axes of a comparison grid, its tuning search and its ``only`` rules (:mod:`jointbench.benchmarks.compare.grid`).

* ``tuning`` (part, and per scenario over the part's): estimator -> setting -> the values searched. A case
  with ``tuning: tuned`` chooses among :func:`candidates` (the paper's settings first, then every
  combination of the values) on tuning realizations (:func:`jointbench.benchmarks.compare.protocol.select_setting`).
* ``only``: rules that run part of the grid (``[{when, keep, reason}]``, :class:`OnlyRule`): a combination that
  matches ``when`` and not ``keep`` is skipped with the ``reason`` (e.g. MuJoCo on a subset).

Both are parsed by :func:`jointbench.core.schema.parse` (a key or axis it does not know, a value of the wrong
type: every error of the part at once).
"""
from __future__ import annotations

import collections
import dataclasses
import itertools
import json
from typing import Any, Mapping

from jointbench import estimators
from jointbench.core.errors import ConfigError
from jointbench.core.schema import param


@dataclasses.dataclass(frozen=True, kw_only=True)
class AxisValues:
    """A value or a list of values per axis of a grid (the ``when`` and ``keep`` of an ``only`` rule); the
    fields are the axes, in the order they appear in case ids (:data:`AXES`)."""

    scenario: tuple[Any, ...] | None = None
    joint: tuple[Any, ...] | None = None
    variation: tuple[Any, ...] | None = None
    perturbation: tuple[Any, ...] | None = None
    noise: tuple[Any, ...] | None = None
    fs: tuple[Any, ...] | None = None
    backend: tuple[Any, ...] | None = None
    estimator: tuple[Any, ...] | None = None
    data: tuple[Any, ...] | None = None
    tuning: tuple[Any, ...] | None = None

    def given(self) -> dict[str, tuple]:
        """The axes given, axis -> values, in :data:`AXES` order."""
        return {a: getattr(self, a) for a in AXES if getattr(self, a) is not None}


#: the axes a grid may have, in the order they appear in case ids (re-exported by jointbench.benchmarks.compare.grid)
AXES = tuple(f.name for f in dataclasses.fields(AxisValues))


@dataclasses.dataclass(frozen=True)
class OnlyRule:
    """A combination matching every axis of ``when`` runs only if it matches every axis of ``keep`` (a value
    or a list each); the others are skipped with the ``reason``."""

    keep: AxisValues = param(doc="the combinations that run, among those matching 'when'")
    when: AxisValues = param(default_factory=AxisValues, doc="the combinations the rule applies to (default: all)")
    reason: str = param("excluded by the grid's 'only'", doc="why the others are skipped")

    def skips(self, combo: Mapping) -> bool:
        """Whether the rule skips combination ``combo`` (axis -> value)."""
        return matches(combo, self.when.given()) and not matches(combo, self.keep.given())


def grid_settings(part_estimators: Mapping[str, dict], est: str) -> dict:
    return dict(part_estimators.get(est) or {})


def check_known_estimators(names, where: str) -> None:
    """Every name is a registered estimator (built-in or plugin); a :class:`ConfigError` naming the first that
    is not, otherwise."""
    unknown = [e for e in names if e not in estimators.REGISTRY]
    if unknown:
        raise ConfigError(f"{where}: unknown estimator {unknown[0]!r}; known: {', '.join(estimators.REGISTRY.names())}")


def check_search(search: Mapping[str, Mapping[str, tuple]], where: str) -> None:
    """A tuning search (estimator -> setting -> the values tried, as parsed) names known estimators and tries
    at least one value of each setting; a :class:`ConfigError` otherwise."""
    check_known_estimators(search, where)
    for est, spec in search.items():
        empty = [k for k, v in spec.items() if not v]
        if empty:
            raise ConfigError(f"{where}.{est}.{empty[0]}: expected a value or a non-empty list of values")


def check_search_applies(search: Mapping[str, Mapping], axes: Mapping[str, tuple], where: str) -> None:
    """A tuning search that would have no effect is a :class:`ConfigError`: one for an estimator not on the
    grid's estimator axis, or any search when the tuning axis has no 'tuned' column."""
    idle = [e for e in search if e not in axes["estimator"]]
    if idle:
        raise ConfigError(f"{where}: {idle[0]!r} is not on the grid's estimator axis "
                          f"({', '.join(axes['estimator'])}); its search would have no effect: add it to "
                          f"grid.estimator or remove its search")
    if search and "tuned" not in axes.get("tuning", ()):
        raise ConfigError(f"{where}: a search, but the grid's tuning axis has no 'tuned' column "
                          f"({', '.join(axes.get('tuning', ())) or 'none'}); add grid.tuning: [paper, tuned] "
                          f"or remove the search")


def skip_summary(skipped: list[dict], most: int = 3) -> str:
    """Why the combinations of ``skipped`` are skipped, in one line: each distinct reason with its count,
    the commonest first (at most ``most``, then how many other reasons)."""
    counts = collections.Counter(s["reason"] for s in skipped)
    text = "; ".join(f"{n} x {reason}" for reason, n in counts.most_common(most))
    rest = len(counts) - most
    return (f"every one of the {len(skipped)} combinations is skipped: {text}"
            + (f"; and {rest} other reason{'s' if rest > 1 else ''}" if rest > 0 else ""))


def candidates(est: str, settings: Mapping, search: Mapping[str, list]) -> list[dict]:
    """The settings a tuned case chooses among: the paper's ``settings`` first, then every combination of
    the ``search`` values over them (each once); empty when there is nothing to search."""
    if not search:
        return []
    out = [dict(settings)]
    names = list(search)
    for values in itertools.product(*(search[n] for n in names)):
        out.append({**settings, **dict(zip(names, values))})
    seen, unique = set(), []
    for c in out:
        key = json.dumps(c, sort_keys=True, default=str)
        if key not in seen:
            seen.add(key)
            unique.append(c)
    return unique


def matches(combo: Mapping, cond: Mapping[str, tuple]) -> bool:
    """Whether ``combo`` (axis -> value) takes one of the values of every axis of ``cond`` (numbers equal as
    numbers, anything else as text)."""
    def eq(a, b):
        if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
            return float(a) == float(b)
        return str(a) == str(b)
    return all(any(eq(combo.get(a), v) for v in vals) for a, vals in cond.items())
