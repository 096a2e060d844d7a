"""The published values of a study (``published.yaml`` beside its ``study.yaml``): each a :class:`Check` with
its tolerance, what a pass means and how it is computed from the tidy rows; parsed strictly by
:func:`jointbench.core.schema.parse` (:class:`PublishedFile`, :class:`CheckEntry`), every error of the file at
once. Judged by :func:`jointbench.benchmarks.checks.judge`.
"""
from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path
from typing import Any, Literal, Mapping

from jointbench.benchmarks.config_yaml import load_yaml
from jointbench.core.errors import ConfigError
from jointbench.core.schema import Problems, error, param, parse

#: how a check counts: ``headline`` (one published value or claim: the headline when its evidence is
#: reproduction) or ``method_difference`` (a difference of two published cells that are checked one by one
#: already, e.g. KBR - skirt of Table I: its own line beside the headline, never in it)
COUNTS = ("headline", "method_difference")
AGGREGATES = ("median", "mean", "min", "max", "std")
#: kinds of evidence, in the order the report shows them; the headline counts ``reproduction`` only.
#: ``recording``: a value the paper measured on real subjects (a human recording), which a simulation reaches only
#: by inventing dynamics the paper does not give: shown beside the reproduced value, never counted (issue 35)
EVIDENCE = ("reproduction", "recording", "conditional", "calibrated", "sanity")
#: range conditions allowed in ``select``, ``versus`` and ``domain`` (``{f_v: {lt: 1.0}}``)
RANGE_OPS = ("lt", "le", "gt", "ge")
#: check kind -> fields it needs (besides the common ones) and fields it allows
CHECK_KINDS = {
    "value": ({"low", "high"}, {"low", "high", "aggregate"}),
    "trend": ({"over"}, {"over", "direction", "slack", "aggregate", "by"}),
    "difference": ({"versus"}, {"versus", "by", "low", "high", "aggregate"}),
}
_KIND_NAMES = tuple(CHECK_KINDS)
#: the fields a check kind may take (:data:`CHECK_KINDS`); left out, they take :func:`_kind_defaults`
_KIND_FIELDS = tuple(sorted(set().union(*(allows for _, allows in CHECK_KINDS.values()))))

@dataclasses.dataclass(frozen=True)
class Check:
    """One published value with its tolerance and how to compute it from the tidy rows.

    ``evidence`` says what a pass means (:data:`EVIDENCE`): ``reproduction`` (an independent published
    value or claim, judged), ``conditional`` (passes only under ``reading``, a reading chosen by its
    outcome), ``calibrated`` (``free_parameter`` was chosen to match it: shown, never counted as a
    pass), ``sanity`` (arithmetic or self-consistency) or ``recording`` (a value measured on real subjects:
    shown beside the reproduced value, never counted). ``tolerance_reason`` states why the band is
    what it is. Notes (``if_missed``, ``if_missed_below`` / ``if_missed_above`` for a miss on one side of the
    band, ``cause``) state no result figure by hand: ``{value}``, ``{published}``, ``{CHECK-ID}`` and
    ``{CHECK-ID.published}`` (format specs allowed) are filled from the judged rows (:func:`note_fields`).
    ``discrimination_reason`` argues a band that also holds the compared method's published cell. ``domain``
    restricts the scored rows (e.g. ``{f_v: {lt: 1.0}}``, the paper's domain; ``domain_reason`` says why); the
    rows outside it are shown, not scored.

    Parameters
    ----------
    id : str
        The check's id, unique in the file (the rows of ``checks.csv``).
    part : str
        The part of the study whose rows it reads.
    description : str
        What is checked, in words.
    source : str
        Where the published value is (table, figure, page of the paper).
    published : number or text
        The published value (or claim).
    if_missed : str
        The likely reason of a miss, shown beside it.
    target : str
        The published table or figure it belongs to (the report's Fidelity table).
    cause : str
        The one-line cause of a miss, shared by the misses it explains.
    if_missed_below, if_missed_above : str
        The note of a miss below ``low`` / above ``high`` (in place of ``if_missed``).
    discrimination_reason : str
        Why the band tells the compared methods apart though it holds the other method's published cell.
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
    if_missed_below: str = ""      # the note of a miss below ``low`` (else ``if_missed``)
    if_missed_above: str = ""      # the note of a miss above ``high`` (else ``if_missed``)
    discrimination_reason: str = ""  # why the band tells the compared methods apart though it holds the other's cell

    @property
    def readings(self) -> tuple[str, ...]:
        """The reading ids named by ``reading`` (``"R1, R2"`` -> ``("R1", "R2")``)."""
        return tuple(r.strip() for r in self.reading.split(",") if r.strip())



def _kind_defaults() -> dict:
    """The values of :data:`_KIND_FIELDS` left out of a check: :class:`Check`'s defaults, an open band."""
    out = {f.name: f.default for f in dataclasses.fields(Check) if f.name in _KIND_FIELDS
           and f.default is not dataclasses.MISSING}
    return {"low": -math.inf, "high": math.inf, **out}

