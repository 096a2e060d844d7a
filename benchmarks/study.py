"""Run a whole study: expand, run cases, write tidy results, checks, figures and the report, and
record the run in the history.

Outputs in ``results/<study>/`` (``./results`` of the current folder, or ``--out``; a run with ``--set`` and
no ``--out``: ``results/set-runs/<study>-set-<hash>/``, said on stderr): ``cases.csv`` (tidy rows) and
``cases.parquet`` (the same, typed), ``curves.csv.gz`` (curves behind the figures), ``checks.csv``
(one row per published check), ``report.md`` with its PNG figures,
``report.html`` (the same report, self-contained), ``failures.log`` (tracebacks of failed cases, when
any). Beside them, shared by every study:
``results/cache/`` (finished cases, :mod:`benchmarks.harness.cache`) and ``results/history.sqlite``
(every run, :mod:`benchmarks.harness.history`).
"""
from __future__ import annotations

import dataclasses
import functools
import os
import shutil
import sys
import time
import traceback
from pathlib import Path

import pandas as pd

from jointbench.benchmarks import backends, figures, report
from jointbench.benchmarks.config import Study, load_study
from jointbench.benchmarks.harness import fingerprint, outputs
from jointbench.benchmarks.harness.cache import Cache, case_key
from jointbench.benchmarks.harness.history import History
from jointbench.benchmarks.runner import CaseResult, RunInterrupted, expand, expand_study, group_cases, run_cases
from jointbench.benchmarks.tables import cases_frame, curves_frame
from jointbench.benchmarks.checks import judge, swap_survival
from jointbench.core.arguments import positive
from jointbench.core.csv_text import write_csv
from jointbench.core.errors import ConfigError, OutputError
from jointbench.core.files import atomic_write, replace_as_set, staging_folder, sweep_stale_temps, write_text

HISTORY_FILE = "history.sqlite"
CACHE_FOLDER = "cache"
PROGRESS_EVERY_S = 2.0


@dataclasses.dataclass
class StudyRun:
    study: Study
    folder: Path
    results: list[CaseResult]
    rows: pd.DataFrame
    checks: pd.DataFrame             # the study's checks, judged (checks.csv)
    run_id: int | None = None
    part_reports: dict = dataclasses.field(default_factory=dict)
    wall_s: float = 0.0
    history: Path | None = None
    report: object = None            # the report page (benchmarks.harness.pages.Page)

    @property
    def failed(self) -> list[CaseResult]:
        return [r for r in self.results if r.status == "failed"]

    @property
    def refused(self) -> list[CaseResult]:
        """Cases with an estimate the output gate refused (:func:`jointbench.fitting.pipeline.gate`): status
        ``refused``, or ``ok`` with some fits refused and the others kept (:attr:`CaseResult.refusals`)."""
        return [r for r in self.results if r.refusals]



#: curves.csv.gz: gzip level 1 (issue 22: zlib's default 6 took 2.7 times as long, 0.14 CPU-s for xu1998's
#: 16 MB, for a file 13 % smaller; 9 took 1.5 times as long as 6 for 4 % less; the file is not committed); no
#: time stamp or file name in the header (jointbench.core.csv_text.write_csv): the same curves, the same bytes
GZIP_LEVEL = 1


def results_root(out_root: Path | None = None) -> Path:
    """The results folder: ``out_root`` (``--out``), else ``./results`` in the current folder (in a checkout,
    `make` runs from its root: the checkout's results/). Never derived from where the code is installed."""
    return Path(out_root) if out_root is not None else Path.cwd() / "results"


def config_hash(study: Study) -> str:
    """Hash of the study as loaded (parts with their resolved models, checks, readings), without paths."""
    parts = {n: {k: v for k, v in dataclasses.asdict(p).items() if k != "where"} for n, p in study.parts.items()}
    return fingerprint.sha({"id": study.id, "title": study.title, "paper": study.paper, "parts": parts,
                            "checks": [dataclasses.asdict(c) for c in study.checks],
                            "readings": [dataclasses.asdict(r) for r in study.readings]}, 16)


def figure_maker(part) -> str:
    """The name of the part's figure maker: its ``figure`` key, else the maker registered under its
    protocol's name ('' when there is none). An unknown ``figure`` is a one-line config error."""
    if part.figure:
        if part.figure not in figures.REGISTRY:
            raise ConfigError(f"{part.where}: key 'figure': unknown figure maker {part.figure!r}; known: "
                              f"{', '.join(figures.REGISTRY.names())}")
        return part.figure
    return part.protocol if part.protocol in figures.REGISTRY else ""


