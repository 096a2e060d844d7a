"""What a run asks of the workers of any executor, and the two ways an executor stops a run.

A worker must run the run's code and numerical libraries: its numbers are cached under the run's keys.
:func:`worker_identity` is what must be equal (the code hash and the key environment of
:mod:`benchmarks.harness.fingerprint`), :func:`identity_problem` says in one line how a worker differs, and
:class:`WorkerMismatch` refuses it. :class:`ExecutorLost` is lost infrastructure (a Dask scheduler gone), not
a failed case. The process pool (:mod:`benchmarks.harness.pool`), the Dask executor
(:mod:`benchmarks.harness.dask_executor`) and the runner (:func:`benchmarks.runner.run_cases`) share them.
"""
from __future__ import annotations

from jointbench.core.errors import JointBenchError

#: seconds one case may run before it is killed and fails "timed out after ..." (a study's
#: ``case_time_limit``, :func:`benchmarks.harness.pool.run_supervised`): ten times the slowest shipped case
DEFAULT_CASE_TIME_LIMIT_S = 600.0


class ExecutorLost(RuntimeError):
    """The executor can no longer run tasks (its Dask scheduler is gone): lost infrastructure, not a failed
    case. The runner stops the run, keeps every finished case and says to run again to resume."""


class WorkerMismatch(JointBenchError, RuntimeError):
    """A worker runs other code or other numerical libraries than the run: its numbers would be cached
    under this code's keys. Refused, in one line."""


def worker_identity() -> dict:
    """What must be equal on every worker of a run: the code hash and the key environment (Python, numpy,
    scipy versions) that cache keys are made of (:mod:`benchmarks.harness.fingerprint`)."""
    from jointbench.benchmarks.harness.fingerprint import code_hash, key_environment

    return {"code": code_hash(), "env": dict(key_environment())}


def identity_problem(run: dict, worker: dict, who: str) -> str | None:
    """One line saying how ``worker``'s identity differs from the run's, or None."""
    if worker.get("code") != run.get("code"):
        return (f"{who} runs other code (code hash {worker.get('code')}, the run's {run.get('code')}): install "
                f"the same checkout on every worker")
    theirs, mine = worker.get("env") or {}, run.get("env") or {}
    diff = [f"{k} {theirs.get(k)} (the run's {mine.get(k)})" for k in sorted(set(mine) | set(theirs))
            if theirs.get(k) != mine.get(k)]
    if diff:
        return (f"{who} runs other library versions: {', '.join(diff)}; install the same versions on every "
                f"worker (they change the numbers)")
    return None
