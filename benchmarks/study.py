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
import gc
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
from jointbench.benchmarks.harness.cache import Cache
from jointbench.benchmarks.harness.history import History
from jointbench.benchmarks.runner import CaseResult, RunInterrupted, expand, expand_study, group_cases, run_cases
from jointbench.benchmarks.tables import cases_frame, curves_frame
from jointbench.benchmarks.checks import judge, swap_survival
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
        return [r for r in self.results if r.status != "ok"]



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
            out[name] = "no case of this part succeeded (see Failed cases)"
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
        todo = [c for c in mine if not (cache.enabled and cache.read and cache.path(cache.key(c)).is_file())]
        if not todo:
            continue
        seconds = estimate_seconds(todo, group_cases(todo))
        n_workers = max(1, workers or os.cpu_count() or 1)
        limit = budget_minutes if budget_minutes is not None else part.grid.budget_minutes
        if not limit > 0:                 # NaN compares false with everything: it must not skip the check
            raise ConfigError(f"--budget: expected minutes > 0, got {limit!r}")
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


def _frozen(run):
    """``run`` with the objects that live through it kept out of the garbage collector's full passes.

    What exists when the run starts (the imports) and, frozen again once every case result is in, the
    results (more than a million containers from the cache's JSON for xu1998) are frozen
    (:func:`gc.freeze`) until it ends: each full collection would otherwise walk all of them again while
    the tables, figures and report are made (2-3 per run, 0.1-0.5 CPU-s a study; in a study forked side by
    side it also touched every page shared with the parent; issue 22). Garbage is collected as before."""
    @functools.wraps(run)
    def frozen(*args, **kwargs):
        gc.freeze()
        try:
            return run(*args, **kwargs)
        finally:
            gc.unfreeze()
    return frozen


