"""Study configs: YAML -> typed, validated objects.

A study config (``configs/studies/<id>.yaml``) names its parts (one per figure or table of the
paper), and for each part the protocol that computes it, its parameters, the simulated experiment
(joint model, apparatus, perturbation, sensors, noise, sampling), the estimators with their settings,
the seeds and any parameter sweep. Published values with tolerances and their source live in
``configs/published/<id>.yaml``. Joint models may be given inline or by the name of a file in
``configs/models/``. Every error names the file, the key and what is allowed.
"""
from __future__ import annotations

import dataclasses
import itertools
import math
from pathlib import Path
from typing import Any, Mapping

import yaml

from jointbench.errors import ConfigError

REPO = Path(__file__).resolve().parents[1]
CONFIGS = REPO / "configs"


def _load_yaml(path: Path) -> Any:
    if not path.is_file():
        raise ConfigError(f"{path}: file not found")
    try:
        return yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML: {exc}") from None


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
    """One published value with its tolerance and how to compute it from the tidy rows."""

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
    evidence: str = ""


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

    def grid(self) -> list[dict[str, Any]]:
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


_PART_KEYS = {"protocol": True, "description": True, "params": False, "experiment": False,
              "estimators": False, "seeds": False, "sweep": False, "report_section": False}
REPORT_SECTIONS = ("results", "interpretation")
_STUDY_KEYS = {"study": True, "title": True, "paper": True, "published": True, "readings": False,
               "parts": True}
_CHECK_KEYS = {"id": True, "part": True, "description": True, "source": True, "published": True,
               "low": False, "high": False, "select": True, "aggregate": False, "if_missed": False,
               "kind": False, "over": False, "direction": False, "slack": False, "versus": False, "by": False,
               "evidence": False}
#: what a check's pass is evidence of (the guide's kinds); optional, checked when given
EVIDENCE = ("reproduction", "calibrated", "sanity", "conditional")
AGGREGATES = ("median", "mean", "min", "max")
#: check kind -> keys it needs (besides the common ones) and keys it allows
CHECK_KINDS = {
    "value": ({"low", "high"}, {"low", "high", "aggregate"}),
    "trend": ({"over"}, {"over", "direction", "slack", "aggregate"}),
    "difference": ({"versus"}, {"versus", "by", "low", "high", "aggregate"}),
}


def _resolve_joint(experiment: Mapping, where: str, models_dir: Path) -> dict:
    exp = dict(experiment)
    joint = exp.get("joint")
    if isinstance(joint, str):
        path = models_dir / f"{joint}.yaml"
        if not path.is_file():
            known = ", ".join(sorted(p.stem for p in models_dir.glob("*.yaml"))) or "(none)"
            raise ConfigError(f"{where}: key 'joint': no model file {path.name} in {models_dir}; "
                              f"known: {known}")
        exp["joint"] = _load_yaml(path)
    return exp


def _seeds(value: Any, where: str) -> tuple[int, ...]:
    if value is None:
        return (0,)
    if isinstance(value, int) and not isinstance(value, bool):
        if value < 1:
            raise ConfigError(f"{where}: key 'seeds': need at least 1 seed, got {value}")
        return tuple(range(value))
    if isinstance(value, list) and value and all(isinstance(v, int) and not isinstance(v, bool)
                                                 for v in value):
        if len(set(value)) != len(value):
            raise ConfigError(f"{where}: key 'seeds': repeated seed in {value}")
        return tuple(value)
    raise ConfigError(f"{where}: key 'seeds': expected a count (e.g. 7) or a list of whole numbers, "
                      f"got {value!r}")


def load_part(name: str, data: Mapping, where: str, models_dir: Path) -> Part:
    _check_keys(data, _PART_KEYS, where)
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
    return Part(name=name, protocol=str(data["protocol"]), description=str(data["description"]),
                report_section=section,
                params=dict(params), experiment=experiment,
                estimators={k: dict(v or {}) for k, v in est.items()},
                seeds=_seeds(data.get("seeds"), where),
                sweep={k: tuple(v) for k, v in sweep.items()}, where=where)


def load_checks(path: Path, parts: Mapping[str, Part]) -> tuple[Check, ...]:
    data = _load_yaml(path)
    _check_keys(data, {"study": True, "source": True, "checks": True}, str(path))
    out, seen = [], set()
    for i, c in enumerate(data["checks"] or []):
        where = f"{path}: checks[{i}]"
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
        for key in ("select", "versus"):
            if key in c and (not isinstance(c[key], Mapping) or "metric" not in c[key]):
                raise ConfigError(f"{where}: key {key!r}: a mapping with at least 'metric'")
        out.append(Check(id=str(c["id"]), part=c["part"], description=str(c["description"]),
                         source=str(c["source"]), published=c["published"], low=low, high=high,
                         select=dict(c["select"]), aggregate=agg, if_missed=str(c.get("if_missed", "")),
                         kind=kind, over=str(c.get("over", "")), direction=direction, slack=slack,
                         versus=dict(c["versus"]) if "versus" in c else None, by=str(c.get("by", "")),
                         evidence=str(c.get("evidence", ""))))
    return tuple(out)


def load_study(path: str | Path, configs_dir: Path = CONFIGS) -> Study:
    """Load ``configs/studies/<id>.yaml`` (or a path) with its published checks, strictly."""
    path = Path(path)
    if not path.suffix:
        path = configs_dir / "studies" / f"{path}.yaml"
    data = _load_yaml(path)
    _check_keys(data, _STUDY_KEYS, str(path))
    parts_data = data["parts"]
    if not isinstance(parts_data, Mapping) or not parts_data:
        raise ConfigError(f"{path}: key 'parts': expected a non-empty mapping")
    models_dir = configs_dir / "models"
    parts = {name: load_part(name, p, f"{path}: parts.{name}", models_dir) for name, p in parts_data.items()}
    readings = []
    for i, r in enumerate(data.get("readings") or []):
        where = f"{path}: readings[{i}]"
        _check_keys(r, {"id": True, "topic": True, "passage": True, "reading": True, "alternatives": False}, where)
        readings.append(Reading(**{k: str(v) for k, v in r.items()}))
    pub = Path(data["published"])
    pub = pub if pub.is_absolute() else configs_dir.parent / pub
    checks = load_checks(pub, parts)
    return Study(id=str(data["study"]), title=str(data["title"]), paper=str(data["paper"]), path=path,
                 parts=parts, readings=tuple(readings), checks=checks)
