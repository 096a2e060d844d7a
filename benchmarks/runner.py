"""Expand a study into independent cases and run them (any executor, verified cache, nothing lost).

A case is a pure function of its specification and seed (:mod:`benchmarks.harness.case`). Cases are
JSON-serialisable and cached by a key of everything that can change their numbers
(:mod:`benchmarks.harness.cache`), so a crash or Ctrl-C loses no finished case and the next run resumes.
"""
from __future__ import annotations

import concurrent.futures as cf
import dataclasses
import json
import math
import os
import queue
import sys
from typing import Callable, Iterable

from jointbench.benchmarks import protocols
from jointbench.benchmarks.config import Part, Study
from jointbench.benchmarks.harness.cache import Cache, case_key
from jointbench.benchmarks.harness.case import Case, CaseResult, parse_inputs, run_case
from jointbench.benchmarks.harness.pool import (InlineExecutor, WorkerPool, close_case_processes, run_supervised,
                                                run_task)
from jointbench.benchmarks.harness.workers import DEFAULT_CASE_TIME_LIMIT_S, ExecutorLost, WorkerMismatch
from jointbench.core.errors import ConfigError
from jointbench.core.schema import Problems, parse

__all__ = ["Case", "CaseResult", "Cache", "RunInterrupted", "expand", "expand_study", "group_cases", "run_case",
           "run_cases"]

#: failed cases whose reasons :func:`failure_summary` prints (the rest are counted, and all are in failures.log)
FAILURES_SHOWN = 5

#: most fits one run may expand to: cases (combinations x seeds) times the estimators each case fits. Each
#: case is built, checked and keyed before anything runs (about 0.3 ms, more in a grid), so a typo in a sweep
#: or seed count (10^4 combinations x 100 seeds) would spend many minutes there before any refusal; 10^5
#: fits of even a second each are more than a day on a 2-core machine
MAX_FITS = 100_000


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


def failure_summary(failed: Iterable[tuple[str, str]], log: str, shown: int = FAILURES_SHOWN) -> list[str]:
    """The lines that end a run with failed cases: each ``(case id, error)``'s reason on one line (the first
    line of the error, at most 300 characters), the first ``shown`` of them, then "N more in LOG"."""
    failed = list(failed)
    lines = []
    for case_id, error in failed[:shown]:
        first = (str(error).strip().splitlines() or ["(no reason recorded)"])[0]
        lines.append(f"  failed  {case_id}: {first[:300] + ('...' if len(first) > 300 else '')}")
    if len(failed) > shown:
        lines.append(f"  ... {len(failed) - shown} more in {log}")
    return lines


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


def part_size(part: Part) -> tuple[int, int]:
    """(cases, fits) a part expands to, counted before it is expanded: its combinations (of the grid's axes,
    the estimator among them, or of the sweep) times its seeds, and those times the estimators each case
    fits (one in a grid; every estimator of the part in a sweep)."""
    if part.grid is not None:
        cases = part.grid.size() * len(part.seeds)
        return cases, cases
    cases = math.prod(len(v) for v in part.sweep.values()) * len(part.seeds)
    return cases, cases * max(1, len(part.estimators))


def expand_study(study: Study, parts: Iterable[str] | None = None,
                 backend: str | None = None) -> tuple[list[Case], list[dict]]:
    """All cases of the selected parts, validated up front (config errors surface before any run), and
    the combinations of comparison grids that are skipped, with their reasons (:mod:`benchmarks.compare.grid`).
    ``backend`` (e.g. ``jointbench run --backend mujoco``) replaces every part's own backend. The config errors
    of every part are raised at once."""
    names = list(study.parts) if parts is None else list(dict.fromkeys(parts))
    unknown = [p for p in names if p not in study.parts]
    if unknown:
        raise ConfigError(f"{study.path}: unknown part {unknown[0]!r}; parts: {', '.join(study.parts)}")
    sizes = {n: part_size(study.parts[n]) for n in names}
    n_cases, n_fits = sum(c for c, _ in sizes.values()), sum(f for _, f in sizes.values())
    if n_fits > MAX_FITS:
        big = max(sizes, key=lambda n: sizes[n][1])
        raise ConfigError(f"{study.path}: the selected parts expand to {n_cases} cases, {n_fits} fits with their "
                          f"estimators ({big}: {sizes[big][0]} cases, {sizes[big][1]} fits), more than the "
                          f"{MAX_FITS} fits a run may hold; lower the seeds, the sweeps or the grid's axes")
    cases, skipped, problems = [], [], Problems()
    for name in names:               # every part's errors at once
        with problems.catch():
            got, skip = _expand_part(study, name, backend)
            cases += got
            skipped += skip
    problems.raise_all()
    seen: dict = {}
    for c in cases:                  # two cases under one id would be one row of the history twice
        if (c.part, c.case_id) in seen:
            raise ConfigError(f"{c.where}: two cases are named {c.case_id!r} (a sweep or grid value given twice, "
                              f"e.g. [1, '1']); list each value once")
        seen[(c.part, c.case_id)] = c
    return cases, skipped


