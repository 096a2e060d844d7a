"""Study configs: YAML -> typed, validated objects.

A study config (``benchmarks/studies/<id>.yaml``) names its parts (one per figure or table of the
paper), and for each part the protocol that computes it, its parameters, the simulated experiment
(joint model, apparatus, perturbation, sensors, noise, sampling), the estimators with their settings,
the seeds and any parameter sweep. Published values with tolerances and their source live in
``published.yaml`` beside ``study.yaml`` (a comparison study may have none). Joint models may be given inline or
by the name of a file in ``configs/models/``. Every error names the file, the key and what is allowed.

The shipped configs are package data (``jointbench.configs``, the checkout's ``configs/`` folder): a
study runs the same from an installed wheel as from the checkout. A study file of one's own (``jointbench
run path/to/my_study.yaml``) finds what it names (``joint: my_model``, ``published: my_values.yaml``,
``plugins``) beside it first, then in the package (:func:`search_roots`).
"""
from __future__ import annotations

import dataclasses
import itertools
import math
import re
from pathlib import Path
from typing import Any, Mapping, Sequence

from jointbench.benchmarks import overrides as _overrides
from jointbench.benchmarks.locate import (find_file, find_model, load_plugins, model_dirs, search_roots,
                                          study_path)
# the one YAML reader of configs: strict and within limits (benchmarks/config_yaml.py)
from jointbench.benchmarks.config_yaml import MAX_YAML_DEPTH, StrictLoader, load_yaml as _load_yaml  # noqa: F401
from jointbench.core.errors import ConfigError




def _check_keys(data: Mapping, allowed: dict[str, bool], where: str) -> None:
    """``allowed`` maps key -> required."""
    if not isinstance(data, Mapping):
        raise ConfigError(f"{where}: expected a mapping, got {type(data).__name__}")
    unknown = sorted(set(data) - set(allowed))
    if unknown:
        raise ConfigError(f"{where}: unknown key {unknown[0]!r}; allowed: {', '.join(allowed)}")
    missing = [k for k, req in allowed.items() if req and k not in data]
    if missing:
        raise ConfigError(f"{where}: missing required key {missing[0]!r}")


@dataclasses.dataclass(frozen=True)
class Reading:
    """One chosen reading of an ambiguous passage (rendered in the report's Interpretation)."""

    id: str
    topic: str
    passage: str
    reading: str
    alternatives: str = ""


@dataclasses.dataclass(frozen=True)
class Check:
    """One published value with its tolerance and how to compute it from the tidy rows.

    ``evidence`` says what a pass means (:data:`EVIDENCE`): ``reproduction`` (an independent published
    value or claim, judged), ``conditional`` (passes only under ``reading``, a reading chosen by its
    outcome), ``calibrated`` (``free_parameter`` was chosen to match it: shown, never counted as a
    pass) or ``sanity`` (arithmetic or self-consistency). ``tolerance_reason`` states why the band is
    what it is. ``domain`` restricts the scored rows (e.g. ``{f_v: {lt: 1.0}}``, the paper's domain;
    ``domain_reason`` says why); the rows outside it are shown, not scored.
    """

    id: str
    part: str
    description: str
    source: str
    published: Any
    low: float
    high: float
    select: Mapping[str, Any]
    aggregate: str = "median"
    if_missed: str = ""
    kind: str = "value"
    over: str = ""
    direction: str = "decreasing"
    slack: float = 0.0
    versus: Mapping[str, Any] | None = None
    by: str = ""
    evidence: str = "reproduction"
    reading: str = ""
    free_parameter: str = ""
    tolerance_reason: str = ""
    domain: Mapping[str, Any] | None = None
    domain_reason: str = ""
    count: str = "headline"        # COUNTS: 'method_difference' = a difference of cells counted already
    target: str = ""               # the published table or figure it belongs to (the Fidelity table)
    cause: str = ""                # one-line cause of a miss, shared by the misses it explains

    @property
    def readings(self) -> tuple[str, ...]:
        """The reading ids named by ``reading`` (``"R1, R2"`` -> ``("R1", "R2")``)."""
        return tuple(r.strip() for r in self.reading.split(",") if r.strip())


@dataclasses.dataclass(frozen=True)
class NotReproduced:
    """A published table, figure or value the study does not reproduce, and why."""

    item: str
    reason: str


