"""Run a whole study: expand, run cases, write tidy results, comparison, figures and the report.

Outputs in ``results/<study>/``: ``cases.csv`` (tidy rows), ``curves.csv.gz`` (curves behind the
figures), ``comparison.csv`` (one row per published check), ``report.md`` and its PNG figures,
``failures.log`` (tracebacks of failed cases, when any), and ``cache/`` (finished cases).
"""
from __future__ import annotations

import dataclasses
import os
import time
import traceback
from pathlib import Path

import pandas as pd

from benchmarks import backends, figures, report
from benchmarks.config import REPO, Study, load_study
from benchmarks.runner import Cache, CaseResult, code_fingerprint, expand, git_commit, run_cases
from benchmarks.tables import cases_frame, compare, curves_frame


@dataclasses.dataclass
class StudyRun:
    study: Study
    folder: Path
    results: list[CaseResult]
    rows: pd.DataFrame
    comparison: pd.DataFrame

    @property
    def failed(self) -> list[CaseResult]:
        return [r for r in self.results if r.status != "ok"]


def _write(path: Path, write) -> None:
    """Write through a temporary file so an interrupted run never leaves half a file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    write(tmp)
    os.replace(tmp, path)


def run_study(ref: str | Path, parts: list[str] | None = None, out_root: Path | None = None,
              serial: bool = False, workers: int | None = None, use_cache: bool = True,
              progress: bool = True, command: str = "", backend: str | None = None) -> StudyRun:
    """Run study ``ref`` (an id under ``configs/studies`` or a path) and write its outputs.

    With ``parts``, only those parts are run; the outputs still cover every other part whose cases
    are all in the cache for the current code (so ``make westwick2012-fig4`` after ``make
    westwick2012`` rewrites fig4 without dropping the rest of the report).

    With ``backend`` (``jointbench run STUDY --backend mujoco``) every part runs on that simulation
    backend and the outputs go to ``results/<study>/backend-<name>/`` (:mod:`benchmarks.backends`).
    """
    study = load_study(ref)
    cases = expand(study, parts, backend)
    folder = backends.run_folder((out_root or REPO / "results") / study.id, backend)
    cache = Cache(folder / "cache", code_fingerprint(), use_cache)
    t0 = time.perf_counter()
    results = run_cases(cases, cache, workers=workers, serial=serial, progress=progress)
    wall = time.perf_counter() - t0
    n_cached = cache.hits
    run_parts = list(dict.fromkeys(c.part for c in cases))
    from_cache = []
    if parts is not None and use_cache:
        for name in study.parts:
            if name in run_parts:
                continue
            hits = [cache.get(c) for c in expand(study, [name], backend)]
            if all(h is not None for h in hits):
                results += hits
                from_cache.append(name)
    commit = git_commit()
    rows = cases_frame(results, commit)
    curves = curves_frame(results)
    shown = [p for p in study.parts if p in run_parts or p in from_cache]
    comparison = compare(study.checks, rows, set(shown))
    _write(folder / "cases.csv", lambda p: rows.to_csv(p, index=False))
    _write(folder / "curves.csv.gz", lambda p: curves.to_csv(p, index=False, compression="gzip"))
    _write(folder / "comparison.csv", lambda p: comparison.to_csv(p, index=False))
    failed = [r for r in results if r.status != "ok"]
    log = folder / "failures.log"
    if failed:
        _write(log, lambda p: p.write_text("\n\n".join(f"== {r.case.case_id}\n{r.detail or r.error}"
                                                         for r in failed)))
    elif log.exists():
        log.unlink()
    part_reports = {}
    for name in shown:
        part = study.parts[name]
        if part.protocol not in figures.REGISTRY:
            part_reports[name] = None
            continue
        if not any(r.status == "ok" and r.case.part == name for r in results):
            part_reports[name] = "no case of this part succeeded (see Failed cases)"
            continue
        try:
            part_reports[name] = figures.REGISTRY.get(part.protocol)(
                part, rows[rows["part"] == name], curves[curves["part"] == name] if len(curves) else curves,
                folder, study.checks)
        except Exception as exc:  # noqa: BLE001 - a broken plot must not lose the tables
            part_reports[name] = f"{type(exc).__name__}: {exc}"
            traceback.print_exc()
    meta = {"commit": commit, "command": command or f"jointbench run {study.id}", "n_cases": len(cases),
            "n_cached": n_cached, "wall_s": wall, "workers": 1 if serial else (workers or os.cpu_count()),
            "parts": run_parts, "from_cache": from_cache, "folder": folder, "backend": backend}
    text = report.render(study, comparison, part_reports, failed, meta)
    _write(folder / "report.md", lambda p: p.write_text(text))
    return StudyRun(study, folder, results, rows, comparison)
