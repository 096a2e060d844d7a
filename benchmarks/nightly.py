"""``jointbench nightly``: run every paper study, check it, diff it against the last nightly, report, and exit
non-zero on a regression. Its config (:func:`load_config`), outcome types and the run (:func:`run_nightly`).

Each study is run afresh (``use_cache: false`` by default: every case is recomputed, so timings are
measured and the cache is not trusted blindly) and recorded in the history as part of one nightly. Each
run is compared with the published values (its checks) and with the same study's run in the previous
finished nightly (:mod:`benchmarks.harness.diff`, thresholds from ``configs/nightly.yaml``). The
report, ``results/nightly/index.html``, leads with what changed; ``history.html`` beside it plots each
study's passing checks and key metrics over the recorded nightlies; ``summary.md`` is the same report as
markdown.

Metrics that are wall-clock times (``wall_clock``, default ``[fit_time_s]``) change on every run: they are
never a drift, whatever the thresholds (a part's compute time is compared under ``timing``).

A regression (exit status 1): a check flipped from pass to miss, a metric drifted beyond its threshold,
a case fails that did not, values went missing, a study could not run, or (when ``timing.regression``
is true) a part's compute time grew beyond ``timing.grow_factor``.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from jointbench.benchmarks.config import load_yaml
from jointbench.benchmarks.locate import CONFIGS, STUDIES, STUDY_FILE, study_ids
from jointbench.benchmarks.harness import fingerprint
from jointbench.benchmarks.harness import outputs
from jointbench.benchmarks.harness.diff import Rules, RunDiff, Threshold, diff_runs
from jointbench.benchmarks.harness.history import History
from jointbench.benchmarks.harness.nightly_pages import write_pages
from jointbench.core.errors import ConfigError, JointBenchError
from jointbench.core.files import sweep_stale_temps
from jointbench.core.schema import error, param, parse

DEFAULT_CONFIG = CONFIGS / "nightly.yaml"


@dataclasses.dataclass(frozen=True)
class NightlyConfig:
    path: Path
    studies: tuple[str, ...]
    use_cache: bool
    rules: Rules
    key_checks: dict[str, tuple[str, ...]]
    text_hash: str


@dataclasses.dataclass(frozen=True)
class _Threshold:
    """One rule of ``thresholds``: a metric drifted when it moved by more than ``abs`` and ``rel``."""

    metric: str = param(doc="a metric name pattern such as 'vaf*' ('*': every other metric)")
    abs: float | None = param(None, ge=0, doc="absolute change allowed")
    rel: float | None = param(None, ge=0, doc="relative change allowed")

    def __post_init__(self):
        if not self.metric:
            raise ConfigError("key 'metric': expected a name pattern such as 'vaf*'")
        if self.abs is None and self.rel is None:
            raise ConfigError("give 'abs', 'rel' or both")


@dataclasses.dataclass(frozen=True)
class _Timing:
    """When a part's compute time counts as grown."""

    grow_factor: float = param(Rules.grow_factor, ge=1, doc="grown when it takes this many times as long")
    min_seconds: float = param(Rules.min_seconds, ge=0, doc="parts faster than this are not compared")
    regression: bool = param(False, doc="a grown compute time is a regression")


def _studies(value: Any, where: str, key: str) -> str | tuple[str, ...]:
    if value == "all":
        return value
    if not isinstance(value, list) or not value or not all(isinstance(s, str) and s for s in value):
        raise error(where, key, "expected 'all' or a non-empty list of study ids or paths")
    if len(set(value)) != len(value):
        raise error(where, key, "a study is listed twice")
    return tuple(value)


@dataclasses.dataclass(frozen=True, kw_only=True)
class NightlyFile:
    """``configs/nightly.yaml`` as written (:func:`load_config`)."""

    studies: str | tuple[str, ...] = param(parser=_studies, doc="'all' or the study ids or paths run")
    exclude: tuple[str, ...] | None = param((), doc="study ids left out of 'all'")
    use_cache: bool = param(False, doc="read the cache (false: every case recomputed)")
    thresholds: tuple[_Threshold, ...] = param(doc="what counts as a drift, the last rule metric '*'")
    timing: _Timing | None = param(default_factory=_Timing, doc="when a compute time counts as grown")
    key_checks: dict[str, tuple[str, ...]] | None = param(None, doc="study -> the check ids shown first")
    wall_clock: tuple[str, ...] = param(Rules.wall_clock, doc="metrics that are wall-clock times (patterns)")

    def __post_init__(self):
        if not self.thresholds:
            raise ConfigError("key 'thresholds': expected a non-empty list of {metric, abs, rel}")
        if self.thresholds[-1].metric != "*":
            raise ConfigError("key 'thresholds': the last rule must be metric '*' (the default)")
        if not all(self.wall_clock):
            raise ConfigError(f"key 'wall_clock': expected a list of metric names (patterns) that are wall-clock "
                              f"times, e.g. [fit_time_s], got {list(self.wall_clock)!r}")


