"""Comparison grids: a study part that names estimators x scenarios x ... and lets the harness expand it.

A part with a ``grid`` runs protocol ``compare`` (:mod:`jointbench.benchmarks.compare.protocol`) on every
combination of its axes, one case per estimator and combination (all R realizations in it)::

    matrix:
      protocol: compare
      seeds: 1                       # base seeds; each case simulates params.realizations realizations
      params: {realizations: 10, ensemble_size: 5}
      budget: 30                     # minutes: a larger estimate needs --yes
      grid:                          # axis -> values (every axis but estimator is optional)
        estimator: [fsewls, kbr, skirt, sds]
        scenario: [xu1998_elbow, vanderuit2018_wrist]
        variation: [sine, square]
        noise: [0.01, 0.1]           # var(noise) / var(torque) on the torque channel
        backend: [analytic, mujoco]
        data: [trial, ensemble]      # fit single trials or ensembles (default: what the estimator takes)
        tuning: [paper, tuned]       # the settings as given, or chosen on tuning realizations (below)
      tuning: {sds: {window: [0.5 s, 1 s, 2 s]}}   # the search of 'tuned' (benchmarks/compare/tuning.py); an
                                     # estimator not named: the search its settings declare (param tune=)
      only:                          # run part of the grid; the rest is skipped with the reason
        - {when: {backend: mujoco}, keep: {tuning: paper, data: trial}, reason: "MuJoCo on a subset"}
      scenarios:                     # name -> an experiment and how to score it
        xu1998_elbow:
          experiment: {...}          # as in any part
          stiffness: {mean: 40, amplitude: 15, period: 2 s}   # levels and time scale of the variations
          estimators: {fsewls: {...}}   # settings for this scenario (over the part's)
      variations: {sine: {shape: sine}, square: {shape: square}}   # levels from the scenario
      estimators: {fsewls: {...}}    # settings of the estimators on the axis

The other axes (``joint``, ``perturbation``, ``fs``) and keys (a scenario's ``discard``, ``realizations``,
``tuning``; ``perturbations``): docs/study_yaml.md, generated from the specs below.

Every resolved experiment (the axes but estimator, data and tuning) also gets one case of protocol
``identifiability`` (rows with estimator ``(scenario)``: how much of the measured torque the stiffness and its
time variation explain, :mod:`jointbench.benchmarks.compare.identifiability`): the report's diagnosis of a
scenario no method can rank. ``params.identify: false`` leaves them out (the report then says how to get them).

A combination an estimator cannot run is skipped and reported with the reason (:mod:`.skips`: a perturbation it
cannot identify from, data it does not take, valid settings that cannot go together, a backend whose extra is
not installed: the other backends' rows run). Any other error in a combination (a typo'd key, a negative
duration, a profile file that is missing or makes K negative, an unstable MuJoCo step) is a config error naming
the combination, before anything runs (exit 2): every distinct error at once, and a variation's keys when the
study is loaded, with the file's other errors. A name or value the grid does not know, or a value listed twice
(``[1, 1.0]``, ``[100 Hz, 0.1 kHz]``), is a config error naming the axis, the value and what is allowed; so is a
grid of more than :data:`MAX_COMBINATIONS`. Every key: docs/study_yaml.md.
"""
from __future__ import annotations

import copy
import dataclasses
import itertools
import json
import math
from typing import Any, Callable, Mapping

from jointbench import estimators, sims
from jointbench.benchmarks.compare.oracle import trials_estimate as oracle_trials
from jointbench.benchmarks.compare.tuning import (AXES, AxisValues, OnlyRule, candidates, check_known_estimators,
                                                  check_search, check_search_applies, grid_settings, nothing_to_tune,
                                                  search_for, skip_summary)
from jointbench.core.errors import ConfigError
from jointbench.benchmarks.compare.protocol import CompareParams
from jointbench.benchmarks.compare.skips import backend_missing, build_experiment, skip_reason
from jointbench.core.schema import Problems, boolean, number, param, parse
from jointbench.sims.profile import parse_profile

