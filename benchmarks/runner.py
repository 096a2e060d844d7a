"""Expand a study into independent cases and run them (any executor, verified cache, nothing lost).

A case is a pure function of its specification and seed (:mod:`benchmarks.harness.case`). Cases are
JSON-serialisable and cached by a key of everything that can change their numbers
(:mod:`benchmarks.harness.cache`), so a crash or Ctrl-C loses no finished case and the next run resumes.
"""
from __future__ import annotations

import concurrent.futures as cf
import json
import math
import os
import queue
import sys
from typing import Callable, Iterable

from jointbench.benchmarks import protocols
from jointbench.benchmarks.config import Part, Study
from jointbench.benchmarks.harness.cache import Cache
from jointbench.benchmarks.harness.case import Case, CaseResult, parse_inputs, run_case, run_group
from jointbench.benchmarks.harness.pool import InlineExecutor, WorkerPool, run_task
from jointbench.benchmarks.harness.workers import ExecutorLost, WorkerMismatch
from jointbench.core.errors import ConfigError
from jointbench.core.schema import parse

__all__ = ["Case", "CaseResult", "Cache", "RunInterrupted", "expand", "expand_study", "group_cases", "run_case",
           "run_cases"]

#: most cases one run may expand to (a typo in a sweep or seed count must not exhaust the memory)
MAX_CASES = 1_000_000


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM during :func:`run_cases`; ``finished`` holds every case finished (and cached)
    before it, ``total`` the number asked for."""

    def __init__(self, finished: list[CaseResult], total: int, reason: str = "interrupted"):
        super().__init__(reason)
        self.finished, self.total, self.reason = finished, total, reason


class InfrastructureLost(RunInterrupted):
    """The executor was lost during :func:`run_cases` (a Dask scheduler): no case failed, the run stopped;
    ``reason`` is the one line to show ("lost the scheduler at ADDRESS after N of M cases; run again to
    resume"). Exit status :attr:`exit_code` (EX_TEMPFAIL: a temporary failure, worth running again)."""

    exit_code = 75


class _Lost(KeyboardInterrupt):
    """Raised inside the runner's loop to stop it like Ctrl-C does (the cleanup is the same)."""

    def __init__(self, what: str):
        super().__init__(what)
        self.what = what


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


def expand_study(study: Study, parts: Iterable[str] | None = None,
                 backend: str | None = None) -> tuple[list[Case], list[dict]]:
    """All cases of the selected parts, validated up front (config errors surface before any run), and
    the combinations of comparison grids that are skipped, with their reasons (:mod:`benchmarks.compare.grid`).
    ``backend`` (e.g. ``jointbench run --backend mujoco``) replaces every part's own backend."""
    from jointbench.benchmarks.compare.grid import expand_grid

    names = list(study.parts) if parts is None else list(dict.fromkeys(parts))
    unknown = [p for p in names if p not in study.parts]
    if unknown:
        raise ConfigError(f"{study.path}: unknown part {unknown[0]!r}; parts: {', '.join(study.parts)}")
    total = sum((study.parts[n].grid.size() if study.parts[n].grid is not None else
                 math.prod(len(v) for v in study.parts[n].sweep.values())) * len(study.parts[n].seeds)
                for n in names)
    if total > MAX_CASES:
        raise ConfigError(f"{study.path}: the selected parts expand to {total} cases, more than the "
                          f"{MAX_CASES} a run may hold; lower the seeds or the sweeps")
    cases, skipped = [], []
    for name in names:
        part: Part = study.parts[name]
        if part.grid is not None:
            specs, skip = expand_grid(study.id, part, backend)
            got = [Case(**spec) for spec in specs]
            cases += got
            skipped += [{"part": name, **s} for s in skip]
            if got:
                parse_inputs(got[0])       # the protocol's parameters, once per part
            continue
        for combo in part.grid_combinations():
            for seed in part.seeds:
                cases.append(Case(study=study.id, part=name, protocol=part.protocol, params=dict(part.params),
                                  sweep=combo, experiment=part.experiment, estimators=dict(part.estimators),
                                  seed=seed, where=part.where, backend=backend or part.backend))
        _, _, exp, ests = parse_inputs(cases[-1])   # validate once per part
        _check_estimators(part, exp, ests)
    seen: dict = {}
    for c in cases:                  # two cases under one id would be one row of the history twice
        if (c.part, c.case_id) in seen:
            raise ConfigError(f"{c.where}: two cases are named {c.case_id!r} (a sweep or grid value given twice, "
                              f"e.g. [1, '1']); list each value once")
        seen[(c.part, c.case_id)] = c
    return cases, skipped


def expand(study: Study, parts: Iterable[str] | None = None, backend: str | None = None) -> list[Case]:
    """All cases of the selected parts (:func:`expand_study` without the skipped grid combinations)."""
    return expand_study(study, parts, backend)[0]


#: the experiment keys that do not change a simulated response (sims.reuse.RESPONSE_FIELDS are the rest)
_NOT_RESPONSE = ("sensors", "acquisition")


def share_key(case: Case, _memo: dict | None = None):
    """Cases with equal keys may share simulated responses and are scheduled together (None: alone).

    The key is the protocol, the case's experiment without its sensors and acquisition, the backend, the
    seed and what the protocol's ``share`` says of its parameters (:class:`benchmarks.protocols.Protocol`).
    It only groups: which responses are equal is decided when they are simulated (:mod:`sims.reuse`)."""
    proto = protocols.REGISTRY.get(case.protocol)
    if proto.share is None or case.experiment is None:
        return None
    memo = {} if _memo is None else _memo
    exp = memo.get(id(case.experiment))
    if exp is None:
        exp = json.dumps({k: v for k, v in case.experiment.items() if k not in _NOT_RESPONSE}, sort_keys=True,
                         default=str)
        memo[id(case.experiment)] = exp
    params = parse(proto.Params, {**case.params, **case.sweep}, f"{case.where}: params")
    return (case.protocol, exp, case.backend, case.seed, json.dumps(proto.share(params), sort_keys=True, default=str))


def group_cases(cases: list[Case], indices: Iterable[int] | None = None) -> list[list[int]]:
    """The indices of ``cases`` (or of ``indices`` among them) in groups of equal :func:`share_key`, each
    group in case order, the groups in the order of their first case."""
    groups: dict = {}
    memo: dict = {}
    for i in (range(len(cases)) if indices is None else indices):
        key = share_key(cases[i], memo)
        groups.setdefault(("alone", i) if key is None else key, []).append(i)
    return list(groups.values())


def _plugin_modules(cases: list[Case]) -> dict:
    """``{module: [folder, {estimator: hash}]}`` of the plugins the cases' estimators come from (what every
    worker must import, :func:`benchmarks.harness.pool.run_task`); empty for built-in estimators only."""
    from jointbench.benchmarks.harness.fingerprint import plugin_hash, plugin_requirements

    names = sorted({n for c in cases for n in c.estimators})
    hashes = plugin_hash(names)
    out: dict = {}
    for name in hashes:
        module, folder = next(iter(plugin_requirements([name]).items()))
        out.setdefault(module, [folder, {}])[1][name] = hashes[name]
    return out


def _progress(total: int, enabled: bool):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, unit="case", file=sys.stderr, dynamic_ncols=True)


