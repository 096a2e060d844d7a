"""Expand a study into independent cases and run them (any executor, verified cache, nothing lost).

A case is a pure function of its specification and seed (:mod:`benchmarks.harness.case`). Cases are
JSON-serialisable and cached by a key of everything that can change their numbers
(:mod:`benchmarks.harness.cache`), so a crash or Ctrl-C loses no finished case and the next run resumes.
"""
from __future__ import annotations

import concurrent.futures as cf
import math
import os
import queue
import sys
from typing import Callable, Iterable

from benchmarks.config import Part, Study
from benchmarks.harness.cache import Cache
from benchmarks.harness.case import Case, CaseResult, parse_inputs, run_case
from benchmarks.harness.pool import InlineExecutor, WorkerPool
from jointbench.errors import ConfigError

__all__ = ["Case", "CaseResult", "Cache", "RunInterrupted", "expand", "run_case", "run_cases"]

#: most cases one run may expand to (a typo in a sweep or seed count must not exhaust the memory)
MAX_CASES = 1_000_000


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM during :func:`run_cases`; ``finished`` holds every case finished (and cached)
    before it, ``total`` the number asked for."""

    def __init__(self, finished: list[CaseResult], total: int, reason: str = "interrupted"):
        super().__init__(reason)
        self.finished, self.total, self.reason = finished, total, reason


def _check_estimators(part: Part, experiment, ests: dict) -> None:
    """An estimator that cannot run on the part's perturbation is a config error, not a failed case."""
    if experiment is None:
        return
    for name, est in ests.items():
        supports = getattr(type(est), "supports", None)
        reason = supports(experiment) if callable(supports) else None
        if reason:
            raise ConfigError(f"{part.where}: estimators.{name}: cannot run on this part's experiment: "
                              f"{reason}; remove it from the part or change the perturbation")


def expand(study: Study, parts: Iterable[str] | None = None, backend: str | None = None) -> list[Case]:
    """All cases of the selected parts, validated up front (config errors surface before any run).
    ``backend`` (e.g. ``jointbench run --backend mujoco``) replaces every part's own backend."""
    names = list(study.parts) if parts is None else list(dict.fromkeys(parts))
    unknown = [p for p in names if p not in study.parts]
    if unknown:
        raise ConfigError(f"{study.path}: unknown part {unknown[0]!r}; parts: {', '.join(study.parts)}")
    total = sum(math.prod(len(v) for v in study.parts[n].sweep.values()) * len(study.parts[n].seeds)
                for n in names)
    if total > MAX_CASES:
        raise ConfigError(f"{study.path}: the selected parts expand to {total} cases, more than the "
                          f"{MAX_CASES} a run may hold; lower the seeds or the sweeps")
    cases = []
    for name in names:
        part: Part = study.parts[name]
        for combo in part.grid():
            for seed in part.seeds:
                cases.append(Case(study=study.id, part=name, protocol=part.protocol, params=dict(part.params),
                                  sweep=combo, experiment=part.experiment, estimators=dict(part.estimators),
                                  seed=seed, where=part.where, backend=backend or part.backend))
        _, _, exp, ests = parse_inputs(cases[-1])   # validate once per part
        _check_estimators(part, exp, ests)
    return cases


def _progress(total: int, enabled: bool):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, unit="case", file=sys.stderr, dynamic_ncols=True)


def _outcome(fut, case: Case) -> CaseResult:
    try:
        return fut.result()
    except Exception as exc:  # noqa: BLE001 - e.g. a worker killed by the OS
        return CaseResult(case, "failed", [], [], 0.0, error=f"{type(exc).__name__}: {exc}")


def _stop(executor) -> None:
    terminate = getattr(executor, "terminate_workers", None)
    if callable(terminate):
        terminate()
    else:
        executor.shutdown(wait=False, cancel_futures=True)