def _part_reports(study, shown, results, rows, curves, folder) -> dict:
    out = {}
    for name in shown:
        part = study.parts[name]
        maker = figure_maker(part)
        if not maker:
            out[name] = None
            continue
        if not any(r.status == "ok" and r.case.part == name for r in results):
            out[name] = "no case of this part succeeded (see Failed cases and Refused cases)"
            continue
        try:
            out[name] = figures.REGISTRY.get(maker)(
                part, rows[rows["part"] == name], curves[curves["part"] == name] if len(curves) else curves,
                folder, study.checks)
        except OutputError:
            raise
        except OSError as exc:    # a full or read-only disk is not a broken plot: the set is not written
            raise OutputError(f"{folder}: cannot write the figures of part {name}: {exc.strerror or exc}") from None
        except Exception as exc:  # noqa: BLE001 - a broken plot must not lose the tables
            out[name] = f"{type(exc).__name__}: {exc}"
            traceback.print_exc()
    return out


class OverBudget(ConfigError):
    """A comparison grid estimated to take longer than its budget (run again with ``--yes``)."""


def check_budget(study: Study, cases: list, skipped: list, cache: Cache, workers: int | None,
                 budget_minutes: float | None, confirm: bool) -> None:
    """Refuse, before running, a comparison grid estimated over its budget (the part's ``budget``, or
    ``budget_minutes``), saying the case count and the estimate; ``confirm`` (``--yes``) goes on."""
    from jointbench.benchmarks.compare.grid import estimate_seconds

    for name in dict.fromkeys(c.part for c in cases):
        part = study.parts[name]
        if part.grid is None:
            continue
        mine = [c for c in cases if c.part == name]
        todo = [c for c in mine if not (cache.enabled and cache.read and cache.path(case_key(c)).is_file())]
        if not todo:
            continue
        seconds = estimate_seconds(todo, group_cases(todo))
        n_workers = max(1, workers or os.cpu_count() or 1)
        limit = positive(budget_minutes if budget_minutes is not None else part.grid.budget_minutes, "budget",
                         "min")           # NaN too: it compares false with every estimate
        wall = seconds / min(n_workers, len(todo)) / 60
        n_skip = sum(1 for s in skipped if s["part"] == name)
        text = (f"{part.where}: {len(mine)} cases ({len(mine) - len(todo)} cached; {n_skip} combinations "
                f"skipped), estimated {seconds / 60:.0f} CPU-minutes, about {wall:.0f} min on {n_workers} "
                f"worker(s)")
        if wall > limit and not confirm:
            raise OverBudget(f"{text}: more than the {limit:g}-minute budget. Run with --yes to go on, or make "
                             f"the grid smaller (e.g. --set {name}.params.realizations=3, fewer axis values)")
        print(f"jointbench: {text}", file=sys.stderr)


def _record_error(history: History, run_id: int, results: list, keys: dict, exc: BaseException,
                  wall: float) -> None:
    """Record a run that failed after its cases (writing its outputs or its history) as ``error``, with
    its cases when the history takes them; the original error is what the user sees, never a second one
    from the history (a full disk, the very constraint that failed)."""
    error = f"{type(exc).__name__}: {exc}"
    for finished in (results, []):
        try:
            history.finish_run(run_id, "error", finished, keys, wall_s=wall, error=error)
            return
        except Exception:  # noqa: BLE001 - see the docstring
            continue


@dataclasses.dataclass(frozen=True)
class RunOptions:
    """How :func:`run_study` runs a study (``jointbench run``'s options); the defaults are those of a plain
    ``jointbench run STUDY``.

    Attributes
    ----------
    parts
        Only these parts are run (None: all); the outputs still cover every other part whose cases are all
        in the cache for the current code (so ``make westwick2012-fig4`` after ``make westwick2012`` rewrites
        fig4 without dropping the rest of the report).
    out_root
        The results folder (``--out``; None: :func:`results_root`).
    serial, workers, executor
        The cases run in this process, on a pool of ``workers`` processes (None: all cores) or on this
        ``concurrent.futures``-style executor (:func:`benchmarks.runner.run_cases`).
    use_cache, read_cache
        Finished cases are kept in the cache; ``read_cache=False`` recomputes every case but still stores
        the results (the nightly run does this).
    progress
        A progress bar on stderr.
    command, kind, nightly_id
        What the history records: the command (default ``jointbench run <study>``), the kind of run (``run``,
        ``nightly``) and the nightly it belongs to.
    backend
        Every part runs on this simulation backend (``jointbench run STUDY --backend mujoco``) and the outputs
        go to ``results/<study>/backend-<name>/`` (:mod:`benchmarks.backends`); the history records the run
        as ``<study>@<backend>``.
    overrides
        ``PART.KEY=VALUE`` texts (``--set``); without ``out_root`` the outputs go to
        ``results/set-runs/<study>-set-<hash>/``, never over the study's own results.
    budget_minutes, confirm
        The budget of a comparison grid (None: the part's own) and ``--yes`` (:func:`check_budget`).
    case_time_limit_s
        Seconds one case may run before it is killed and fails "timed out after ..." (None: the study's
        ``case_time_limit``, default 600 s; ``math.inf``: no limit).
    """

    parts: list[str] | None = None
    out_root: Path | None = None
    serial: bool = False
    workers: int | None = None
    executor: object = None
    use_cache: bool = True
    read_cache: bool = True
    progress: bool = True
    command: str = ""
    kind: str = "run"
    nightly_id: int | None = None
    backend: str | None = None
    overrides: tuple = ()
    budget_minutes: float | None = None
    confirm: bool = False
    case_time_limit_s: float | None = None