def _outcomes(fut, cases: list[Case]) -> list[CaseResult]:
    """The results of a finished task (a group of cases); when the task itself failed (a worker killed by
    the OS, a worker running other code), every case of it fails with that error."""
    try:
        return fut.result()
    except Exception as exc:  # noqa: BLE001 - e.g. a worker killed by the OS
        return [CaseResult(c, "failed", [], [], 0.0, error=f"{type(exc).__name__}: {exc}") for c in cases]


def _stop(executor) -> None:
    terminate = getattr(executor, "terminate_workers", None)
    if callable(terminate):
        terminate()
    else:
        executor.shutdown(wait=False, cancel_futures=True)


def run_cases(cases: list[Case], cache: Cache, workers: int | None = None, serial: bool = False,
              progress: bool = True, on_result: Callable[[CaseResult], None] | None = None,
              executor: cf.Executor | None = None, info: dict | None = None) -> list[CaseResult]:
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
        A future failing with :class:`~benchmarks.harness.workers.ExecutorLost` (a lost Dask scheduler)
        stops the run (:class:`InfrastructureLost`); one failing with
        :class:`~benchmarks.harness.workers.WorkerMismatch` (a worker running other code) stops it with
        that error. Any other failure of a task fails its cases.
    info
        Filled with ``workers``: what the cases ran on (for the report), e.g. ``2 worker processes``.

    Raises
    ------
    RunInterrupted
        On Ctrl-C or SIGTERM: pending cases are cancelled, the workers terminated, and every case that
        finished is stored before this is raised (within about a second).
    InfrastructureLost
        The executor was lost; as on Ctrl-C every finished case is kept (the next run resumes).
    WorkerMismatch
        A worker runs other code or libraries (one line); finished cases are kept.
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
    tasks = group_cases(cases, todo)
    own = executor is None
    limits = None
    code = None
    ran_on = "no worker (every case from the cache)" if not tasks else ""
    if own and (serial or workers == 1 or len(tasks) <= 1):
        from threadpoolctl import threadpool_limits

        executor, capacity = InlineExecutor(), 1
        limits = threadpool_limits(limits=1)     # as in the workers: same BLAS reductions, same numbers
        ran_on = ran_on or "1 process (serial)"
    elif own:
        executor = WorkerPool(min(workers, len(tasks)))
        capacity = 2 * min(workers, len(tasks))
        ran_on = f"{min(workers, len(tasks))} worker processes"
    else:
        capacity = 2 * (getattr(executor, "_max_workers", None) or workers)
    outside = None
    extra: tuple = ()
    if not isinstance(executor, InlineExecutor):
        from jointbench.benchmarks.harness.fingerprint import code_hash, key_environment

        code = code_hash()
        outside = _plugin_modules([cases[i] for i in todo])
        extra = (dict(key_environment()), os.path.abspath(cache.folder) if cache.enabled and
                 getattr(executor, "stores_on_worker", False) else None)   # absolute: a worker has its own cwd
    done_q: queue.SimpleQueue = queue.SimpleQueue()
    inflight: dict = {}
    pending = iter(tasks)
    try:
        while True:
            while len(inflight) < capacity:
                group = next(pending, None)
                if group is None:
                    break
                batch = [cases[i] for i in group]
                fut = (executor.submit(run_group, batch) if code is None else
                       executor.submit(run_task, batch, code, *extra, outside))
                inflight[fut] = group
                fut.add_done_callback(done_q.put)
            if not inflight:
                break
            try:
                fut = done_q.get(timeout=0.25)
            except queue.Empty:
                continue
            group = inflight.pop(fut)
            error = None if fut.cancelled() else fut.exception()
            if isinstance(error, ExecutorLost):
                raise _Lost(str(error))
            if isinstance(error, WorkerMismatch):
                raise error
            for i, res in zip(group, _outcomes(fut, [cases[i] for i in group])):
                finish(i, res)
    except KeyboardInterrupt as exc:
        _stop(executor)
        try:                  # keep every finished case: those not yet stored, those done meanwhile
            for i, res in list(results.items()):
                if i not in stored and not res.cached:
                    cache.put(res)
            for fut, group in list(inflight.items()):   # a result, not the error of a terminated worker
                if fut.done() and not fut.cancelled() and fut.exception() is None:
                    for i, res in zip(group, fut.result()):
                        if i not in results:
                            finish(i, res)
        except KeyboardInterrupt:
            pass
        if bar is not None:
            bar.close()
        finished = [results[i] for i in sorted(results)]
        if isinstance(exc, _Lost):   # count the cases the workers stored themselves (groups cut short)
            from jointbench.benchmarks.harness.cache import case_key

            kept = len(finished) + sum(1 for i in todo if i not in results and cache.enabled
                                       and cache.path(case_key(cases[i])).is_file())
            raise InfrastructureLost(finished, len(cases), f"{exc.what} after {kept} of {len(cases)} "
                                     "cases; run again to resume") from None
        raise RunInterrupted(finished, len(cases), getattr(exc, "reason", "interrupted")) from exc
    except BaseException:
        _stop(executor)
        if bar is not None:
            bar.close()
        raise
    finally:
        if limits is not None:
            limits.restore_original_limits()
    if info is not None:
        describe = getattr(executor, "describe", None)
        info["workers"] = ran_on or (describe() if callable(describe) else f"{capacity // 2} worker(s)")
    if own:
        executor.shutdown(wait=True)
    if bar is not None:
        bar.close()
    return [results[i] for i in range(len(cases))]