def _resolved_studies(spec: NightlyFile, path: Path) -> tuple[str, ...]:
    """The studies of the nightly: ids, or paths made absolute (a relative path is relative to the config);
    a study that does not exist is a config error before anything runs, not a study that 'could not run'."""
    studies = [s for s in study_ids() if s not in (spec.exclude or ())] if spec.studies == "all" else spec.studies
    resolved = []
    for s in studies:
        p = Path(s)
        resolved.append(str(p if p.is_absolute() or not p.suffix else (path.parent / p).resolve()))
        where = Path(resolved[-1]) if p.suffix else STUDIES / s / STUDY_FILE
        if not where.is_file():
            raise ConfigError(f"{path}: key 'studies': no study {s!r} ({where} not found); "
                              f"known: {', '.join(study_ids())}")
    return tuple(resolved)


def load_config(path: Path = DEFAULT_CONFIG) -> NightlyConfig:
    """Parse the nightly config strictly (every error names the file and key, all of them at once)."""
    path = Path(path)
    data = load_yaml(path)
    spec = parse(NightlyFile, data, str(path), document=True)
    timing = spec.timing or _Timing()
    thresholds = tuple(Threshold(t.metric, t.abs or 0.0, t.rel or 0.0) for t in spec.thresholds)
    return NightlyConfig(
        path=path, studies=_resolved_studies(spec, path), use_cache=spec.use_cache,
        rules=Rules(thresholds, timing.grow_factor, timing.min_seconds, timing.regression, spec.wall_clock),
        key_checks=dict(spec.key_checks or {}), text_hash=fingerprint.sha(data, 16))


@dataclasses.dataclass
class StudyOutcome:
    ref: str
    study: str
    run: object | None = None            # benchmarks.study.StudyRun
    error: str = ""
    previous: int | None = None           # run id compared with
    diff: RunDiff | None = None

    @property
    def regressions(self) -> list[str]:
        if self.error:
            return [f"{self.study}: could not run: {self.error}"]
        failed = self.run.failed and self.diff is None
        fails = [f"{self.study}: {len(self.run.failed)} case(s) failed"] if failed else []
        return fails + (self.diff.regressions if self.diff is not None else [])


@dataclasses.dataclass
class NightlyResult:
    nightly_id: int
    verdict: str                         # regression, ok, baseline
    regressions: list[str]
    outcomes: list[StudyOutcome]
    index: Path
    history_page: Path


def run_nightly(config: NightlyConfig, out_root: Path, workers: int | None = None, serial: bool = False,
                progress: bool = True, command: str = "jointbench nightly") -> NightlyResult:
    """Run every study of ``config`` as one nightly: each recorded in the history, checked, diffed against
    its run in the previous finished nightly, and the pages written (``results/nightly/``)."""
    from jointbench.benchmarks.study import HISTORY_FILE, run_study

    root = Path(out_root)
    site = root / "nightly"
    outputs.ensure_writable(root, site)
    sweep_stale_temps(site)
    history = History(root / HISTORY_FILE)
    nid = history.begin_nightly(config.text_hash)
    outcomes: list[StudyOutcome] = []
    try:
        for ref in config.studies:
            name = Path(ref).stem
            try:
                run = run_study(ref, out_root=root, workers=workers, serial=serial, progress=progress,
                                command=command, kind="nightly", nightly_id=nid, read_cache=config.use_cache)
            except JointBenchError as exc:
                outcomes.append(StudyOutcome(ref, name, error=str(exc)))
                continue
            prev = history.previous_nightly_run(run.study.id, nid)
            diff = diff_runs(history, prev, run.run_id, config.rules) if prev is not None else None
            outcomes.append(StudyOutcome(ref, run.study.id, run, previous=prev, diff=diff))
        regressions = [line for o in outcomes for line in o.regressions]
        baseline = all(o.diff is None for o in outcomes if not o.error)
        verdict = "regression" if regressions else ("baseline" if baseline else "ok")
        index, hist_page = write_pages(history, nid, verdict, regressions, outcomes, config, site, command)
        summary = {"regressions": regressions, "studies": {o.study: (o.run.run_id if o.run else None)
                                                           for o in outcomes}}
        history.finish_nightly(nid, "complete", verdict, summary)
    except KeyboardInterrupt:
        history.finish_nightly(nid, "interrupted", "interrupted", {"studies": [o.study for o in outcomes]})
        raise
    except BaseException as exc:
        history.finish_nightly(nid, "error", "error", {"error": f"{type(exc).__name__}: {exc}"})
        raise
    finally:
        history.close()
    return NightlyResult(nid, verdict, regressions, outcomes, index, hist_page)