@dataclasses.dataclass(frozen=True)
class MethodSwap:
    """Swap test of a study comparing two methods: with their reproduced values exchanged, how many
    method-specific checks still pass (a check that survives the swap does not tell the methods apart)."""

    part: str
    estimators: tuple[str, str]


@dataclasses.dataclass(frozen=True)
class Part:
    """One figure or table of a paper."""

    name: str
    protocol: str
    description: str
    params: Mapping[str, Any]
    experiment: Mapping[str, Any] | None
    estimators: Mapping[str, Mapping[str, Any]]
    seeds: tuple[int, ...]
    sweep: Mapping[str, tuple[Any, ...]]
    where: str
    report_section: str = "results"
    backend: str = "analytic"
    figure: str = ""               # its figure maker (benchmarks.figures); '' = the one named like the protocol
    grid: Any = None               # a comparison grid (benchmarks.compare.grid.Grid): cases come from its axes

    def grid_combinations(self) -> list[dict[str, Any]]:
        """Every combination of the sweep (one empty dict without a sweep)."""
        keys = list(self.sweep)
        return [dict(zip(keys, combo)) for combo in itertools.product(*(self.sweep[k] for k in keys))]


@dataclasses.dataclass(frozen=True)
class Study:
    id: str
    title: str
    paper: str
    path: Path
    parts: Mapping[str, Part]
    readings: tuple[Reading, ...]
    checks: tuple[Check, ...]
    not_reproduced: tuple[NotReproduced, ...] = ()
    method_swap: MethodSwap | None = None
    plugins: tuple[str, ...] = ()      # outside modules with estimators (jointbench.core.plugins), imported
    expected_failures: bool = False   # cases are expected to fail: `jointbench run` exits 0 all the same


_PART_KEYS = {"protocol": True, "description": True, "params": False, "experiment": False,
              "estimators": False, "seeds": False, "sweep": False, "report_section": False, "backend": False,
              "figure": False, "grid": False, "scenarios": False, "variations": False, "perturbations": False,
              "budget": False, "tuning": False, "only": False}
#: keys only a part with a comparison grid takes (benchmarks/compare/grid.py)
GRID_KEYS = ("scenarios", "variations", "perturbations", "budget", "tuning", "only")
REPORT_SECTIONS = ("results", "interpretation")
_STUDY_KEYS = {"study": True, "title": True, "paper": True, "published": False, "readings": False,
               "not_reproduced": True, "method_swap": False, "parts": True, "plugins": False,
               # true: the study expects some cases to fail (a study of where methods break down); without it
               # a run in which any case failed exits non-zero (the exit status tells a scheduler the truth)
               "expected_failures": False}
_CHECK_KEYS = {"id": True, "part": True, "description": True, "source": True, "published": True,
               "low": False, "high": False, "select": True, "aggregate": False, "if_missed": False,
               "kind": False, "over": False, "direction": False, "slack": False, "versus": False, "by": False,
               "evidence": True, "reading": False, "free_parameter": False, "tolerance_reason": True,
               "domain": False, "domain_reason": False, "count": False, "target": False, "cause": False}
#: how a check counts: ``headline`` (one published value or claim: the headline when its evidence is
#: reproduction) or ``method_difference`` (a difference of two published cells that are checked one by one
#: already, e.g. KBR - skirt of Table I: its own line beside the headline, never in it)
COUNTS = ("headline", "method_difference")
AGGREGATES = ("median", "mean", "min", "max", "std")
#: kinds of evidence, in the order the report shows them; the headline counts ``reproduction`` only
EVIDENCE = ("reproduction", "conditional", "calibrated", "sanity")
#: range conditions allowed in ``select``, ``versus`` and ``domain`` (``{f_v: {lt: 1.0}}``)
RANGE_OPS = ("lt", "le", "gt", "ge")
#: check kind -> keys it needs (besides the common ones) and keys it allows
CHECK_KINDS = {
    "value": ({"low", "high"}, {"low", "high", "aggregate"}),
    "trend": ({"over"}, {"over", "direction", "slack", "aggregate"}),
    "difference": ({"versus"}, {"versus", "by", "low", "high", "aggregate"}),
}