def run_cases(cases: list[Case], cache: Cache, workers: int | None = None, serial: bool = False,
              progress: bool = True, on_result: Callable[[CaseResult], None] | None = None,
              executor: cf.Executor | None = None) -> list[CaseResult]:
    """Run cases (verified cached ones are reused); order is preserved.

    Parameters
    ----------
    cases, cache
        What to run and where finished cases are kept (each is stored the moment it finishes).
    workers, serial
        Processes of the default :class:`~benchmarks.harness.pool.WorkerPool` (default: all cores), or
        run in this process.
    on_result
        Called with each result as it finishes (cached ones included), in completion order.
    executor
        Any ``concurrent.futures``-style executor to use instead (``submit`` returning futures with
        ``add_done_callback``; ``terminate_workers()`` when it can stop at once). It is not shut down.

    Raises
    ------
    RunInterrupted
        On Ctrl-C or SIGTERM: pending cases are cancelled, the workers terminated, and every case that
        finished is stored before this is raised (within about a second).
    """
    if workers is not None and workers < 1:
        raise ConfigError(f"workers: need at least 1 process, got {workers}")
    results: dict[int, CaseResult] = {}
    todo = []
    for i, c in enumerate(cases):
        hit = cache.get(c)
        if hit is not None:
            results[i] = hit
            if on_result:
                on_result(hit)
        else:
            todo.append(i)
    bar = _progress(len(cases), progress)
    if bar is not None:
        bar.update(len(results))
        bar.set_postfix_str(f"{len(results)} cached")

    stored: set[int] = set()

    def finish(i: int, res: CaseResult) -> None:
        results[i] = res
        cache.put(res)
        stored.add(i)
        if on_result:
            on_result(res)
        if bar is not None:
            bar.update(1)
            if res.status != "ok":
                bar.write(f"case {res.case.case_id} failed: {res.error}")

    workers = workers or os.cpu_count() or 1
    own = executor is None
    limits = None
    if own and (serial or workers == 1 or len(todo) <= 1):
        from threadpoolctl import threadpool_limits

        executor, capacity = InlineExecutor(), 1
        limits = threadpool_limits(limits=1)     # as in the workers: same BLAS reductions, same numbers
    elif own:
        executor = WorkerPool(min(workers, len(todo)))
        capacity = 2 * min(workers, len(todo))
    else:
        capacity = 2 * (getattr(executor, "_max_workers", None) or workers)
    done_q: queue.SimpleQueue = queue.SimpleQueue()
    inflight: dict = {}
    pending = iter(todo)
    try:
        while True:
            while len(inflight) < capacity:
                i = next(pending, None)
                if i is None:
                    break
                fut = executor.submit(run_case, cases[i])
                inflight[fut] = i
                fut.add_done_callback(done_q.put)
            if not inflight:
                break
            try:
                fut = done_q.get(timeout=0.25)
            except queue.Empty:
                continue
            finish(inflight[fut], _outcome(fut, cases[inflight[fut]]))
            del inflight[fut]
    except KeyboardInterrupt as exc:
        _stop(executor)
        try:                  # keep every finished case: those not yet stored, those done meanwhile
            for i, res in list(results.items()):
                if i not in stored and not res.cached:
                    cache.put(res)
            for fut, i in list(inflight.items()):   # a result, not the error of a terminated worker
                if fut.done() and not fut.cancelled() and fut.exception() is None and i not in results:
                    finish(i, fut.result())
        except KeyboardInterrupt:
            pass
        if bar is not None:
            bar.close()
        raise RunInterrupted([results[i] for i in sorted(results)], len(cases),
                             getattr(exc, "reason", "interrupted")) from exc
    except BaseException:
        _stop(executor)
        if bar is not None:
            bar.close()
        raise
    finally:
        if limits is not None:
            limits.restore_original_limits()
    if own:
        executor.shutdown(wait=True)
    if bar is not None:
        bar.close()
    return [results[i] for i in range(len(cases))]
