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

Every file is parsed by :func:`jointbench.core.schema.parse` into the typed specs below (the study file:
:class:`StudyFile`, each part: :class:`PartFile`; the readings, items left out and swap test:
:class:`Reading`, :class:`NotReproduced`, :class:`MethodSwap`; the published values:
:mod:`benchmarks.published`), and every error of a file is reported at once, one per line.
"""
from __future__ import annotations

import dataclasses
import itertools
from pathlib import Path
from typing import Any, Literal, Mapping, Sequence

from jointbench.benchmarks import overrides as _overrides
from jointbench.benchmarks.harness.workers import DEFAULT_CASE_TIME_LIMIT_S
from jointbench.benchmarks.locate import (find_file, find_model, load_plugins, model_dirs, search_roots,
                                          study_path)
# the one YAML reader of configs: strict and within limits (benchmarks/config_yaml.py)
from jointbench.benchmarks.config_yaml import MAX_YAML_DEPTH, StrictLoader, load_yaml  # noqa: F401 - re-exported
# the published values (published.yaml): re-exported, the study holds its checks
from jointbench.benchmarks.published import (AGGREGATES, CHECK_KINDS, COUNTS, EVIDENCE, RANGE_OPS,  # noqa: F401
                                             Check, load_checks)
from jointbench.core.errors import ConfigError
from jointbench.core.schema import Problems, error, param, parse



@dataclasses.dataclass(frozen=True)
class Reading:
    """One chosen reading of an ambiguous passage (rendered in the report's Interpretation).

    Parameters
    ----------
    id : str
        Its id (``R1``, ``M7``), named by the checks that pass only under it (their ``reading``).
    topic : str
        What it is about, in a few words.
    passage : str
        The passage of the paper that is ambiguous (quoted or summarised, with its place).
    reading : str
        The reading chosen, and why.
    alternatives : str
        The other readings, and how to run them (e.g. a ``--set``).
    """

    id: str
    topic: str
    passage: str
    reading: str
    alternatives: str = ""


@dataclasses.dataclass(frozen=True)
class NotReproduced:
    """A published table, figure or value the study does not reproduce, and why."""

    item: str = param(doc="the table, figure or value left out")
    reason: str = param(doc="why")

    def __post_init__(self):
        object.__setattr__(self, "item", self.item.strip())
        object.__setattr__(self, "reason", self.reason.strip())
        if not self.item or not self.reason:
            raise ConfigError("'item' and 'reason' must not be empty")


@dataclasses.dataclass(frozen=True)
class MethodSwap:
    """Swap test of a study comparing two methods: with their reproduced values exchanged, how many
    method-specific checks still pass (a check that survives the swap does not tell the methods apart)."""

    part: str = param(doc="the part whose two estimators are swapped")
    estimators: tuple[str, str] = param(doc="the two estimators compared")

    def __post_init__(self):
        if self.estimators[0] == self.estimators[1]:
            raise ConfigError(f"key 'estimators': two different estimator names, got {list(self.estimators)!r}")


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
    case_time_limit_s: float = DEFAULT_CASE_TIME_LIMIT_S    # seconds a case may run (inf: no limit)



REPORT_SECTIONS = ("results", "interpretation")
#: most seeds one part may run (a typo such as ``seeds: 1000000000`` must not exhaust the memory)
MAX_SEEDS = 100_000


# ------------------------------------------------------------------------------------------ parsers
def _seeds(value: Any, where: str, key: str) -> tuple[int, ...]:
    """``seeds``: a count (``7``: seeds 0..6) or a list of distinct whole numbers; none: seed 0."""
    if value is None:
        return (0,)
    if isinstance(value, int) and not isinstance(value, bool):
        if value < 1:
            raise error(where, key, f"need at least 1 seed, got {value}")
        if value > MAX_SEEDS:
            raise error(where, key, f"{value} seeds is more than the {MAX_SEEDS} a part may run")
        return tuple(range(value))
    if isinstance(value, list) and len(value) > MAX_SEEDS:
        raise error(where, key, f"{len(value)} seeds is more than the {MAX_SEEDS} a part may run")
    if isinstance(value, list) and value and all(isinstance(v, int) and not isinstance(v, bool) for v in value):
        if len(set(value)) != len(value):
            raise error(where, key, f"repeated seed in {value}")
        return tuple(value)
    raise error(where, key, f"expected a count (e.g. 7) or a list of whole numbers, got {value!r}")


def _sweep(value: Any, where: str, key: str) -> dict[str, tuple]:
    """``sweep``: key -> the non-empty list of values it takes."""
    value = value or {}
    if not isinstance(value, Mapping) or not all(isinstance(v, list) and v for v in value.values()):
        raise error(where, key, "expected a mapping key -> non-empty list of values")
    return {k: tuple(v) for k, v in value.items()}


def _backend(value: Any, where: str, key: str) -> str:
    return check_backend(value, f"{where}: key '{key}'")


def _published(value: Any, where: str, key: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise error(where, key, f"expected the path of the published values (e.g. published.yaml beside the "
                                f"study) or no key at all, got {value!r}")
    return value


def _not_reproduced(value: Any, where: str, key: str) -> tuple[NotReproduced, ...]:
    if not isinstance(value, list):
        raise error(where, key, "a list of {item, reason} naming every published table, figure and value left "
                                "out (write the list even when it is short; [] for a study that leaves nothing out)")
    problems, out = Problems(), []
    for i, v in enumerate(value):
        with problems.catch():
            out.append(parse(NotReproduced, v, f"{where}: {key}[{i}]"))
    problems.raise_all()
    return tuple(out)


# ---------------------------------------------------------------------------------------- the parts
@dataclasses.dataclass(frozen=True, kw_only=True)
class PartFile:
    """One part of a study file, as written (:func:`load_part`)."""

    protocol: str = param(doc="the protocol that computes it (benchmarks.protocols)")
    description: str = param(doc="what it reproduces")
    params: dict | None = param(None, doc="the protocol's parameters")
    experiment: dict | None = param(None, doc="the simulated experiment (sims.Experiment.from_mapping)")
    estimators: dict[str, dict | None] | None = param(None, doc="estimator -> its settings")
    seeds: tuple[int, ...] = param((0,), parser=_seeds, doc="a count, or a list of seeds")
    sweep: dict[str, tuple] = param(default_factory=dict, parser=_sweep, doc="key -> the values it takes")
    report_section: Literal[REPORT_SECTIONS] = param("results", doc="where the report shows it")
    backend: str = param("analytic", parser=_backend, doc="the simulation backend (sims.BACKENDS)")
    figure: str | None = param("", doc="its figure maker; default: the one named like the protocol")
    # a comparison grid: these keys are parsed by benchmarks.compare.grid.GridSpec
    grid: dict | None = param(None, doc="a comparison grid: axis -> values (benchmarks.compare.grid)")
    scenarios: Any = param(None, doc="grid: name -> an experiment and its scoring")
    variations: Any = param(None, doc="grid: name -> a relative stiffness variation")
    perturbations: Any = param(None, doc="grid: name -> a perturbation")
    budget: Any = param(None, doc="grid: minutes; a larger estimate needs --yes")
    tuning: Any = param(None, doc="grid: estimator -> setting -> values searched")
    only: Any = param(None, doc="grid: rules that run part of the grid")

    def __post_init__(self):
        given = self.grid_keys()
        if self.grid is None and given:
            raise ConfigError(f"key {next(iter(given))!r} belongs to a part with a 'grid' (a comparison grid)")
        if self.grid is not None and self.protocol != "compare":
            raise ConfigError(f"a part with a 'grid' runs protocol 'compare', not {self.protocol!r}")
        if self.grid is not None and self.sweep:
            raise ConfigError("key 'sweep': a part with a 'grid' takes its values from the grid's axes")

    def grid_keys(self) -> dict[str, Any]:
        """The keys of the comparison grid given (:class:`benchmarks.compare.grid.GridSpec`), by name."""
        names = ("grid", "scenarios", "variations", "perturbations", "budget", "tuning", "only")
        return {k: getattr(self, k) for k in names if getattr(self, k) is not None}


def _resolve_joint(experiment: Mapping, where: str, models_dir: Path | Sequence[Path]) -> dict:
    exp = dict(experiment)
    joint = exp.get("joint")
    if isinstance(joint, str):
        exp["joint"] = load_yaml(find_model(joint, [models_dir] if isinstance(models_dir, Path) else models_dir,
                                            where))
    return exp


def resolve_joint(name: str, study_path: Path | None = None, where: str = "joint") -> dict:
    """The joint model named ``name`` (a file ``<name>.yaml`` beside the study, in its ``models/`` folder or
    in the package's ``configs/models``), as its mapping."""
    return _resolve_joint({"joint": name}, where, model_dirs(search_roots(study_path)))["joint"]


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


def _overridden(data: Any, overrides: list, where: str, models_dir: Path | Sequence[Path]) -> tuple[dict, str]:
    """A part's mapping with ``--set`` overrides applied (:mod:`benchmarks.overrides`), and its place name."""
    if not isinstance(data, Mapping):
        raise ConfigError(f"{where}: expected a mapping")

    def expand(path, value):   # a joint model given by name, so that its keys can be set
        if path[-1] == "joint" and isinstance(value, str) and len(path) == 2:
            return _resolve_joint({"joint": value}, f"{where}: {path[0]}", models_dir)["joint"]
        return value

    return _overrides.apply(data, overrides, where, expand), where + _overrides.describe(overrides)


def load_part(name: str, data: Mapping, where: str, models_dir: Path | Sequence[Path],
              overrides: list | None = None) -> Part:
    """One part, strictly; ``overrides`` (``--set``, :mod:`benchmarks.overrides`) are applied first."""
    if overrides:
        data, where = _overridden(data, overrides, where, models_dir)
    spec = parse(PartFile, data, where)
    experiment = spec.experiment
    if experiment is not None:
        experiment = _resolve_joint(experiment, f"{where}: experiment", models_dir)
    params = spec.params or {}
    if "joint" in params:   # analytic parts name a joint model like experiments do
        params = _resolve_joint(params, f"{where}: params", models_dir)
    est = {k: dict(v or {}) for k, v in (spec.estimators or {}).items()}
    grid = None
    if spec.grid is not None:
        from jointbench.benchmarks.compare import grid as _grid

        grid = _grid.parse_grid(spec.grid_keys(), experiment, est, where,
                                lambda m, w: _resolve_joint({"joint": m}, w, models_dir)["joint"],
                                overridden=bool(overrides))
    return Part(name=name, protocol=spec.protocol, description=spec.description, report_section=spec.report_section,
                backend=spec.backend, params=dict(params), experiment=experiment, estimators=est, seeds=spec.seeds,
                sweep=spec.sweep, where=where, figure=spec.figure or "", grid=grid)


# ---------------------------------------------------------------------------------------- the study
@dataclasses.dataclass(frozen=True, kw_only=True)
class StudyFile:
    """A study file, as written (:func:`load_study`)."""

    study: str = param(doc="the study's id")
    title: str = param(doc="its title")
    paper: str = param(doc="the paper it reproduces")
    published: str | None = param(None, parser=_published, doc="the published values (published.yaml)")
    readings: tuple[Reading, ...] | None = param((), doc="the readings chosen of ambiguous passages")
    not_reproduced: tuple[NotReproduced, ...] = param(parser=_not_reproduced, doc="what is left out, and why")
    method_swap: MethodSwap | None = param(None, doc="the swap test of a study comparing two methods")
    parts: dict[str, Any] = param(doc="name -> a part (one figure or table of the paper)")
    plugins: tuple[str, ...] | None = param((), doc="outside modules with estimators, imported first")
    # true: the study expects some cases to fail (a study of where methods break down); without it a run in
    # which any case failed exits non-zero (the exit status tells a scheduler the truth)
    expected_failures: bool = param(False, doc="cases are expected to fail")
    # a case still running after this is killed and fails "timed out after ..." (a plugin that never returns
    # must not hang the run); "90 s", "20 min", or .inf for no limit
    case_time_limit: float = param(DEFAULT_CASE_TIME_LIMIT_S, unit="s", gt=0, allow_inf=True,
                                   doc="the time one case may run before it is killed and fails")

    def __post_init__(self):
        if not self.parts:
            raise ConfigError("key 'parts': expected a non-empty mapping")


def _load_parts(parts_data: Any, path: Path, roots: list[Path], overrides) -> dict[str, Part]:
    """Every part of study file ``path``, every error of every part at once. A part whose name is not text
    (``5:``, ``null:``) is left out here: the study file's own parse reports it (:class:`StudyFile`)."""
    parts_data = {name: p for name, p in parts_data.items() if isinstance(name, str)}
    models_dir = model_dirs(roots)
    per_part = _overrides.for_parts(overrides, list(parts_data), str(path))
    problems, parts = Problems(), {}
    for name, p in parts_data.items():
        with problems.catch():
            parts[name] = load_part(name, p, f"{path}: parts.{name}", models_dir, per_part[name])
    problems.raise_all()
    return parts


def _cross_references(spec: StudyFile, path: Path, parts: Mapping[str, Part], pub: Path | None,
                      checks: tuple[Check, ...]) -> None:
    """The part of the swap test and the readings the checks name exist (every error at once)."""
    problems = Problems()
    if spec.method_swap is not None and spec.method_swap.part not in parts:
        problems.add(ConfigError(f"{path}: method_swap.part: unknown part {spec.method_swap.part!r}"))
    known = {r.id for r in spec.readings or ()}
    for c in checks:
        missing = [r for r in c.readings if r not in known]
        if missing:
            problems.add(ConfigError(f"{pub}: check {c.id}: key 'reading': {missing[0]} is not a reading of "
                                     f"{path.name} ({', '.join(sorted(known)) or 'none'})"))
    problems.raise_all()


def load_study(path: str | Path | Mapping, overrides=()) -> Study:
    """Load a shipped study (by id), a study file (by path) or a study mapping with its checks, strictly.

    Relative paths and model names in the file are looked up beside it first, then in the package
    (:func:`search_roots`). ``published`` is optional: a study without it (a comparison) has no checks.
    ``plugins`` (module names or ``.py`` files) are imported first, so that their estimators can be named.
    ``overrides``: ``--set PART.KEY=VALUE`` texts (:mod:`benchmarks.overrides`), applied to the parts'
    YAML before the strict parse; errors name the override. The errors of the study file are reported at
    once (its keys and its parts'), then those of its published values."""
    if isinstance(path, Mapping):    # a study as a mapping (jointbench.api.run): names resolve from the current folder
        data, path = dict(path), Path.cwd() / f"{path.get('study', 'study')}.yaml"
    else:
        path = study_path(path)
        data = load_yaml(path)
    problems, spec, parts, plugin_specs = Problems(), None, {}, ()
    with problems.catch():
        spec = parse(StudyFile, data, str(path), document=True)
    roots = search_roots(path)
    parts_data = data.get("parts") if isinstance(data, Mapping) else None
    if isinstance(parts_data, Mapping) and (spec is not None or "plugins" not in data):   # their errors too
        with problems.catch():
            plugin_specs = load_plugins((spec.plugins or ()) if spec is not None else (), str(path), roots)
            parts = _load_parts(parts_data, path, roots, overrides)
    problems.raise_all()
    pub = find_file(spec.published, roots, str(path), "published") if spec.published else None
    checks = load_checks(pub, parts) if pub is not None else ()
    _cross_references(spec, path, parts, pub, checks)
    return Study(id=spec.study, title=spec.title, paper=spec.paper, path=path, parts=parts,
                 readings=tuple(spec.readings or ()), checks=checks, not_reproduced=spec.not_reproduced,
                 method_swap=spec.method_swap, plugins=plugin_specs, expected_failures=spec.expected_failures,
                 case_time_limit_s=spec.case_time_limit)