def _resolve_joint(experiment: Mapping, where: str, models_dir: Path | Sequence[Path]) -> dict:
    exp = dict(experiment)
    joint = exp.get("joint")
    if isinstance(joint, str):
        exp["joint"] = _load_yaml(find_model(joint, [models_dir] if isinstance(models_dir, Path) else models_dir,
                                             where))
    return exp


def resolve_joint(name: str, study_path: Path | None = None, where: str = "joint") -> dict:
    """The joint model named ``name`` (a file ``<name>.yaml`` beside the study, in its ``models/`` folder or
    in the package's ``configs/models``), as its mapping."""
    return _resolve_joint({"joint": name}, where, model_dirs(search_roots(study_path)))["joint"]


#: most seeds one part may run (a typo such as ``seeds: 1000000000`` must not exhaust the memory)
MAX_SEEDS = 100_000


def _seeds(value: Any, where: str) -> tuple[int, ...]:
    if value is None:
        return (0,)
    if isinstance(value, int) and not isinstance(value, bool):
        if value < 1:
            raise ConfigError(f"{where}: key 'seeds': need at least 1 seed, got {value}")
        if value > MAX_SEEDS:
            raise ConfigError(f"{where}: key 'seeds': {value} seeds is more than the {MAX_SEEDS} a part may run")
        return tuple(range(value))
    if isinstance(value, list) and len(value) > MAX_SEEDS:
        raise ConfigError(f"{where}: key 'seeds': {len(value)} seeds is more than the {MAX_SEEDS} a part may run")
    if isinstance(value, list) and value and all(isinstance(v, int) and not isinstance(v, bool)
                                                 for v in value):
        if len(set(value)) != len(value):
            raise ConfigError(f"{where}: key 'seeds': repeated seed in {value}")
        return tuple(value)
    raise ConfigError(f"{where}: key 'seeds': expected a count (e.g. 7) or a list of whole numbers, "
                      f"got {value!r}")


def check_backend(name: Any, where: str) -> str:
    """A simulation backend name of :data:`sims.BACKENDS` (``analytic``, ``mujoco``, ...), or a one-line
    error naming ``where`` (the part, or the command line)."""
    from jointbench.sims import BACKENDS

    if not isinstance(name, str) or name not in BACKENDS:
        raise ConfigError(f"{where}: unknown simulation backend {name!r}; known: "
                          f"{', '.join(BACKENDS.names())}")
    why = getattr(BACKENDS.get(name), "unavailable", lambda: None)()
    if why:                                  # e.g. mujoco without the [mujoco] extra: one line, before any case
        raise ConfigError(f"{where}: simulation backend {name!r} {why}")
    return name


def load_part(name: str, data: Mapping, where: str, models_dir: Path | Sequence[Path],
              overrides: list | None = None) -> Part:
    """One part, strictly; ``overrides`` (``--set``, :mod:`benchmarks.overrides`) are applied first."""
    if overrides:
        if not isinstance(data, Mapping):
            raise ConfigError(f"{where}: expected a mapping")

        def expand(path, value):   # a joint model given by name, so that its keys can be set
            if path[-1] == "joint" and isinstance(value, str) and len(path) == 2:
                return _resolve_joint({"joint": value}, f"{where}: {path[0]}", models_dir)["joint"]
            return value

        data = _overrides.apply(data, overrides, where, expand)
        where += _overrides.describe(overrides)
    _check_keys(data, _PART_KEYS, where)
    if "grid" not in data:
        extra = [k for k in GRID_KEYS if k in data]
        if extra:
            raise ConfigError(f"{where}: key {extra[0]!r} belongs to a part with a 'grid' (a comparison grid)")
    experiment = data.get("experiment")
    if experiment is not None:
        if not isinstance(experiment, Mapping):
            raise ConfigError(f"{where}: key 'experiment': expected a mapping")
        experiment = _resolve_joint(experiment, f"{where}: experiment", models_dir)
    est = data.get("estimators") or {}
    if not isinstance(est, Mapping) or not all(v is None or isinstance(v, Mapping) for v in est.values()):
        raise ConfigError(f"{where}: key 'estimators': expected a mapping name -> settings")
    sweep = data.get("sweep") or {}
    if not isinstance(sweep, Mapping) or not all(isinstance(v, list) and v for v in sweep.values()):
        raise ConfigError(f"{where}: key 'sweep': expected a mapping key -> non-empty list of values")
    params = data.get("params") or {}
    if not isinstance(params, Mapping):
        raise ConfigError(f"{where}: key 'params': expected a mapping")
    if "joint" in params:   # analytic parts name a joint model like experiments do
        params = _resolve_joint(params, f"{where}: params", models_dir)
    section = data.get("report_section", "results")
    if section not in REPORT_SECTIONS:
        raise ConfigError(f"{where}: key 'report_section': {section!r} not allowed; allowed: "
                          f"{', '.join(REPORT_SECTIONS)}")
    protocol = str(data["protocol"])
    grid = None
    if "grid" in data:
        from jointbench.benchmarks.compare import grid as _grid

        if sweep:
            raise ConfigError(f"{where}: key 'sweep': a part with a 'grid' takes its values from the grid's axes")
        grid = _grid.parse_grid(data, experiment, {k: dict(v or {}) for k, v in est.items()}, where,
                                lambda m, w: _resolve_joint({"joint": m}, w, models_dir)["joint"])
    return Part(name=name, protocol=protocol, description=str(data["description"]),
                report_section=section,
                backend=check_backend(data.get("backend", "analytic"), f"{where}: key 'backend'"),
                params=dict(params), experiment=experiment,
                estimators={k: dict(v or {}) for k, v in est.items()},
                seeds=_seeds(data.get("seeds"), where),
                sweep={k: tuple(v) for k, v in sweep.items()}, where=where,
                figure=str(data.get("figure") or ""), grid=grid)