NATIVE = "native"
DATA = ("trial", "ensemble")
#: the tuning axis: the paper's settings, or tuned on tuning realizations (protocols.compare)
TUNING = ("paper", "tuned")
#: the axes an identifiability case has (one per resolved experiment: no estimator, data or tuning)
SCENARIO_AXES = AXES[:7]
#: default budget (minutes) of a grid part without ``budget``
DEFAULT_BUDGET_MIN = 30.0
#: most combinations a grid may have: each is built and checked when the study is expanded (about a
#: millisecond each), before the budget is estimated; the matrix study has 704
MAX_COMBINATIONS = 20_000

#: a tuning search: estimator -> setting -> the values tried
Search = dict[str, dict[str, tuple[Any, ...]]]


@dataclasses.dataclass(frozen=True)
class Stiffness:
    """Levels and time scale a scenario gives the time variations (``variations`` are relative)."""

    mean: float = param(unit="N.m/rad", gt=0, doc="mean stiffness")
    amplitude: float = param(unit="N.m/rad", ge=0, doc="half the range of the variation")
    period: float = param(unit="s", gt=0, doc="period of the sine and square variations")
    key: str = param("", doc="the joint model's stiffness key (default: K, or k for the wrist)")


@dataclasses.dataclass(frozen=True)
class ScenarioSpec:
    """A scenario of a grid: an experiment, the levels its variations take and how it is scored."""

    experiment: dict = param(doc="the experiment simulated (as a part's)")
    stiffness: Stiffness | None = param(None, doc="levels and period of the variations (needed with a variation axis)")
    discard: float | None = param(None, unit="s", ge=0, doc="seconds not scored at each end")
    realizations: int | None = param(None, ge=2, doc="R of this scenario (over params.realizations)")
    estimators: dict = param(default_factory=dict, doc="estimator -> settings for this scenario")
    tuning: Search = param(default_factory=dict, doc="estimator -> setting -> values searched (over the part's)")


@dataclasses.dataclass(frozen=True, kw_only=True)
class GridAxes(AxisValues):
    """The axes of a grid: the estimators compared, and any other axis (:data:`AXES`)."""

    estimator: tuple[Any, ...] = param(doc="the estimators compared")


def _axes(value: Any, where: str, key: str) -> GridAxes:
    """The grid's axes: each a non-empty list of values, each value listed once."""
    if isinstance(value, Mapping):
        for axis, values in value.items():
            if not isinstance(values, list) or not values:
                raise ConfigError(f"{where}: grid.{axis}: expected a non-empty list of values, got {values!r}")
            if len({json.dumps(v, sort_keys=True, default=str) for v in values}) != len(values):
                raise ConfigError(f"{where}: grid.{axis}: a value is listed twice in {values}")
    return parse(GridAxes, value, f"{where}: {key}")


@dataclasses.dataclass(frozen=True, kw_only=True)
class GridSpec:
    """The keys of a part with a comparison grid, as written (the module docstring)."""

    grid: GridAxes = param(parser=_axes, doc="axis -> the values it takes (every axis but estimator is optional)")
    scenarios: dict[str, ScenarioSpec] = param(default_factory=dict, doc="name -> an experiment and its scoring")
    variations: dict[str, dict] = param(default_factory=dict, doc="name -> a relative stiffness variation")
    perturbations: dict[str, dict] = param(default_factory=dict, doc="name -> a perturbation {kind: ...}")
    budget: float = param(DEFAULT_BUDGET_MIN, unit="min", gt=0, doc="a larger estimated time needs --yes")
    tuning: Search = param(default_factory=dict, doc="estimator -> setting -> values searched by 'tuned'")
    only: tuple[OnlyRule, ...] = param((), doc="rules that run part of the grid")


@dataclasses.dataclass(frozen=True)
class Grid:
    """A parsed comparison grid (see the module docstring)."""

    axes: Mapping[str, tuple]
    scenarios: Mapping[str, ScenarioSpec]
    variations: Mapping[str, dict]
    perturbations: Mapping[str, dict]
    joints: Mapping[str, dict]
    settings: Mapping[str, dict]
    budget_minutes: float
    search: Mapping[str, dict] = dataclasses.field(default_factory=dict)
    only: tuple[OnlyRule, ...] = ()

    def size(self) -> int:
        return math.prod(len(v) for v in self.axes.values())