def _expand_part(study: Study, name: str, backend: str | None) -> tuple[list[Case], list[dict]]:
    """The cases of part ``name`` and its skipped grid combinations, validated (:func:`expand_study`)."""
    from jointbench.benchmarks.compare.grid import expand_grid

    part: Part = study.parts[name]
    if part.grid is not None:
        specs, skip = expand_grid(study.id, part, backend)
        got = [Case(**spec) for spec in specs]
        if got:
            parse_inputs(got[0])       # the protocol's parameters, once per part
        return got, [{"part": name, **s} for s in skip]
    got = [Case(study=study.id, part=name, protocol=part.protocol, params=dict(part.params), sweep=combo,
                experiment=part.experiment, estimators=dict(part.estimators), seed=seed, where=part.where,
                backend=backend or part.backend)
           for combo in part.grid_combinations() for seed in part.seeds]
    _, _, exp, ests = parse_inputs(got[-1])   # validate once per part
    _check_estimators(part, exp, ests)
    return got, []


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


class _Results:
    """The results of one :func:`run_cases` call as they come, by case index: each stored in the cache the
    moment it finishes, passed to ``on_result`` and counted on the progress bar."""

    def __init__(self, cases: list[Case], cache: Cache, on_result: Callable[[CaseResult], None] | None):
        self.cases, self.cache, self.on_result = cases, cache, on_result
        self.by_index: dict[int, CaseResult] = {}
        self.stored: set[int] = set()
        self.bar = None

    def take_cached(self) -> list[int]:
        """Reuse every verified cached result; the indices of the cases still to run."""
        todo = []
        for i, c in enumerate(self.cases):
            hit = self.cache.get(c)
            if hit is not None:
                self.by_index[i] = hit
                if self.on_result:
                    self.on_result(hit)
            else:
                todo.append(i)
        return todo

    def show_progress(self, enabled: bool) -> None:
        """A progress bar on stderr (when ``enabled``), the cached cases already counted."""
        self.bar = _progress(len(self.cases), enabled)
        if self.bar is not None:
            self.bar.update(len(self.by_index))
            self.bar.set_postfix_str(f"{len(self.by_index)} cached")

    def finish(self, i: int, res: CaseResult) -> None:
        """Case ``i`` finished: kept, stored in the cache, reported."""
        self.by_index[i] = res
        self.cache.put(res)
        self.stored.add(i)
        if self.on_result:
            self.on_result(res)
        if self.bar is not None:
            self.bar.update(1)
            if res.status != "ok":
                self.bar.write(f"case {res.case.case_id} {res.status}: {res.error}")

    def keep_finished(self, inflight: dict) -> None:
        """After a stop: store every finished case not yet stored, and those whose task ended meanwhile (a
        result, not the error of a terminated worker). A second Ctrl-C cuts this short."""
        try:
            for i, res in list(self.by_index.items()):
                if i not in self.stored and not res.cached:
                    self.cache.put(res)
            for fut, group in list(inflight.items()):
                if fut.done() and not fut.cancelled() and fut.exception() is None:
                    for i, res in zip(group, fut.result()):
                        if i not in self.by_index:
                            self.finish(i, res)
        except KeyboardInterrupt:
            pass

    def finished(self) -> list[CaseResult]:
        """The results so far, in case order."""
        return [self.by_index[i] for i in sorted(self.by_index)]

    def lost(self, exc: _Lost, todo: list[int]) -> InfrastructureLost:
        """The error of a run whose executor was lost, counting the cases the workers stored themselves
        (groups cut short)."""
        finished, n = self.finished(), len(self.cases)
        kept = len(finished) + sum(1 for i in todo if i not in self.by_index and self.cache.enabled
                                   and self.cache.path(case_key(self.cases[i])).is_file())
        return InfrastructureLost(finished, n, f"{exc.what} after {kept} of {n} cases; run again to resume")

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


@dataclasses.dataclass
class _Slots:
    """Where a run's tasks go: the executor, how many tasks may be in flight at once, what it is (for the
    report; '' to ask the executor), whether the runner made it (and shuts it down) and the BLAS limit of a
    run in this process (restored at the end)."""

    executor: cf.Executor
    capacity: int
    ran_on: str
    own: bool
    limits: object = None

    def restore_blas(self) -> None:
        if self.limits is not None:
            self.limits.restore_original_limits()

    def done(self, info: dict | None) -> None:
        """The run ended well: ``info["workers"]`` says what it ran on; the runner's own executor is shut down."""
        if info is not None:
            describe = getattr(self.executor, "describe", None)
            info["workers"] = self.ran_on or (describe() if callable(describe) else f"{self.capacity // 2} worker(s)")
        if self.own:
            self.executor.shutdown(wait=True)


