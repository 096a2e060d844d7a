"""Executors that run cases: in this process, or on a pool of worker processes that survive what
schedulers and impatient people do.

:func:`benchmarks.runner.run_cases` takes any ``concurrent.futures``-style executor (``submit`` returning
futures with ``add_done_callback``, ``shutdown``); a pool that can be stopped at once also offers
``terminate_workers()``. :class:`WorkerPool` is the default:

- a worker exits when its parent dies, even by ``kill -9``: on Linux the kernel sends it SIGKILL
  (``prctl(PR_SET_PDEATHSIG)``); everywhere a watchdog thread checks that its parent is still the
  process that started it, twice a second;
- a worker ignores SIGINT: Ctrl-C in a terminal reaches the whole process group, and the parent alone
  decides what to do (keep the finished cases, terminate the workers, return within 2 s);
- a worker uses one BLAS thread (:func:`benchmarks.harness.case.limit_process_to_one_blas_thread`).

A task is a group of cases (:func:`run_task`): cases that share a simulated response run together in one
worker (:func:`benchmarks.harness.case.run_group`). :func:`make_executor` builds the executor a run asks
for: ``process`` (this module's pool, the default), ``serial`` or ``dask``
(:mod:`benchmarks.harness.dask_executor`, a Dask cluster: a local one or the scheduler at an address).
"""
from __future__ import annotations

import concurrent.futures as cf
import ctypes
import ctypes.util
import os
import signal
import sys
import threading
import time

from jointbench.benchmarks.harness.case import limit_process_to_one_blas_thread, run_group
from jointbench.benchmarks.harness.workers import WorkerMismatch, identity_problem, worker_identity
from jointbench.core.errors import ConfigError, argument

#: the executors :func:`make_executor` builds (``jointbench run --executor``)
EXECUTORS = ("process", "serial", "dask")

PR_SET_PDEATHSIG = 1
WATCHDOG_PERIOD_S = 0.5
#: most worker processes per core a run may ask for (``--workers 10000`` is a typo, not a plan: a pool or
#: a local Dask cluster of that size would exhaust the machine before it answered)
MAX_WORKERS_PER_CORE = 4


def _die_with(parent: int) -> None:
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
            libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):
            pass                                   # the watchdog below still works
    if os.getppid() != parent:                     # the parent died before prctl took effect
        os._exit(1)

    def watchdog() -> None:
        while True:
            time.sleep(WATCHDOG_PERIOD_S)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watchdog, name="jointbench-parent-watchdog", daemon=True).start()


def init_worker(parent: int) -> None:
    """Initializer of every pool worker (see the module docstring)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)   # a fork inherits the CLI's SIGTERM handler
    _die_with(parent)
    limit_process_to_one_blas_thread()


class WorkerPool(cf.ProcessPoolExecutor):
    """A process pool whose workers die with the parent, ignore Ctrl-C and can be stopped at once."""

    def __init__(self, max_workers: int):
        super().__init__(max_workers=max_workers, initializer=init_worker, initargs=(os.getpid(),))

    def worker_pids(self) -> list[int]:
        return [p.pid for p in list(getattr(self, "_processes", {}).values()) if p.pid]

    def terminate_workers(self, grace_s: float = 0.5) -> None:
        """Stop now: cancel what has not started, SIGTERM the workers, SIGKILL those still alive
        after ``grace_s``."""
        procs = list(getattr(self, "_processes", {}).values())
        self.shutdown(wait=False, cancel_futures=True)
        for p in procs:
            if p.is_alive():
                p.terminate()
        deadline = time.monotonic() + grace_s
        for p in procs:
            p.join(max(0.0, deadline - time.monotonic()))
            if p.is_alive():
                p.kill()
                p.join(0.5)


class InlineExecutor(cf.Executor):
    """Runs each submitted call at once in this process (``--serial``); futures come back done."""

    def submit(self, fn, /, *args, **kwargs):
        fut: cf.Future = cf.Future()
        try:
            fut.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # noqa: BLE001 - KeyboardInterrupt must reach the caller
            if not isinstance(exc, Exception):
                raise
            fut.set_exception(exc)
        return fut


def _import_plugins(plugins: dict, who: str) -> None:
    """Import the outside modules the cases' estimators come from (a Dask worker has not imported them) and
    refuse when their source differs from the parent's (``{module: [folder, {estimator: hash}]}``)."""
    from jointbench.core import plugins as _plugins
    from jointbench.benchmarks.harness.fingerprint import plugin_hash

    _plugins.ensure({m: folder for m, (folder, _) in plugins.items()})
    for module, (_, hashes) in plugins.items():
        here = plugin_hash(hashes)
        if here != hashes:
            raise WorkerMismatch(f"{who} runs other code of plugin {module} ({here}, the run's {hashes}): install "
                                 f"the same plugin on every worker")