@dataclasses.dataclass(frozen=True)
class Range:
    """A range condition of ``select``, ``versus`` or ``domain`` (``{f_v: {lt: 1.0}}``): at least one bound.

    Parameters
    ----------
    lt, le, gt, ge : float
        The column's values below, at most, above, at least this.
    """

    lt: float | None = None
    le: float | None = None
    gt: float | None = None
    ge: float | None = None

    def __post_init__(self):
        if all(getattr(self, op) is None for op in RANGE_OPS):
            raise ConfigError(f"a range takes {', '.join(RANGE_OPS)}, got nothing")


def _conditions(need_metric: bool):
    """The parser of a ``select``/``versus``/``domain`` mapping: column -> value, or column -> a range."""
    def parser(value: Any, where: str, key: str) -> dict:
        if not isinstance(value, Mapping) or (need_metric and "metric" not in value):
            raise error(where, key, "a mapping column -> value" + (" with at least 'metric'" if need_metric else ""))
        problems, out = Problems(), dict(value)
        for col, v in value.items():
            if isinstance(v, Mapping):
                with problems.catch():
                    bounds = parse(Range, v, f"{where}: key '{key}.{col}'")
                    out[col] = {op: b if isinstance(b, (int, float)) and not isinstance(b, bool)
                                else getattr(bounds, op) for op, b in v.items()}
        problems.raise_all()
        return out
    return parser


@dataclasses.dataclass(frozen=True, kw_only=True)
class CheckEntry(Check):
    """One check as written in ``published.yaml`` (:class:`Check`, strictly: :meth:`to_check`).

    The fields a check kind needs and takes (:data:`CHECK_KINDS`) are None or empty when not given;
    ``evidence`` and ``tolerance_reason`` are required.
    """

    low: float | None = param(None, allow_inf=True, doc="lowest value that passes")
    high: float | None = param(None, allow_inf=True, doc="highest value that passes")
    select: Mapping[str, Any] = param(parser=_conditions(True), doc="the rows: column -> value or range")
    aggregate: Literal[AGGREGATES] | None = param(None, doc="over the selected rows (default median)")
    kind: Literal[_KIND_NAMES] = param("value", doc="value, trend or difference")
    over: str = param("", doc="trend: the column the value changes over")
    direction: Literal["decreasing", "increasing"] | None = param(None, doc="trend: its direction")
    slack: float | None = param(None, ge=0, doc="trend: how much it may go the other way")
    versus: Mapping[str, Any] | None = param(None, parser=_conditions(True), doc="difference: the other rows")
    by: str = param("", doc="difference: the column the difference is paired by; trend: one trend per value of it")
    evidence: Literal[EVIDENCE] = param(doc="what a pass means")
    reading: str = param("", doc="conditional: the reading(s) it passes under")
    free_parameter: str = param("", doc="calibrated: the parameter chosen to match it")
    tolerance_reason: str = param(doc="why the band is what it is")
    domain: Mapping[str, Any] | None = param(None, parser=_conditions(False), doc="the rows scored")
    domain_reason: str = param("", doc="why the domain")
    count: Literal[COUNTS] = param("headline", doc="headline or method_difference")

    def __post_init__(self):
        self._check_kind()
        self._check_evidence()
        if (self.domain is None) != (not self.domain_reason.strip()):
            raise ConfigError("keys 'domain' and 'domain_reason' go together (a domain needs its reason)")
        clash = sorted(set(self.domain or {}) & (set(self.select) | set(self.versus or {})))
        if clash:
            raise ConfigError(f"key 'domain': column {clash[0]!r} is also in 'select'/'versus'")
        if self.count == "method_difference" and self.kind != "difference":
            raise ConfigError("key 'count': 'method_difference' needs check kind 'difference'")
        if not self.tolerance_reason.strip():
            raise ConfigError("key 'tolerance_reason': state why the band is what it is")

    def _check_kind(self) -> None:
        needs, allows = CHECK_KINDS[self.kind]
        given = {name for name in _KIND_FIELDS if getattr(self, name) not in (None, "")}
        missing = sorted(needs - given)
        if missing:
            raise ConfigError(f"check kind '{self.kind}' needs key {missing[0]!r}")
        extra = sorted(given - allows)
        if extra:
            raise ConfigError(f"key {extra[0]!r} does not apply to check kind '{self.kind}'; "
                              f"it takes: {', '.join(sorted(allows))}")
        low = -math.inf if self.low is None else self.low
        high = math.inf if self.high is None else self.high
        if low > high:
            raise ConfigError(f"low {low} > high {high}")

    def _check_evidence(self) -> None:
        reading, free = self.reading.strip(), self.free_parameter.strip()
        if self.evidence == "conditional":
            ids = [r.strip() for r in reading.split(",") if r.strip()]
            if not ids or not all(re.fullmatch(r"[A-Z]+\d+", r) for r in ids):
                raise ConfigError(f"evidence 'conditional' needs key 'reading': the reading(s) chosen by outcome "
                                  f"that the check passes under, e.g. 'R1' or 'R1, R2'; got {reading!r}")
        elif reading:
            raise ConfigError("key 'reading' applies to evidence 'conditional' only")
        if self.evidence == "calibrated":
            if not free:
                raise ConfigError("evidence 'calibrated' needs key 'free_parameter': the parameter chosen to match "
                                  "the published value (and its value)")
        elif free:
            raise ConfigError("key 'free_parameter' applies to evidence 'calibrated' only")

    def to_check(self) -> Check:
        """The :class:`Check`, the fields not given at their defaults."""
        values = {f.name: getattr(self, f.name) for f in dataclasses.fields(Check)}
        values.update({k: d for k, d in _kind_defaults().items() if values[k] is None})
        values.update(reading=self.reading.strip(), free_parameter=self.free_parameter.strip(),
                      tolerance_reason=self.tolerance_reason.strip())
        return Check(**values)