def parse_grid(data: Mapping, experiment: Mapping | None, part_estimators: Mapping[str, dict], where: str,
               resolve_joint: Callable[[Any, str], dict], overridden: bool = False) -> Grid:
    """The grid of a part from its grid keys ``data`` (:class:`GridSpec`: ``grid``, ``scenarios``,
    ``variations``, ``perturbations``, ``budget``, ``tuning``, ``only``), every name and value checked;
    the errors name the part, the axis, the value and what is allowed, all of them at once. An idle tuning search
    is an error as written, not when ``overridden`` (``--set matrix.grid.estimator=[sds]``: idle on purpose)."""
    spec = parse(GridSpec, data, where)
    scenarios = _scenarios(spec, experiment, where, resolve_joint)
    axes = spec.grid.given()
    axes.setdefault("scenario", tuple(scenarios))
    problems, found = Problems(), {}
    with problems.catch():
        _check_names(axes, scenarios, spec, part_estimators, where)
    with problems.catch():
        found["joints"] = _joints(axes, where, resolve_joint)
    with problems.catch():
        _check_values(axes, where)
    with problems.catch():
        _check_size(axes, where)
    with problems.catch():
        _check_variations(spec.variations, scenarios, where)
    problems.raise_all()
    found["settings"] = _settings(axes, scenarios, part_estimators, where)     # of the estimators named
    found["search"] = _search(spec, scenarios, axes, part_estimators, where, overridden)
    return Grid(axes=axes, scenarios=scenarios, variations=spec.variations, perturbations=spec.perturbations,
                joints=found["joints"], settings=found["settings"], budget_minutes=float(spec.budget),
                search=found["search"], only=spec.only)


def _scenarios(spec: GridSpec, experiment: Mapping | None, where: str,
               resolve_joint: Callable[[Any, str], dict]) -> dict[str, ScenarioSpec]:
    """The scenarios (``scenarios``, or the part's one ``experiment``), their joint models resolved."""
    if spec.scenarios and experiment is not None:
        raise ConfigError(f"{where}: give either 'experiment' (one scenario) or 'scenarios', not both")
    if not spec.scenarios and experiment is None:
        raise ConfigError(f"{where}: a grid needs 'scenarios' (or one 'experiment')")
    given = spec.scenarios or {"experiment": ScenarioSpec(experiment=dict(experiment))}
    problems, out = Problems(), {}
    for name, sc in given.items():
        w = f"{where}: scenarios.{name}"
        exp = dict(sc.experiment)
        with problems.catch():
            if isinstance(exp.get("joint"), str):
                exp["joint"] = resolve_joint(exp["joint"], f"{w}: experiment")
            check_known_estimators(sc.estimators, f"{w}: estimators")
        out[name] = dataclasses.replace(sc, experiment=exp)
    problems.raise_all()
    return out


def _check_names(axes: Mapping[str, tuple], scenarios: Mapping, spec: GridSpec, part_estimators: Mapping,
                 where: str) -> None:
    """Every value of the axes that name things (scenario, estimator, variation, perturbation) is defined
    (or ``native``); the perturbations name known kinds; a variation axis has the levels of every scenario."""
    _names("scenario", axes["scenario"], scenarios, where, "scenario", native=False)
    _names("estimator", axes["estimator"], estimators.REGISTRY.names(), where, "estimator", native=False)
    # settings of an estimator not on the axis are kept (an axis shortened by --set)
    check_known_estimators(part_estimators, f"{where}: estimators")
    _names("variation", axes.get("variation", ()), spec.variations, where, "variation")
    _names("perturbation", axes.get("perturbation", ()), spec.perturbations, where, "perturbation")
    for name, pert in spec.perturbations.items():
        kind = pert.get("kind")
        if kind not in sims.PERTURBATIONS:
            raise ConfigError(f"{where}: perturbations.{name}: unknown perturbation kind {kind!r}; known: "
                              f"{', '.join(sims.PERTURBATIONS.names())}")
    if "variation" in axes:
        missing = [n for n, sc in scenarios.items() if sc.stiffness is None]
        if missing:
            raise ConfigError(f"{where}: scenarios.{missing[0]}: the grid has a 'variation' axis, so the scenario "
                              f"needs 'stiffness: {{mean, amplitude, period}}' (the levels the variations take)")