@dataclasses.dataclass
class _Run:
    """A study's run while it is made: what it runs, where it writes, and its row in the history."""

    study: Study
    options: RunOptions
    cases: list
    skipped: list                    # the combinations of comparison grids left out, with their reasons
    root: Path
    folder: Path
    cache: Cache
    history: History | None = None
    run_id: int | None = None
    keys: dict = dataclasses.field(default_factory=dict)      # case id -> cache key, of every case recorded

    @functools.cached_property
    def parts(self) -> list[str]:
        """The parts whose cases this run runs (worked out once: the cases do not change)."""
        return list(dict.fromkeys(c.part for c in self.cases))

    @property
    def command(self) -> str:
        return self.options.command or f"jointbench run {self.study.id}"

    @property
    def n_workers(self) -> int:
        return 1 if self.options.serial else (self.options.workers or os.cpu_count() or 1)


@dataclasses.dataclass
class _Outcome:
    """What a run made, before it is written: every case result (those of the parts taken from the cache
    too), the tidy rows and curves, the judged checks, the parts the report shows and its facts."""

    results: list[CaseResult]
    wall: float
    rows: pd.DataFrame
    curves: pd.DataFrame
    checks: pd.DataFrame
    shown: list[str]
    meta: dict


def _output_folder(study: Study, root: Path, opts: RunOptions) -> Path:
    """``<root>/<study>`` (``backend-<name>/`` in it with a backend); a run with ``--set`` and no ``--out``
    never replaces the study's own (committed) results: ``<root>/set-runs/<study>-set-<hash>/``, said on
    stderr."""
    base = outputs.study_folder(root, study.id, study.path)
    if opts.overrides and opts.out_root is None:
        base = outputs.study_folder(root / outputs.SET_RUNS, outputs.set_folder_name(study.id, opts.overrides),
                                    study.path)
    folder = backends.run_folder(base, opts.backend)
    if base.name != study.id:
        print(f"jointbench: --set without --out: outputs in {folder} (not {root / study.id}; --out DIR to choose)",
              file=sys.stderr)
    return folder


def _prepare(ref: str | Path, opts: RunOptions) -> _Run:
    """Everything that can refuse a run before any case runs: the study loaded and expanded, its figure
    makers known, the folders writable (stale temporary files swept), a grid within its budget."""
    study = load_study(ref, overrides=opts.overrides)
    for part in study.parts.values():
        figure_maker(part)
    from jointbench.benchmarks.compare.skips import missing_extra_lines

    cases, skipped = expand_study(study, opts.parts, opts.backend)
    for line in missing_extra_lines([{**s, "part": study.parts[s["part"]].where} for s in skipped]):
        print(f"jointbench: {line}", file=sys.stderr)      # e.g. a grid's MuJoCo rows on the light install
    root = results_root(opts.out_root)
    folder = _output_folder(study, root, opts)
    cache_dir = root / CACHE_FOLDER
    outputs.ensure_writable(root, folder, cache_dir)
    for f in (folder, root):
        sweep_stale_temps(f)
    sweep_stale_temps(cache_dir, recursive=True)
    cache = Cache(cache_dir, enabled=opts.use_cache, read=opts.read_cache)
    check_budget(study, cases, skipped, cache, opts.workers if not opts.serial else 1, opts.budget_minutes,
                 opts.confirm)
    return _Run(study, opts, cases, skipped, root, folder, cache)


