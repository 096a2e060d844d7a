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
import math
from pathlib import Path

from jointbench.benchmarks.config import _check_keys, _load_yaml
from jointbench.benchmarks.locate import CONFIGS, STUDIES, STUDY_FILE, study_ids
from jointbench.benchmarks.harness import fingerprint
from jointbench.benchmarks.harness import outputs
from jointbench.benchmarks.harness.diff import Rules, RunDiff, Threshold, diff_runs
from jointbench.benchmarks.harness.history import History
from jointbench.benchmarks.harness.nightly_pages import write_pages
from jointbench.core.errors import ConfigError, JointBenchError
from jointbench.core.files import sweep_stale_temps

DEFAULT_CONFIG = CONFIGS / "nightly.yaml"
_KEYS = {"studies": True, "exclude": False, "use_cache": False, "thresholds": True, "timing": False,
         "key_checks": False, "wall_clock": False}
_TIMING_KEYS = {"grow_factor": False, "min_seconds": False, "regression": False}
_THRESHOLD_KEYS = {"metric": True, "abs": False, "rel": False}


@dataclasses.dataclass(frozen=True)
class NightlyConfig:
    path: Path
    studies: tuple[str, ...]
    use_cache: bool
    rules: Rules
    key_checks: dict[str, tuple[str, ...]]
    text_hash: str


def _number(v, where: str, key: str, low: float = 0.0) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < low:
        raise ConfigError(f"{where}: key {key!r}: expected a number >= {low:g}, got {v!r}")
    return float(v)


def load_config(path: Path = DEFAULT_CONFIG) -> NightlyConfig:
    """Parse the nightly config strictly (every error names the file and key)."""
    path = Path(path)
    data = _load_yaml(path)
    _check_keys(data, _KEYS, str(path))
    studies = data["studies"]
    exclude = data.get("exclude") or []
    if not isinstance(exclude, list) or not all(isinstance(s, str) for s in exclude):
        raise ConfigError(f"{path}: key 'exclude': expected a list of study ids (left out of 'all')")
    if studies == "all":
        studies = [s for s in study_ids() if s not in exclude]
    if not isinstance(studies, list) or not studies or not all(isinstance(s, str) and s for s in studies):
        raise ConfigError(f"{path}: key 'studies': expected 'all' or a non-empty list of study ids or paths")
    if len(set(studies)) != len(studies):
        raise ConfigError(f"{path}: key 'studies': a study is listed twice")
    resolved = []
    for s in studies:          # a relative path is relative to the nightly config
        p = Path(s)
        resolved.append(str(p if p.is_absolute() or not p.suffix else (path.parent / p).resolve()))
        where = Path(resolved[-1]) if p.suffix else STUDIES / s / STUDY_FILE
        if not where.is_file():    # a config error before anything runs, not a study that 'could not run'
            known = ", ".join(study_ids())
            raise ConfigError(f"{path}: key 'studies': no study {s!r} ({where} not found); known: {known}")
    use_cache = data.get("use_cache", False)
    if not isinstance(use_cache, bool):
        raise ConfigError(f"{path}: key 'use_cache': expected true or false, got {use_cache!r}")
    rules = data["thresholds"]
    if not isinstance(rules, list) or not rules:
        raise ConfigError(f"{path}: key 'thresholds': expected a non-empty list of {{metric, abs, rel}}")
    thresholds = []
    for i, r in enumerate(rules):
        where = f"{path}: thresholds[{i}]"
        _check_keys(r, _THRESHOLD_KEYS, where)
        if not isinstance(r["metric"], str) or not r["metric"]:
            raise ConfigError(f"{where}: key 'metric': expected a name pattern such as 'vaf*'")
        if "abs" not in r and "rel" not in r:
            raise ConfigError(f"{where}: give 'abs', 'rel' or both")
        thresholds.append(Threshold(r["metric"], _number(r.get("abs", 0.0), where, "abs"),
                                    _number(r.get("rel", 0.0), where, "rel")))
    if thresholds[-1].metric != "*":
        raise ConfigError(f"{path}: key 'thresholds': the last rule must be metric '*' (the default)")
    timing = data.get("timing") or {}
    _check_keys(timing, _TIMING_KEYS, f"{path}: timing")
    regression = timing.get("regression", False)
    if not isinstance(regression, bool):
        raise ConfigError(f"{path}: timing: key 'regression': expected true or false, got {regression!r}")
    wall_clock = data.get("wall_clock", list(Rules.wall_clock))
    if not isinstance(wall_clock, list) or not all(isinstance(w, str) and w for w in wall_clock):
        raise ConfigError(f"{path}: key 'wall_clock': expected a list of metric names (patterns) that are "
                          f"wall-clock times, e.g. [fit_time_s]")
    key_checks = data.get("key_checks") or {}
    if not isinstance(key_checks, dict) or not all(isinstance(v, list) and all(isinstance(c, str) for c in v)
                                                   for v in key_checks.values()):
        raise ConfigError(f"{path}: key 'key_checks': expected a mapping study -> list of check ids")
    return NightlyConfig(
        path=path, studies=tuple(resolved), use_cache=use_cache,
        rules=Rules(tuple(thresholds), _number(timing.get("grow_factor", 1.5), f"{path}: timing", "grow_factor", 1.0),
                    _number(timing.get("min_seconds", 5.0), f"{path}: timing", "min_seconds"), regression,
                    tuple(wall_clock)),
        key_checks={str(k): tuple(v) for k, v in key_checks.items()},
        text_hash=fingerprint.sha(data, 16))


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