def _check_variations(variations: Mapping[str, dict], scenarios: Mapping[str, ScenarioSpec], where: str) -> None:
    """Every variation makes a profile at a scenario's levels (the first scenario with ``stiffness``): a missing
    or wrong key of a variation is found when the study is loaded, with the file's other errors, every one at
    once (not one per run, combination by combination, as the grid is expanded)."""
    levels = next((sc.stiffness for sc in scenarios.values() if sc.stiffness is not None), None)
    if levels is None:
        return
    problems = Problems()
    for name, variation in variations.items():
        with problems.catch():
            parse_profile(stiffness_profile(variation, levels), f"{where}: variations.{name}")
    problems.raise_all()


def _names(axis: str, values: tuple, known, where: str, what: str, native: bool = True) -> None:
    for i, v in enumerate(values):
        if native and v == NATIVE:
            continue
        if not isinstance(v, str) or v not in known:
            allowed = ", ".join(([NATIVE] if native else []) + list(known)) or "(none defined)"
            raise ConfigError(f"{where}: grid.{axis}[{i}]: unknown {what} {v!r}; allowed: {allowed}")


def _settings(axes: Mapping[str, tuple], scenarios: Mapping[str, ScenarioSpec], part_estimators: Mapping,
              where: str) -> dict[str, dict]:
    """The part's settings of each estimator on the axis; every combination with a scenario's parses."""
    settings = {}
    for est in axes["estimator"]:
        base = dict(part_estimators.get(est) or {})
        for sname, sc in scenarios.items():
            estimators.make(est, {**base, **(sc.estimators.get(est) or {})},
                            f"{where}: estimators.{est} (scenario {sname})")
        settings[est] = base
    return settings


def _joints(axes: Mapping[str, tuple], where: str, resolve_joint: Callable[[Any, str], dict]) -> dict[str, dict]:
    """The joint models of the ``joint`` axis (``native`` is the scenario's own)."""
    joints = {}
    for i, v in enumerate(axes.get("joint", ())):
        if v != NATIVE:
            if not isinstance(v, str):
                raise ConfigError(f"{where}: grid.joint[{i}]: expected '{NATIVE}' or the name of a model in "
                                  f"configs/models, got {v!r}")
            joints[v] = resolve_joint(v, f"{where}: grid.joint[{i}]")
    return joints


def _no_repeats(axis: str, given, values: list, where: str, unit: str = "") -> None:
    """Two entries of an axis that mean the same value (``[1, 1.0]``, ``[100 Hz, 0.1 kHz]``) would run the
    same cases twice under two names: refused."""
    seen: dict = {}
    for i, v in enumerate(values):
        if v in seen:
            raise ConfigError(f"{where}: grid.{axis}[{i}]: {given[i]!r} is the same value as grid.{axis}"
                              f"[{seen[v]}] {given[seen[v]]!r} ({v:g}{unit}); list each value once")
        seen[v] = i