def run_task(cases: list, code_hash: str | None = None, env: dict | None = None,
             cache_dir: str | None = None, plugins: dict | None = None) -> list:
    """What a worker runs: one group of cases (:func:`~benchmarks.harness.case.run_group`) with one BLAS
    thread. ``code_hash`` and ``env`` are the run's: a worker that runs other code or other libraries (a
    remote Dask worker on another checkout) refuses (:class:`WorkerMismatch`), instead of computing
    numbers that would be cached under this code's keys. With ``cache_dir`` (an existing folder on this
    worker: one machine, or a shared file system) each case is stored in the cache as it finishes, so
    nothing finished is lost with the scheduler. ``plugins`` (from
    :func:`~benchmarks.harness.fingerprint.plugin_requirements` and ``plugin_hash``): the outside modules
    the cases' estimators come from, imported here first and refused when their source differs."""
    limit_process_to_one_blas_thread()
    if code_hash is not None:
        here = worker_identity()
        run = {"code": code_hash, "env": env if env is not None else here["env"]}
        problem = identity_problem(run, here, f"worker {os.uname().nodename}:{os.getpid()}")
        if problem:
            raise WorkerMismatch(problem)
    on_result = None
    if cache_dir is not None and os.path.isdir(cache_dir):
        from jointbench.benchmarks.harness.cache import Cache

        cache = Cache(cache_dir, warn=lambda msg: None)

        def on_result(res) -> None:
            try:
                cache.put(res)
            except OSError:        # a full or read-only cache here: the run's own process stores it
                pass
    if plugins:
        _import_plugins(plugins, f"worker {os.uname().nodename}:{os.getpid()}")
    return run_group(cases, on_result)


def check_workers(kind: str, workers: int | None) -> None:
    """Refuse a worker count that would exhaust the machine (one line, before anything starts)."""
    cores = os.cpu_count() or 1
    if workers is not None and kind in ("process", "dask") and workers > MAX_WORKERS_PER_CORE * cores:
        raise ConfigError(f"{argument('workers', workers)}: more than {MAX_WORKERS_PER_CORE} worker processes per "
                          f"core ({MAX_WORKERS_PER_CORE * cores} on this machine's {cores} cores); for more, run "
                          f"`dask worker` processes on other machines and give {argument('scheduler')}")


def make_executor(kind: str, workers: int | None = None, scheduler: str | None = None):
    """The executor ``kind`` of :data:`EXECUTORS` (None for ``process``: the runner makes its own pool,
    sized to the work). ``scheduler`` (dask only): the address of a running Dask scheduler
    (``tcp://host:8786``); without it a local Dask cluster of ``workers`` processes is started."""
    if kind not in EXECUTORS:
        raise ConfigError(f"{argument('executor')}: unknown executor {kind!r}; known: {', '.join(EXECUTORS)}")
    if scheduler is not None and kind != "dask":
        raise ConfigError(f"{argument('scheduler')} applies to {argument('executor', 'dask')}, not {kind!r}")
    check_workers(kind, workers if scheduler is None else None)
    if kind == "serial":
        return InlineExecutor()
    if kind == "dask":
        from jointbench.benchmarks.harness.dask_executor import DaskExecutor

        return DaskExecutor(scheduler=scheduler, workers=workers)
    return None