def _check_list(value: Any, where: str, key: str) -> tuple[Mapping, ...]:
    if not isinstance(value or [], list) or not all(isinstance(c, Mapping) for c in value or []):
        raise error(where, key, f"expected a list of checks, got {value!r}")
    return tuple(value or ())


@dataclasses.dataclass(frozen=True)
class PublishedFile:
    """A ``published.yaml``: the study, the source and the checks."""

    study: str = param(doc="the study's id")
    source: str = param(doc="the paper the values are from")
    checks: tuple[Mapping, ...] = param(parser=_check_list, doc="the checks (:class:`CheckEntry`)")


def load_checks(path: Path, parts: Mapping[str, Any]) -> tuple[Check, ...]:
    """The checks of published-values file ``path`` on ``parts``, strictly (every error of the file at once)."""
    spec = parse(PublishedFile, load_yaml(path), str(path), document=True)
    problems, out, seen = Problems(), [], set()
    for i, c in enumerate(spec.checks):
        where = f"{path}: check {c['id']}" if "id" in c else f"{path}: checks[{i}]"
        with problems.catch():
            check = parse(CheckEntry, c, where).to_check()
            if check.id in seen:
                raise error(where, "id", f"duplicate check id {check.id!r}")
            seen.add(check.id)
            if check.part not in parts:
                raise error(where, "part", f"unknown part {check.part!r}; parts: {', '.join(parts)}")
            out.append(check)
    problems.raise_all()
    for check in out:
        with problems.catch():
            _check_notes(check, seen, f"{path}: check {check.id}")
    problems.raise_all()
    return tuple(out)


#: the note fields whose figures come from the rows
NOTE_FIELDS = ("if_missed", "if_missed_below", "if_missed_above", "cause")


def note_fields(text: str) -> list[tuple[str, str]]:
    """The placeholders of a note: ``(check id or 'value' / 'published', attribute)`` for each ``{...}``."""
    import string

    out = []
    for _, name, _, _ in string.Formatter().parse(text or ""):
        if name is None:
            continue
        head, _, attr = name.partition(".")
        out.append((head, attr))
    return out


def _check_notes(check: Check, ids: set[str], where: str) -> None:
    """Every placeholder of a note names ``value``, ``published`` or a check of the file (``.published``
    the only attribute); one-sided notes only where the band has that side."""
    for field in NOTE_FIELDS:
        try:
            names = note_fields(getattr(check, field))
        except ValueError as exc:
            raise error(where, field, f"not a valid note template ({exc}); write a literal brace as '{{{{'")
        for head, attr in names:
            if head not in ids | {"value", "published"} or attr not in ("", "published"):
                raise error(where, field, f"unknown placeholder {{{head}{'.' + attr if attr else ''}}}: use "
                                          f"{{value}}, {{published}}, {{CHECK-ID}} or {{CHECK-ID.published}}")
    if (check.if_missed_below or check.if_missed_above) and check.kind == "trend":
        raise error(where, "if_missed_below", "a trend has no band below or above: use 'if_missed'")