def _check_values(axes: dict[str, tuple], where: str) -> None:
    """The values of the noise, fs, backend, data and tuning axes (``fs`` read in Hz, in place)."""
    for i, v in enumerate(axes.get("noise", ())):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (v >= 0 and math.isfinite(v)):
            raise ConfigError(f"{where}: grid.noise[{i}]: expected a number >= 0 (var(noise)/var(torque) on the "
                              f"torque channel; 0 = no noise), got {v!r}")
    _no_repeats("noise", axes.get("noise", ()), [float(v) for v in axes.get("noise", ())], where)
    if "fs" in axes:
        fs = [v if v == NATIVE else float(number(v, "Hz", f"{where}: grid", f"fs[{i}]"))
              for i, v in enumerate(axes["fs"])]
        for i, x in enumerate(fs):
            if x != NATIVE and not x > 0:
                raise ConfigError(f"{where}: grid.fs[{i}]: expected '{NATIVE}' or a rate > 0 Hz, got {axes['fs'][i]!r}")
        _no_repeats("fs", axes["fs"], fs, where, " Hz")
        axes["fs"] = tuple(fs)
    for i, v in enumerate(axes.get("backend", ())):
        if not isinstance(v, str) or v not in sims.BACKENDS:
            raise ConfigError(f"{where}: grid.backend[{i}]: unknown simulation backend {v!r}; known: "
                              f"{', '.join(sims.BACKENDS.names())}")
    for axis, allowed in (("data", DATA), ("tuning", TUNING)):
        for i, v in enumerate(axes.get(axis, ())):
            if v not in allowed:
                raise ConfigError(f"{where}: grid.{axis}[{i}]: {v!r} not allowed; allowed: {', '.join(allowed)}")


def _search(spec: GridSpec, scenarios: Mapping[str, ScenarioSpec], axes: Mapping[str, tuple],
            part_estimators: Mapping, where: str, overridden: bool = False) -> Search:
    """The part's tuning search; with each scenario's over it, every candidate of every estimator parses; none
    idle (:func:`check_search_applies`) unless the grid was narrowed by ``--set``."""
    check_search(spec.tuning, f"{where}: tuning")
    for at, search in [] if overridden else [(f"{where}: tuning", spec.tuning)] + [
            (f"{where}: scenarios.{s}.tuning", sc.tuning) for s, sc in scenarios.items()]:
        check_search_applies(search, axes, at)
    for sname, sc in scenarios.items():
        check_search(sc.tuning, f"{where}: scenarios.{sname}.tuning")
        for est in axes["estimator"]:
            settings = {**grid_settings(part_estimators, est), **(sc.estimators.get(est) or {})}
            for cand in candidates(est, settings, search_for(est, settings, spec.tuning, sc.tuning)):
                estimators.make(est, cand, f"{where}: tuning of {est} (scenario {sname})")
    return spec.tuning


def _check_size(axes: Mapping[str, tuple], where: str) -> None:
    size = math.prod(len(v) for v in axes.values())
    if size > MAX_COMBINATIONS:
        raise ConfigError(f"{where}: grid: {' x '.join(f'{len(v)} {a}' for a, v in axes.items())} = {size} "
                          f"combinations, more than the {MAX_COMBINATIONS} a grid may have; shorten the axes")


# ------------------------------------------------------------------------------------------ expansion
def stiffness_profile(variation: Mapping, levels: Stiffness) -> Any:
    """The profile of a relative variation at a scenario's levels: sine/square/smooth_random take
    ``mean`` and ``amplitude`` (and sine/square the ``period``) unless the variation gives them; a ramp
    goes from ``mean - amplitude`` to ``mean + amplitude``; ``constant`` is ``mean``."""
    v = dict(variation)
    shape = v.get("shape")
    if shape == "constant":
        return float(v.get("mean", levels.mean))
    if shape in ("sine", "square", "smooth_random"):
        v.setdefault("mean", levels.mean)
        v.setdefault("amplitude", levels.amplitude)
        if shape != "smooth_random" and "frequency" not in v:
            v.setdefault("period", levels.period)
    elif shape == "ramp":
        v.setdefault("initial", levels.mean - levels.amplitude)
        v.setdefault("final", levels.mean + levels.amplitude)
    return v