def _slots(executor: cf.Executor | None, workers: int, serial: bool, n_tasks: int) -> _Slots:
    """The given executor, or the runner's own: this process (``serial``, one worker or one task) or a
    :class:`~benchmarks.harness.pool.WorkerPool` of at most ``workers`` processes."""
    ran_on = "no worker (every case from the cache)" if not n_tasks else ""
    if executor is not None:
        return _Slots(executor, 2 * (getattr(executor, "_max_workers", None) or workers), ran_on, own=False)
    if serial or workers == 1 or n_tasks <= 1:
        from threadpoolctl import threadpool_limits

        limits = threadpool_limits(limits=1)     # as in the workers: same BLAS reductions, same numbers
        return _Slots(InlineExecutor(), 1, ran_on or "1 process (serial)", own=True, limits=limits)
    n = min(workers, n_tasks)
    return _Slots(WorkerPool(n), 2 * n, f"{n} worker processes", own=True)


def _submitter(executor: cf.Executor, cases: list[Case], todo: list[int], cache: Cache,
               time_limit_s: float | None) -> Callable:
    """How a task (a group of cases) is submitted: :func:`~benchmarks.harness.pool.run_supervised` from this
    process; elsewhere :func:`~benchmarks.harness.pool.run_task` with the run's code hash and key environment
    (a worker running other code refuses), the cache folder when the executor's workers store cases
    themselves and the plugins the workers must import. Either way each case runs in a child process within
    ``time_limit_s`` seconds."""
    if isinstance(executor, InlineExecutor):
        key = ("run in this process", id(todo))        # this run's: closed when it ends (run_cases)
        return lambda batch: executor.submit(run_supervised, batch, None, time_limit_s, key)
    from jointbench.benchmarks.harness.fingerprint import code_hash, key_environment

    code = code_hash()
    outside = _plugin_modules([cases[i] for i in todo])
    store = (os.path.abspath(cache.folder) if cache.enabled and getattr(executor, "stores_on_worker", False)
             else None)                          # absolute: a worker has its own cwd
    env = dict(key_environment())
    return lambda batch: executor.submit(run_task, batch, code, env, store, outside, time_limit_s)


def _drive(slots: _Slots, tasks: list[list[int]], submit: Callable, got: _Results, inflight: dict) -> None:
    """Keep up to ``slots.capacity`` tasks in ``inflight`` (future -> case indices) until every task is done,
    finishing each case as its task ends. Polls a queue of done futures every 0.25 s, so Ctrl-C is seen.
    A lost executor stops the run (:class:`_Lost`), a worker running other code raises its
    :class:`~benchmarks.harness.workers.WorkerMismatch`; any other failure of a task fails its cases."""
    done_q: queue.SimpleQueue = queue.SimpleQueue()
    pending = iter(tasks)
    while True:
        while len(inflight) < slots.capacity:
            group = next(pending, None)
            if group is None:
                break
            fut = submit([got.cases[i] for i in group])
            inflight[fut] = group
            fut.add_done_callback(done_q.put)
        if not inflight:
            return
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
        for i, res in zip(group, _outcomes(fut, [got.cases[i] for i in group])):
            got.finish(i, res)


def run_cases(cases: list[Case], cache: Cache, workers: int | None = None, serial: bool = False,
              progress: bool = True, on_result: Callable[[CaseResult], None] | None = None,
              executor: cf.Executor | None = None, info: dict | None = None,
              time_limit_s: float | None = DEFAULT_CASE_TIME_LIMIT_S) -> list[CaseResult]:
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
    time_limit_s
        Seconds one case may run (a study's ``case_time_limit``; None: no limit): every executor runs each
        case in a child process (:func:`~benchmarks.harness.pool.run_supervised`), killed past the limit
        (the case fails "timed out after ..."); a case whose process dies fails with how it died.

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
    got = _Results(cases, cache, on_result)
    todo = got.take_cached()
    got.show_progress(progress)
    tasks = group_cases(cases, todo)
    slots = _slots(executor, workers or os.cpu_count() or 1, serial, len(tasks))
    inflight: dict = {}
    try:
        _drive(slots, tasks, _submitter(slots.executor, cases, todo, cache, time_limit_s), got, inflight)
    except KeyboardInterrupt as exc:
        _stop(slots.executor)
        got.keep_finished(inflight)
        got.close()
        if isinstance(exc, _Lost):
            raise got.lost(exc, todo) from None
        raise RunInterrupted(got.finished(), len(cases), getattr(exc, "reason", "interrupted")) from exc
    except BaseException:
        _stop(slots.executor)
        got.close()
        raise
    finally:
        slots.restore_blas()
        close_case_processes(("run in this process", id(todo)))
    slots.done(info)
    got.close()
    return [got.by_index[i] for i in range(len(cases))]
