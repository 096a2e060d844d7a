"""The axes of a comparison grid, its tuning search and its ``only`` rules (:mod:`jointbench.benchmarks.compare.grid`).

* The tuning search of an estimator (:func:`search_for`): what its settings declare (its smoothing setting,
  ``param(..., tune=Tune(...))``, :func:`declared_search`: the configured value and multiples of it), unless
  the study's ``tuning`` (part, and per scenario over the part's: estimator -> setting -> the values
  searched) names the estimator, which replaces the declaration. A case with ``tuning: tuned`` chooses
  among :func:`candidates` (the paper's settings first, then every combination of the values) on tuning
  realizations (:func:`jointbench.benchmarks.compare.protocol.select_setting`); a choice at the lowest or
  highest value tried of a setting is an edge choice (:func:`jointbench.benchmarks.compare.protocol.edge_of`,
  reported by :func:`edge_sentence`): there the candidates, not the method, decided.
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
import math
import numbers
import operator
from typing import Any, Mapping

from jointbench import estimators
from jointbench.core.errors import ConfigError
from jointbench.core.schema import param, tuned_fields


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


def _is_number(v: Any) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool) and math.isfinite(v)


_BOUNDS = (("gt", operator.gt), ("ge", operator.ge), ("lt", operator.lt), ("le", operator.le))


def _multiple(value: float, factor: float, field, integer: bool) -> float | int | None:
    """``factor`` times ``value``: an integer rounded half up and raised to the field's lower bound, a number
    that breaks an upper or open bound left out (None)."""
    x = value * factor
    meta = field.metadata
    if integer:
        x = int(math.floor(x + 0.5))
        if meta.get("ge") is not None:
            x = max(x, int(math.ceil(meta["ge"])))
        if meta.get("gt") is not None:
            x = max(x, int(math.floor(meta["gt"])) + 1)
    return x if all(meta.get(b) is None or op(x, meta[b]) for b, op in _BOUNDS) else None


def declared_search(est: str, settings: Mapping) -> dict[str, tuple]:
    """The tuning search estimator ``est`` declares around its ``settings`` (the case's paper settings, as
    configured): for each smoothing setting (``param(..., tune=Tune(factors))``,
    :class:`jointbench.core.schema.Tune`), ``factors`` times the configured value, or times the field's
    default when the configured value is not a number (``auto``); an integer rounded half up and raised to
    its lower bound; a multiple that breaks a bound or equals the configured value left out. Values carry
    the field's unit (``"10 1/s"``). Empty when the estimator declares no smoothing setting.

    References
    ----------
    The declared settings and their papers: FSEWLS's forgetting rate (Xu & Hollerbach 1998, eq. 6), KBR's
    kernel width (van de Ruit et al. 2018, eq. 15), skirt's order of the time variation (eq. 14), the SDS
    window, the number of basis functions of Guarin's method and of the time-varying parallel cascade, the
    window of the ensemble spectral estimator (each setting's ``doc`` in its estimator's module).
    """
    cls = estimators.REGISTRY.get(est)
    fields = tuned_fields(getattr(cls, "Settings", None))
    if not fields:
        return {}
    parsed = estimators.make(est, settings, f"tuning of {est}").settings
    out = {}
    for name, (field, tune) in fields.items():
        configured = getattr(parsed, name)
        centre = configured if _is_number(configured) else field.default
        if not _is_number(centre):
            continue
        integer = isinstance(centre, int)
        unit = field.metadata.get("unit")
        values = []
        for f in tune.factors if centre is configured else (1.0, *tune.factors):
            x = _multiple(centre, f, field, integer)
            if x is None or x == configured or x in values:
                continue
            values.append(x)
        if values:
            out[name] = tuple(x if integer or not unit else f"{x:.12g} {unit}" for x in values)
    return out


def search_for(est: str, settings: Mapping, part_search: Mapping[str, Mapping],
               scenario_search: Mapping[str, Mapping]) -> dict[str, tuple]:
    """The tuning search of estimator ``est`` in a scenario: the study's (``part_search``, with
    ``scenario_search`` over it setting by setting) when either names ``est`` (an empty mapping: nothing
    to tune), else what the estimator declares around its ``settings`` (:func:`declared_search`). Every
    method, built-in or plugin, is thus tuned by one policy without a study edit, and a study can still
    choose its own candidates."""
    if est in part_search or est in scenario_search:
        return {**(part_search.get(est) or {}), **(scenario_search.get(est) or {})}
    return declared_search(est, settings)


def nothing_to_tune(est: str, part_search: Mapping[str, Mapping], scenario_search: Mapping[str, Mapping]) -> str:
    """The reason a tuned case of ``est`` is skipped when :func:`search_for` gives no candidate."""
    if est in part_search or est in scenario_search:
        why = f"the study's tuning gives {est} no values to try"
    else:
        why = f"{est} declares no smoothing setting (param tune=) and the study's tuning does not name it"
    return f"nothing to tune: {why} (its tuned column is its paper column)"


def edge_sentence(rows) -> str:
    """The report's sentence on edge choices, from labelled tidy rows (columns ``method``, ``case_id``,
    ``tuning``, ``tuning_edge``): how many tuned cases chose a candidate on an edge, per method and
    setting (the label of :func:`jointbench.benchmarks.compare.protocol.edge_of`); '' when no row is of a
    tuned case with a ``tuning_edge`` label."""
    from jointbench.benchmarks.compare.protocol import INSIDE

    if "tuning_edge" not in rows.columns:
        return ""
    cases = rows[(rows["tuning"] == "tuned") & rows["tuning_edge"].notna() & (rows["tuning_edge"] != "")]
    cases = cases.drop_duplicates("case_id")
    if cases.empty:
        return ""
    at_edge = cases[cases["tuning_edge"] != INSIDE]
    if at_edge.empty:
        return (f"Tuning: in every one of the {len(cases)} tuned cases the chosen candidate lies inside the "
                "values tried of each setting (none at the lowest or highest).")
    per = []
    for method, g in cases.groupby("method", sort=True):
        e = g[g["tuning_edge"] != INSIDE]
        if len(e):
            which = collections.Counter(part for text in e["tuning_edge"] for part in text.split("; "))
            per.append(f"{method} {len(e)} of {len(g)} ("
                       + ", ".join(f"{w} in {n}" for w, n in sorted(which.items())) + ")")
    return (f"**Edge choices: in {len(at_edge)} of the {len(cases)} tuned cases the chosen candidate is the lowest "
            f"or highest value tried of a setting**: {'; '.join(per)}. There the candidates, not the method, "
            "bounded the result (a value beyond them may predict better): the column 'edge' of the tuning table "
            "and the rows' `tuning_edge` say which; widen the search (the study's `tuning:` entry, or the factors "
            "of the estimator's declared `tune=`) to see the method's own optimum.")


def matches(combo: Mapping, cond: Mapping[str, tuple]) -> bool:
    """Whether ``combo`` (axis -> value) takes one of the values of every axis of ``cond`` (numbers equal as
    numbers, anything else as text)."""
    def eq(a, b):
        if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
            return float(a) == float(b)
        return str(a) == str(b)
    return all(any(eq(combo.get(a), v) for v in vals) for a, vals in cond.items())
