"""``jointbench nightly``: run every paper study, compare, report, and exit non-zero on a regression.

Each study of the nightly config is run (recomputed unless ``use_cache``) and recorded in the history as
part of one nightly; each run is compared with the published values (its checks) and with the same
study's run in the previous finished nightly (:mod:`benchmarks.harness.compare`); the pages are written
by :mod:`benchmarks.harness.nightly_pages`. What counts as a regression: :mod:`benchmarks.harness.nightly`.
"""
from __future__ import annotations

from pathlib import Path

from jointbench.benchmarks.harness import outputs
from jointbench.benchmarks.harness.compare import compare_runs
from jointbench.benchmarks.harness.history import History
from jointbench.benchmarks.harness.nightly import NightlyConfig, NightlyResult, StudyOutcome
from jointbench.benchmarks.harness.nightly_pages import write_pages
from jointbench.benchmarks.study import HISTORY_FILE, run_study
from jointbench.core.errors import JointBenchError
from jointbench.core.files import sweep_stale_temps


def run_nightly(config: NightlyConfig, out_root: Path, workers: int | None = None, serial: bool = False,
                progress: bool = True, command: str = "jointbench nightly") -> NightlyResult:
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
            diff = compare_runs(history, prev, run.run_id, config.rules) if prev is not None else None
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