def _experiment(grid: Grid, combo: Mapping[str, Any]) -> dict:
    """The experiment mapping of one combination (scenario with the joint, variation, perturbation,
    noise and rate of the combination)."""
    sc = grid.scenarios[combo["scenario"]]
    exp = copy.deepcopy(sc.experiment)
    if combo.get("joint", NATIVE) != NATIVE:
        exp["joint"] = copy.deepcopy(grid.joints[combo["joint"]])
    if combo.get("variation", NATIVE) != NATIVE:
        joint = exp["joint"]
        key = sc.stiffness.key or ("k" if "k" in joint and "K" not in joint else "K")
        joint[key] = stiffness_profile(grid.variations[combo["variation"]], sc.stiffness)
    if combo.get("perturbation", NATIVE) != NATIVE:
        exp["perturbation"] = copy.deepcopy(grid.perturbations[combo["perturbation"]])
    if "noise" in combo:
        sensors = dict(exp.get("sensors") or {})
        torque = {k: v for k, v in (sensors.get("torque") or {}).items()
                  if k not in ("noise_rms", "noise_snr_db", "noise_variance_ratio")}
        if combo["noise"]:
            torque["noise_variance_ratio"] = combo["noise"]
        sensors["torque"] = torque
        exp["sensors"] = sensors
    if combo.get("fs", NATIVE) != NATIVE:
        exp["acquisition"] = {**(exp.get("acquisition") or {}), "fs": combo["fs"]}
    return exp


def expand_grid(study_id: str, part, backend: str | None = None) -> tuple[list[dict], list[dict]]:
    """The cases of a grid part as the fields of :class:`benchmarks.harness.case.Case` (one per estimator,
    combination and seed; each case simulates every realization), and the skipped combinations (labels,
    ``estimator``, ``reason``). ``backend`` (``--backend``) replaces the backend axis."""
    grid: Grid = part.grid
    axes = dict(grid.axes)
    if backend is not None:
        axes["backend"] = (backend,)
    axes.setdefault("backend", (part.backend,))
    names = [a for a in AXES if a in axes]
    cases, skipped = [], []
    identified: dict[str, dict] = {}       # params.identify: one identifiability case per experiment and seed
    built: dict[str, Any] = {}
    missing = {b: backend_missing(b) for b in axes["backend"]}
    errors: dict[str, dict] = {}           # an invalid experiment's error -> the combinations (no estimator) with it
    identify = boolean(part.params.get("identify", CompareParams.identify), f"{part.where}: params", "identify")
    for values in itertools.product(*(axes[a] for a in names)):
        combo = dict(zip(names, values))
        est = combo["estimator"]
        cls = estimators.REGISTRY.get(est)
        mode = combo.get("data") or ("trial" if "trial" in cls.accepts else "ensemble")
        sc = grid.scenarios[combo["scenario"]]
        mapping = _experiment(grid, combo)
        lacking = missing[combo["backend"]]
        # a backend whose extra is missing (MuJoCo on the light install): skipped with that reason unless another
        # would skip the combination anyway (the estimator's, judged on the analytic backend's experiment)
        exp = build_experiment(built, mapping, "analytic" if lacking else combo["backend"])
        if isinstance(exp, ConfigError) and not lacking:     # an invalid config: an error before anything runs
            errors.setdefault(str(exp), {})[", ".join(f"{a}={v}" for a, v in combo.items() if a != "estimator")] = 1
            continue
        settings = {**grid.settings[est], **(sc.estimators.get(est) or {})}
        tuned = combo.get("tuning") == "tuned"
        search = candidates(est, settings, search_for(est, settings, grid.search, sc.tuning)) if tuned else []
        reason = skip_reason(grid.only, combo, cls, mode, exp, lacking,
                             nothing_to_tune(est, grid.search, sc.tuning) if tuned and not search else None)
        if reason:
            skipped.append({**combo, "data": mode, "reason": reason})
            continue
        params = {**part.params, "data": mode}
        if sc.discard is not None:
            params["discard"] = sc.discard
        if sc.realizations is not None:
            params["realizations"] = sc.realizations
        if search:
            params["search"] = search
        for seed in part.seeds:
            cases.append(dict(study=study_id, part=part.name, protocol=part.protocol, params=params,
                              sweep={**combo, "data": mode}, experiment=mapping, estimators={est: settings},
                              seed=seed, where=part.where, backend=combo["backend"]))
            scen = {a: v for a, v in combo.items() if a in SCENARIO_AXES}
            ident = json.dumps([scen, seed], sort_keys=True, default=str)
            if identify and ident not in identified:
                identified[ident] = dict(study=study_id, part=part.name, protocol="identifiability",
                                         params={k: v for k, v in params.items() if k not in ("data", "search")},
                                         sweep=scen, experiment=mapping, estimators={}, seed=seed,
                                         where=part.where, backend=combo["backend"])
    if errors:                           # every invalid combination at once, each distinct error once
        raise ConfigError("\n".join(
            f"{part.where}: the combination {next(iter(combos))}"
            + (f" (and {len(combos) - 1} more with this error)" if len(combos) > 1 else "")
            + f": {line.removeprefix('the experiment: ')}"
            for text, combos in errors.items() for line in text.splitlines()))
    if not cases:
        raise ConfigError(f"{part.where}: nothing to run: {skip_summary(skipped)}; change the grid's axes or "
                          f"its 'only' rules{' or --backend' if backend is not None else ''}")
    return cases + list(identified.values()), skipped


