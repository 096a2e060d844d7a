"""The tuning search and the ``only`` rules of a comparison grid (:mod:`jointbench.benchmarks.compare.grid`).

* ``tuning`` (part, and per scenario over the part's): estimator -> setting -> the values searched. A case
  with ``tuning: tuned`` chooses among :func:`candidates` (the paper's settings first, then every
  combination of the values) on tuning realizations (:func:`jointbench.benchmarks.compare.protocol.select_setting`).
* ``only``: rules that run part of the grid (``[{when, keep, reason}]``, :func:`_only`): a combination that
  matches ``when`` and not ``keep`` is skipped with the ``reason`` (e.g. MuJoCo on a subset).
"""
from __future__ import annotations

import itertools
import json
from typing import Any, Mapping

from jointbench import estimators
from jointbench.core.errors import ConfigError

#: the axes a grid may have, in the order they appear in case ids (re-exported by jointbench.benchmarks.compare.grid)
AXES = ("scenario", "joint", "variation", "perturbation", "noise", "fs", "backend", "estimator", "data", "tuning")


def grid_settings(part_estimators: Mapping[str, dict], est: str) -> dict:
    return dict(part_estimators.get(est) or {})


def _search(value: Any, where: str) -> dict[str, dict[str, list]]:
    """A tuning search: estimator -> setting -> the values tried (non-empty lists)."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ConfigError(f"{where}: expected a mapping estimator -> setting -> list of values")
    out = {}
    for est, spec in value.items():
        if est not in estimators.REGISTRY:
            raise ConfigError(f"{where}: unknown estimator {est!r}; known: {', '.join(estimators.REGISTRY.names())}")
        if not isinstance(spec, Mapping) or not all(isinstance(v, list) and v for v in spec.values()):
            raise ConfigError(f"{where}.{est}: expected a mapping setting -> non-empty list of values, got {spec!r}")
        out[str(est)] = {str(k): list(v) for k, v in spec.items()}
    return out


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


def _only(value: Any, axes: Mapping[str, tuple], where: str) -> tuple:
    """Rules that run part of the grid: ``[{when: {axis: values}, keep: {axis: values}, reason: text}]``; a
    combination matching every axis of ``when`` runs only if it matches every axis of ``keep`` (a value or
    a list); the others are skipped with the ``reason``."""
    if value is None:
        return ()
    if not isinstance(value, list):
        raise ConfigError(f"{where}: key 'only': expected a list of {{when, keep, reason}}")
    rules = []
    for i, rule in enumerate(value):
        w = f"{where}: only[{i}]"
        if not isinstance(rule, Mapping) or set(rule) - {"when", "keep", "reason"} or "keep" not in rule:
            raise ConfigError(f"{w}: expected {{when: {{axis: values}}, keep: {{axis: values}}, reason: text}}")
        parsed = {}
        for key in ("when", "keep"):
            m = rule.get(key) or {}
            if not isinstance(m, Mapping):
                raise ConfigError(f"{w}.{key}: expected a mapping axis -> value or list of values")
            for axis in m:
                if axis not in AXES:
                    raise ConfigError(f"{w}.{key}: unknown axis {axis!r}; axes: {', '.join(AXES)}")
            parsed[key] = {a: tuple(v if isinstance(v, list) else [v]) for a, v in m.items()}
        rules.append((parsed["when"], parsed["keep"], str(rule.get("reason") or "excluded by the grid's 'only'")))
    return tuple(rules)


def _matches(combo: Mapping, cond: Mapping[str, tuple]) -> bool:
    def eq(a, b):
        if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
            return float(a) == float(b)
        return str(a) == str(b)
    return all(any(eq(combo.get(a), v) for v in vals) for a, vals in cond.items())