@_frozen
def run_study(ref: str | Path, parts: list[str] | None = None, out_root: Path | None = None,
              serial: bool = False, workers: int | None = None, use_cache: bool = True,
              progress: bool = True, command: str = "", kind: str = "run", nightly_id: int | None = None,
              read_cache: bool = True, executor=None, backend: str | None = None,
              overrides=(), budget_minutes: float | None = None, confirm: bool = False) -> StudyRun:
    """Run study ``ref`` (a shipped study's id, a study file or a folder holding one), write its outputs,
    record the run.

    With ``parts``, only those parts are run; the outputs still cover every other part whose cases
    are all in the cache for the current code (so ``make westwick2012-fig4`` after ``make
    westwick2012`` rewrites fig4 without dropping the rest of the report). ``read_cache=False``
    recomputes every case but still stores the results (the nightly run does this).

    With ``backend`` (``jointbench run STUDY --backend mujoco``) every part runs on that simulation
    backend and the outputs go to ``results/<study>/backend-<name>/`` (:mod:`benchmarks.backends`); the
    history records the run as ``<study>@<backend>``.

    Raises
    ------
    ConfigError, OutputError
        Bad config or options; results folder not writable (before any case runs).
    RunInterrupted
        Ctrl-C or SIGTERM: the finished cases are cached and recorded in the history (status
        ``interrupted``); ``run_id`` is set on the exception.
    """
    study = load_study(ref, overrides=overrides)
    for part in study.parts.values():
        figure_maker(part)
    cases, skipped = expand_study(study, parts, backend)
    root = results_root(out_root)
    base = outputs.study_folder(root, study.id, study.path)
    if overrides and out_root is None:    # a --set run never replaces the study's own (committed) results
        base = outputs.study_folder(root / outputs.SET_RUNS, outputs.set_folder_name(study.id, overrides), study.path)
    folder = backends.run_folder(base, backend)
    if base.name != study.id:
        print(f"jointbench: --set without --out: outputs in {folder} (not {root / study.id}; --out DIR to choose)",
              file=sys.stderr)
    cache_dir = root / CACHE_FOLDER
    outputs.ensure_writable(root, folder, cache_dir)
    for f in (folder, root):
        sweep_stale_temps(f)
    sweep_stale_temps(cache_dir, recursive=True)
    cache = Cache(cache_dir, enabled=use_cache, read=read_cache)
    check_budget(study, cases, skipped, cache, workers if not serial else 1, budget_minutes, confirm)
    history = History(root / HISTORY_FILE)
    run_parts = list(dict.fromkeys(c.part for c in cases))
    n_workers = 1 if serial else (workers or os.cpu_count() or 1)
    run_id = history.begin_run(study.id if backend is None else f"{study.id}@{backend}", run_parts, config_hash(study),
                               len(cases), kind=kind,
                               nightly_id=nightly_id, command=command or f"jointbench run {study.id}",
                               workers=n_workers)
    done = [0, time.monotonic()]

    def on_result(_res: CaseResult) -> None:
        done[0] += 1
        if time.monotonic() - done[1] > PROGRESS_EVERY_S:
            done[1] = time.monotonic()
            history.progress(run_id, done[0])

    keys = {c.case_id: cache.key(c) for c in cases}
    check_metrics = {c.id: str(c.select.get("metric", "")) for c in study.checks}
    t0 = time.perf_counter()
    ran: dict = {}
    try:
        results = run_cases(cases, cache, workers=workers, serial=serial, progress=progress,
                            on_result=on_result, executor=executor, info=ran)
    except RunInterrupted as exc:
        history.finish_run(run_id, "interrupted", exc.finished, keys, wall_s=time.perf_counter() - t0,
                           error=exc.reason)
        exc.run_id = run_id
        raise
    except BaseException as exc:
        history.finish_run(run_id, "error", [], keys, wall_s=time.perf_counter() - t0,
                           error=f"{type(exc).__name__}: {exc}")
        raise
    wall = time.perf_counter() - t0
    gc.freeze()                       # the results too (see _frozen)
    n_cached = cache.hits
    from_cache = []
    if parts is not None and use_cache and read_cache:
        for name in study.parts:
            if name in run_parts:
                continue
            extra = expand(study, [name], backend)
            hits = [cache.get(c) for c in extra]
            if all(h is not None for h in hits):
                results += hits
                keys.update({c.case_id: cache.key(c) for c in extra})
                from_cache.append(name)
    commit = fingerprint.git_commit()
    rows = cases_frame(results, commit)
    if skipped:
        from jointbench.benchmarks.compare.grid import skipped_rows

        rows = pd.concat([rows, pd.DataFrame(skipped_rows(study.id, skipped)).assign(git_commit=commit)],
                         ignore_index=True)
    curves = curves_frame(results)
    shown = [p for p in study.parts if p in run_parts or p in from_cache]
    comparison = judge(study.checks, rows, set(shown), commit)
    recorded = False
    try:
        with outputs.study_lock(folder, f"run {run_id} (pid {os.getpid()})"):
            # The outputs are one set: written into a staging folder beside them, the run recorded, then
            # moved into place together. A run that fails on the way (a full disk, the history) leaves
            # the last good set as it was (tests/test_outputs_set.py).
            stage = staging_folder(folder)
            try:
                atomic_write(stage / "cases.csv", lambda p: write_csv(rows, p))
                atomic_write(stage / "cases.parquet", lambda p: outputs.write_parquet(rows, p))
                atomic_write(stage / "curves.csv.gz", lambda p: write_csv(curves, p, gzip_level=GZIP_LEVEL))
                atomic_write(stage / "checks.csv", lambda p: write_csv(comparison, p))
                failed = [r for r in results if r.status != "ok"]
                if failed:
                    write_text(stage / "failures.log",
                               "\n\n".join(f"== {r.case.case_id}\n{r.detail or r.error}" for r in failed))
                part_reports = _part_reports(study, shown, results, rows, curves, stage)
                meta = {"commit": commit, "command": command or f"jointbench run {study.id}", "n_cases": len(cases),
                        "n_cached": n_cached, "wall_s": wall, "workers": n_workers, "parts": run_parts,
                        "from_cache": from_cache, "folder": folder, "backend": backend, "stage": stage,
                        "ran_on": ran.get("workers")}
                swap = study.method_swap
                if swap is not None and swap.part in shown:
                    meta["method_swap"] = {**swap_survival(study.checks, rows, swap.part, swap.estimators),
                                           "part": swap.part, "estimators": swap.estimators}
                page = report.page(study, comparison, part_reports, failed, meta)
                report.write(stage, page)
                history.finish_run(run_id, "ok", results, keys, comparison, check_metrics, wall)
                recorded = True
                replace_as_set(folder, stage)
                report.relocate(page, stage, folder)
                if not failed:
                    (folder / "failures.log").unlink(missing_ok=True)
            finally:
                shutil.rmtree(stage, ignore_errors=True)      # what a failed run staged: never moved
    except KeyboardInterrupt as exc:
        if not recorded:
            history.finish_run(run_id, "interrupted", results, keys, comparison, check_metrics, wall,
                               error="interrupted while writing the outputs")
        stop = RunInterrupted(results, len(results), "interrupted while writing the outputs")
        stop.run_id = run_id
        raise stop from exc
    except BaseException as exc:
        if not recorded:
            _record_error(history, run_id, results, keys, exc, wall)
        raise
    history.close()
    return StudyRun(study, folder, results, rows, comparison, run_id, part_reports, wall, root / HISTORY_FILE, page)