def _conditions(value: Any, key: str, where: str, need_metric: bool) -> dict:
    """A ``select``/``versus``/``domain`` mapping: column -> value, or column -> {lt|le|gt|ge: number}."""
    if not isinstance(value, Mapping) or (need_metric and "metric" not in value):
        raise ConfigError(f"{where}: key {key!r}: a mapping column -> value"
                          + (" with at least 'metric'" if need_metric else ""))
    for col, v in value.items():
        if isinstance(v, Mapping):
            bad = sorted(set(v) - set(RANGE_OPS))
            if bad or not v:
                raise ConfigError(f"{where}: key {key}.{col}: a range takes {', '.join(RANGE_OPS)}, got "
                                  f"{bad[0] if bad else 'nothing'!r}")
            for op, bound in v.items():
                if isinstance(bound, bool) or not isinstance(bound, (int, float)):
                    raise ConfigError(f"{where}: key {key}.{col}.{op}: expected a number, got {bound!r}")
    return dict(value)


def _evidence(c: Mapping, where: str) -> tuple[str, str, str]:
    """``evidence`` with what it requires: ``reading`` for conditional, ``free_parameter`` for calibrated."""
    ev = c["evidence"]
    if ev not in EVIDENCE:
        raise ConfigError(f"{where}: key 'evidence': {ev!r} not allowed; allowed: {', '.join(EVIDENCE)}")
    reading, free = str(c.get("reading", "")).strip(), str(c.get("free_parameter", "")).strip()
    if ev == "conditional":
        ids = [r.strip() for r in reading.split(",") if r.strip()]
        if not ids or not all(re.fullmatch(r"[A-Z]+\d+", r) for r in ids):
            raise ConfigError(f"{where}: evidence 'conditional' needs key 'reading': the reading(s) chosen by "
                              f"outcome that the check passes under, e.g. 'R1' or 'R1, R2'; got {reading!r}")
    elif "reading" in c:
        raise ConfigError(f"{where}: key 'reading' applies to evidence 'conditional' only")
    if ev == "calibrated":
        if not free:
            raise ConfigError(f"{where}: evidence 'calibrated' needs key 'free_parameter': the parameter chosen "
                              f"to match the published value (and its value)")
    elif "free_parameter" in c:
        raise ConfigError(f"{where}: key 'free_parameter' applies to evidence 'calibrated' only")
    return ev, reading, free