def _begin(run: _Run) -> None:
    """Record the run's start in the history (``run.history``, ``run.run_id``)."""
    study, opts = run.study, run.options
    run.history = History(run.root / HISTORY_FILE)
    run.run_id = run.history.begin_run(study.id if opts.backend is None else f"{study.id}@{opts.backend}",
                                       run.parts, config_hash(study), len(run.cases), kind=opts.kind,
                                       nightly_id=opts.nightly_id, command=run.command, workers=run.n_workers,
                                       plugins=run_plugins(run.cases, run.skipped))


def _run_cases(run: _Run) -> tuple[list[CaseResult], float, str | None]:
    """The results of the run's cases (:func:`benchmarks.runner.run_cases`), the wall time and what they ran
    on; the history's count of finished cases updated every :data:`PROGRESS_EVERY_S`. An interrupted or
    failed run is recorded as such before its error goes on (``run_id`` set on a :class:`RunInterrupted`)."""
    opts = run.options
    done = [0, time.monotonic()]

    def on_result(_res: CaseResult) -> None:
        done[0] += 1
        if time.monotonic() - done[1] > PROGRESS_EVERY_S:
            done[1] = time.monotonic()
            run.history.progress(run.run_id, done[0])

    run.keys = {c.case_id: case_key(c) for c in run.cases}
    t0 = time.perf_counter()
    ran: dict = {}
    try:
        results = run_cases(run.cases, run.cache, workers=opts.workers, serial=opts.serial, progress=opts.progress,
                            on_result=on_result, executor=opts.executor, info=ran,
                            time_limit_s=_time_limit(run))
    except RunInterrupted as exc:
        run.history.finish_run(run.run_id, "interrupted", exc.finished, run.keys, wall_s=time.perf_counter() - t0,
                               error=exc.reason)
        exc.run_id = run.run_id
        raise
    except BaseException as exc:
        run.history.finish_run(run.run_id, "error", [], run.keys, wall_s=time.perf_counter() - t0,
                               error=f"{type(exc).__name__}: {exc}")
        raise
    return results, time.perf_counter() - t0, ran.get("workers")


def _time_limit(run: _Run) -> float | None:
    """Seconds one case of the run may run (None: no limit): the option, else the study's
    ``case_time_limit``."""
    limit = run.options.case_time_limit_s
    limit = run.study.case_time_limit_s if limit is None else limit
    if not limit > 0:                     # NaN compares false: it must not disable the limit unnoticed
        raise ConfigError(f"case_time_limit: expected a time > 0 (or inf for none), got {limit!r}")
    return None if limit == float("inf") else float(limit)


def _cached_parts(run: _Run) -> tuple[list[CaseResult], list[str]]:
    """A run of some parts only: the results of every other part whose cases are all in the cache for the
    current code (their keys added to ``run.keys``), and the names of those parts."""
    opts = run.options
    results: list[CaseResult] = []
    names: list[str] = []
    if opts.parts is None or not (opts.use_cache and opts.read_cache):
        return results, names
    for name in run.study.parts:
        if name in run.parts:
            continue
        extra = expand(run.study, [name], opts.backend)
        hits = [run.cache.get(c) for c in extra]
        if all(h is not None for h in hits):
            results += hits
            run.keys.update({c.case_id: case_key(c) for c in extra})
            names.append(name)
    return results, names


def run_plugins(cases, skipped=()) -> dict[str, str]:
    """The plugin estimators of a run's ``cases`` and ``skipped`` combinations: estimator ->
    ``"<distribution>==<version> <source hash>"`` (:func:`benchmarks.harness.fingerprint.plugin_hash`), for
    the rows, the report and the history."""
    names = {e for c in cases for e in c.estimators} | {s["estimator"] for s in skipped}
    return fingerprint.plugin_hash(names)


def _outcome(run: _Run, results: list[CaseResult], wall: float, ran_on: str | None) -> _Outcome:
    """The tidy rows and curves of the results (and of the parts the cache holds), the checks judged on the
    parts shown, and the facts the report states."""
    n_cached = run.cache.hits
    extra, from_cache = _cached_parts(run)
    results = results + extra
    commit = fingerprint.git_commit()
    plugins = run_plugins([r.case for r in results], run.skipped)
    rows = cases_frame(results, commit, plugins)
    if run.skipped:
        from jointbench.benchmarks.compare.skips import skipped_rows

        skipped = pd.DataFrame(skipped_rows(run.study.id, run.skipped)).assign(git_commit=commit)
        if plugins:
            skipped["plugin"] = skipped["estimator"].map(plugins)
        rows = pd.concat([rows, skipped], ignore_index=True)
    shown = [p for p in run.study.parts if p in run.parts or p in from_cache]
    checks = judge(run.study.checks, rows, set(shown), commit, swap=run.study.method_swap)
    meta = {"commit": commit, "plugins": plugins, "command": run.command, "n_cases": len(run.cases),
            "n_cached": n_cached,
            "wall_s": wall, "workers": run.n_workers, "parts": run.parts, "from_cache": from_cache,
            "folder": run.folder, "backend": run.options.backend, "stage": None, "ran_on": ran_on}
    return _Outcome(results, wall, rows, curves_frame(results), checks, shown, meta)