# --------------------------------------------------------------------------------------- time estimate
#: rough CPU seconds per simulated step of one response, by backend, and of the sensors and acquisition of
#: every trial; measured on the 2-core development machine (the matrix study); the estimate says it is rough
SIM_S_PER_STEP = {"analytic": 0.8e-6, "lti": 0.8e-6, "ltv": 0.8e-6, "mujoco": 4e-6}
TRIAL_S_PER_STEP = 0.15e-6
#: rough fit seconds per acquired sample (of every realization of an ensemble), by estimator (the matrix
#: study's medians); others: FIT_DEFAULT
FIT_S_PER_SAMPLE = {"fsewls": 0.7e-6, "kbr": 12e-6, "skirt": 3e-6, "sds": 6e-6, "guarin": 12e-6,
                    "ensemble_irf": 3e-6, "irf2_ls": 0.3e-6, "irf2_corr": 0.1e-6, "ibk_irf": 2.5e-6,
                    "ibk_spectral": 2.5e-6, "spectral": 2.5e-6, "ensemble_spectral": 10e-6}
FIT_DEFAULT = 1e-5
#: rough CPU seconds a case spends besides its fits (scoring, the bootstrap of the spread, parsing)
CASE_OVERHEAD_S = 0.15


def estimate_seconds(cases: list, groups: list[list[int]]) -> float:
    """A rough estimate (s of one core) of computing ``cases`` of a grid, scheduled in ``groups`` (each
    group simulates its distinct responses once: R realizations, times the ensemble size when a case of
    it fits ensembles)."""
    total = 0.0
    for g in groups:
        first = cases[g[0]]
        exp = sims.Experiment.from_mapping(first.experiment, "estimate", backend=first.backend) \
            if first.experiment is not None else None
        R = int(first.params.get("realizations", 10))
        M = int(first.params.get("ensemble_size", 5))
        ens = any(cases[i].sweep.get("data") == "ensemble" for i in g)
        if exp is not None:
            per_step = SIM_S_PER_STEP.get(first.backend, SIM_S_PER_STEP["mujoco"])
            total += R * (M if ens else 1) * exp.n_sim * per_step
            noises = {json.dumps(cases[i].experiment.get("sensors"), sort_keys=True, default=str) for i in g}
            total += len(noises) * R * (M if ens else 1) * exp.n_sim * TRIAL_S_PER_STEP
        for i in g:
            c = cases[i]
            n = exp.n if exp is not None else 0
            if c.protocol == "identifiability":     # N_IDENTIFY realizations, with and without noise; the oracle's
                trials = 2 * min(R, 3) + oracle_trials(R, M, first.backend)
                total += trials * (exp.n_sim * TRIAL_S_PER_STEP if exp is not None else 0) + CASE_OVERHEAD_S
                continue
            est = next(iter(c.estimators), "")
            k = M if c.sweep.get("data") == "ensemble" else 1
            per_fit = k * n * FIT_S_PER_SAMPLE.get(est, FIT_DEFAULT)
            total += R * per_fit + CASE_OVERHEAD_S
            search = c.params.get("search") or ()
            if search and exp is not None:         # each candidate fitted once; k + 2 tuning realizations
                per_step = SIM_S_PER_STEP.get(first.backend, SIM_S_PER_STEP["mujoco"])
                total += len(search) * per_fit + (k + 2) * exp.n_sim * (per_step + TRIAL_S_PER_STEP)
    return total