def load_checks(path: Path, parts: Mapping[str, Part]) -> tuple[Check, ...]:
    data = _load_yaml(path)
    _check_keys(data, {"study": True, "source": True, "checks": True}, str(path))
    out, seen = [], set()
    if not isinstance(data["checks"] or [], list):
        raise ConfigError(f"{path}: key 'checks': expected a list of checks, got {data['checks']!r}")
    for i, c in enumerate(data["checks"] or []):
        where = f"{path}: check {c['id']}" if isinstance(c, Mapping) and "id" in c else f"{path}: checks[{i}]"
        _check_keys(c, _CHECK_KEYS, where)
        if c["id"] in seen:
            raise ConfigError(f"{where}: key 'id': duplicate check id {c['id']!r}")
        seen.add(c["id"])
        if c["part"] not in parts:
            raise ConfigError(f"{where}: key 'part': unknown part {c['part']!r}; parts: {', '.join(parts)}")
        kind = c.get("kind", "value")
        if kind not in CHECK_KINDS:
            raise ConfigError(f"{where}: key 'kind': {kind!r} not allowed; allowed: {', '.join(CHECK_KINDS)}")
        needs, allows = CHECK_KINDS[kind]
        for key in sorted(needs - set(c)):
            raise ConfigError(f"{where}: check kind '{kind}' needs key {key!r}")
        extra = sorted((set(c) & (set().union(*(v[1] for v in CHECK_KINDS.values())))) - allows)
        if extra:
            raise ConfigError(f"{where}: key {extra[0]!r} does not apply to check kind '{kind}'; "
                              f"it takes: {', '.join(sorted(allows))}")
        if c.get("evidence", "reproduction") not in EVIDENCE:
            raise ConfigError(f"{where}: key 'evidence': {c['evidence']!r} not allowed; allowed: {', '.join(EVIDENCE)}")
        agg = c.get("aggregate", "median")
        if agg not in AGGREGATES:
            raise ConfigError(f"{where}: key 'aggregate': {agg!r} not allowed; allowed: {', '.join(AGGREGATES)}")
        try:
            low, high = float(c.get("low", -math.inf)), float(c.get("high", math.inf))
            slack = float(c.get("slack", 0.0))
        except (TypeError, ValueError):
            raise ConfigError(f"{where}: keys 'low', 'high' and 'slack' must be numbers") from None
        if low > high:
            raise ConfigError(f"{where}: low {low} > high {high}")
        if slack < 0:
            raise ConfigError(f"{where}: key 'slack': must be >= 0, got {slack}")
        direction = c.get("direction", "decreasing")
        if direction not in ("decreasing", "increasing"):
            raise ConfigError(f"{where}: key 'direction': {direction!r}; allowed: decreasing, increasing")
        select = _conditions(c["select"], "select", where, True)
        versus = _conditions(c["versus"], "versus", where, True) if "versus" in c else None
        domain = _conditions(c["domain"], "domain", where, False) if "domain" in c else None
        if (domain is None) != ("domain_reason" not in c):
            raise ConfigError(f"{where}: keys 'domain' and 'domain_reason' go together (a domain needs its reason)")
        if domain is not None:
            clash = sorted(set(domain) & (set(select) | set(versus or {})))
            if clash:
                raise ConfigError(f"{where}: key 'domain': column {clash[0]!r} is also in 'select'/'versus'")
        evidence, reading, free = _evidence(c, where)
        count = str(c.get("count", "headline"))
        if count not in COUNTS:
            raise ConfigError(f"{where}: key 'count': {count!r} not allowed; allowed: {', '.join(COUNTS)}")
        if count == "method_difference" and kind != "difference":
            raise ConfigError(f"{where}: key 'count': 'method_difference' needs check kind 'difference'")
        reason = str(c["tolerance_reason"]).strip()
        if not reason:
            raise ConfigError(f"{where}: key 'tolerance_reason': state why the band is what it is")
        out.append(Check(id=str(c["id"]), part=c["part"], description=str(c["description"]),
                         source=str(c["source"]), published=c["published"], low=low, high=high,
                         select=select, aggregate=agg, if_missed=str(c.get("if_missed", "")),
                         kind=kind, over=str(c.get("over", "")), direction=direction, slack=slack,
                         versus=versus, by=str(c.get("by", "")), evidence=evidence, reading=reading,
                         free_parameter=free, tolerance_reason=reason, domain=domain,
                         domain_reason=str(c.get("domain_reason", "")), count=count,
                         target=str(c.get("target", "")), cause=str(c.get("cause", ""))))
    return tuple(out)