def _stage(run: _Run, out: _Outcome, stage: Path) -> tuple[dict, object, list[CaseResult]]:
    """Write the outputs into the staging folder ``stage``: the tables, ``failures.log`` (when a case
    failed), the figures and the report; the part reports, the report page and the failed cases."""
    rows, curves, comparison, study = out.rows, out.curves, out.checks, run.study
    atomic_write(stage / "cases.csv", lambda p: write_csv(rows, p))
    atomic_write(stage / "cases.parquet", lambda p: outputs.write_parquet(rows, p))
    atomic_write(stage / "curves.csv.gz", lambda p: write_csv(curves, p, gzip_level=GZIP_LEVEL))
    atomic_write(stage / "checks.csv", lambda p: write_csv(comparison, p))
    failed = [r for r in out.results if r.status == "failed"]
    if failed:
        write_text(stage / "failures.log", "\n\n".join(f"== {r.case.case_id}\n{r.detail or r.error}" for r in failed))
    part_reports = _part_reports(study, out.shown, out.results, rows, curves, stage)
    meta = {**out.meta, "stage": stage, "refused": [r for r in out.results if r.refusals]}
    swap = study.method_swap
    if swap is not None and swap.part in out.shown:
        meta["method_swap"] = {**swap_survival(study.checks, rows, swap.part, swap.estimators),
                               "part": swap.part, "estimators": swap.estimators}
    page = report.page(study, comparison, part_reports, failed, meta)
    report.write(stage, page)
    return part_reports, page, failed


def _write_outputs(run: _Run, out: _Outcome) -> tuple[dict, object]:
    """Write the outputs and record the run: the outputs are one set, written into a staging folder beside
    them, the run recorded, then moved into place together. A run that fails on the way (a full disk, the
    history) leaves the last good set as it was (tests/test_outputs_set.py) and is recorded as interrupted
    or failed; the part reports and the report page."""
    check_metrics = {c.id: str(c.select.get("metric", "")) for c in run.study.checks}
    recorded = False
    try:
        with outputs.study_lock(run.folder, f"run {run.run_id} (pid {os.getpid()})"):
            stage = staging_folder(run.folder)
            try:
                part_reports, page, failed = _stage(run, out, stage)
                run.history.finish_run(run.run_id, "ok", out.results, run.keys, out.checks, check_metrics, out.wall)
                recorded = True
                replace_as_set(run.folder, stage)
                report.relocate(page, stage, run.folder)
                if not failed:
                    (run.folder / "failures.log").unlink(missing_ok=True)
            finally:
                shutil.rmtree(stage, ignore_errors=True)      # what a failed run staged: never moved
    except KeyboardInterrupt as exc:
        if not recorded:
            run.history.finish_run(run.run_id, "interrupted", out.results, run.keys, out.checks, check_metrics,
                                   out.wall, error="interrupted while writing the outputs")
        stop = RunInterrupted(out.results, len(out.results), "interrupted while writing the outputs")
        stop.run_id = run.run_id
        raise stop from exc
    except BaseException as exc:
        if not recorded:
            _record_error(run.history, run.run_id, out.results, run.keys, exc, out.wall)
        raise
    return part_reports, page


def run_study(ref: str | Path, options: RunOptions | None = None, /, **fields) -> StudyRun:
    """Run study ``ref`` (a shipped study's id, a study file or a folder holding one), write its outputs,
    record the run.

    ``options`` (:class:`RunOptions`), or its fields as keywords (``run_study("xu1998", serial=True)``; with
    ``options`` too, they replace its fields).

    Raises
    ------
    ConfigError, OutputError
        Bad config or options; results folder not writable (before any case runs).
    RunInterrupted
        Ctrl-C or SIGTERM: the finished cases are cached and recorded in the history (status
        ``interrupted``); ``run_id`` is set on the exception.
    """
    run = _prepare(ref, dataclasses.replace(options or RunOptions(), **fields))
    _begin(run)
    results, wall, ran_on = _run_cases(run)
    out = _outcome(run, results, wall, ran_on)
    part_reports, page = _write_outputs(run, out)
    run.history.close()
    return StudyRun(run.study, run.folder, out.results, out.rows, out.checks, run.run_id, part_reports, wall,
                    run.root / HISTORY_FILE, page)