def _not_reproduced(value: Any, where: str) -> tuple[NotReproduced, ...]:
    if not isinstance(value, list):
        raise ConfigError(f"{where}: key 'not_reproduced': a list of {{item, reason}} naming every published "
                          f"table, figure and value left out (write the list even when it is short; [] for a "
                          f"study that leaves nothing out)")
    out = []
    for i, v in enumerate(value):
        _check_keys(v, {"item": True, "reason": True}, f"{where}: not_reproduced[{i}]")
        if not str(v["item"]).strip() or not str(v["reason"]).strip():
            raise ConfigError(f"{where}: not_reproduced[{i}]: 'item' and 'reason' must not be empty")
        out.append(NotReproduced(str(v["item"]).strip(), str(v["reason"]).strip()))
    return tuple(out)


def _method_swap(value: Any, where: str, parts: Mapping[str, Part]) -> MethodSwap | None:
    if value is None:
        return None
    _check_keys(value, {"part": True, "estimators": True}, f"{where}: method_swap")
    if value["part"] not in parts:
        raise ConfigError(f"{where}: method_swap.part: unknown part {value['part']!r}")
    est = value["estimators"]
    if not (isinstance(est, list) and len(est) == 2 and all(isinstance(e, str) for e in est) and est[0] != est[1]):
        raise ConfigError(f"{where}: method_swap.estimators: two different estimator names, got {est!r}")
    return MethodSwap(str(value["part"]), (est[0], est[1]))


def load_study(path: str | Path | Mapping, overrides=()) -> Study:
    """Load a shipped study (by id), a study file (by path) or a study mapping with its checks, strictly.

    Relative paths and model names in the file are looked up beside it first, then in the package
    (:func:`search_roots`). ``published`` is optional: a study without it (a comparison) has no checks.
    ``plugins`` (module names or ``.py`` files) are imported first, so that their estimators can be named.
    ``overrides``: ``--set PART.KEY=VALUE`` texts (:mod:`benchmarks.overrides`), applied to the parts'
    YAML before the strict parse; errors name the override."""
    if isinstance(path, Mapping):    # a study as a mapping (jointbench.api.run): names resolve from the current folder
        data, path = dict(path), Path.cwd() / f"{path.get('study', 'study')}.yaml"
    else:
        path = study_path(path)
        data = _load_yaml(path)
    _check_keys(data, _STUDY_KEYS, str(path))
    parts_data = data["parts"]
    if not isinstance(parts_data, Mapping) or not parts_data:
        raise ConfigError(f"{path}: key 'parts': expected a non-empty mapping")
    roots = search_roots(path)
    plugin_specs = load_plugins(data.get("plugins"), str(path), roots)
    models_dir = model_dirs(roots)
    per_part = _overrides.for_parts(overrides, list(parts_data), str(path))
    parts = {name: load_part(name, p, f"{path}: parts.{name}", models_dir, per_part[name])
             for name, p in parts_data.items()}
    readings = []
    for i, r in enumerate(data.get("readings") or []):
        where = f"{path}: readings[{i}]"
        _check_keys(r, {"id": True, "topic": True, "passage": True, "reading": True, "alternatives": False}, where)
        readings.append(Reading(**{k: str(v) for k, v in r.items()}))
    published = data.get("published")
    if "published" in data and (not isinstance(published, str) or not published.strip()):
        raise ConfigError(f"{path}: key 'published': expected the path of the published values (e.g. "
                          f"published.yaml beside the study) or no key at all, got {published!r}")
    pub = find_file(published, roots, str(path), "published") if published else None
    checks = load_checks(pub, parts) if pub is not None else ()
    known = {r.id for r in readings}
    for c in checks:
        missing = [r for r in c.readings if r not in known]
        if missing:
            raise ConfigError(f"{pub}: check {c.id}: key 'reading': {missing[0]} is not a reading of {path.name} "
                              f"({', '.join(sorted(known)) or 'none'})")
    expected = data.get("expected_failures", False)
    if not isinstance(expected, bool):
        raise ConfigError(f"{path}: key 'expected_failures': expected true or false, got {expected!r}")
    return Study(id=str(data["study"]), title=str(data["title"]), paper=str(data["paper"]), path=path,
                 parts=parts, readings=tuple(readings), checks=checks,
                 not_reproduced=_not_reproduced(data["not_reproduced"], str(path)),
                 method_swap=_method_swap(data.get("method_swap"), str(path), parts), plugins=plugin_specs,
                 expected_failures=expected)
