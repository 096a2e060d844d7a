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
worker (:func:`benchmarks.harness.case.run_group`). Every executor runs a task's cases in a child process of
its own (:func:`run_supervised`), never in the process that runs the executor: a case that outlives its
time limit (``case_time_limit``, :data:`DEFAULT_CASE_TIME_LIMIT_S`) is killed and fails "timed out after
...", and a case whose process dies (``os._exit`` in a plugin, a crash in compiled code, the OS's
out-of-memory killer) fails with how it died; the other cases of the run go on. :func:`make_executor`
builds the executor a run asks for: ``process`` (this module's pool, the default), ``serial`` or ``dask``
(:mod:`benchmarks.harness.dask_executor`, a Dask cluster: a local one or the scheduler at an address).
"""
from __future__ import annotations

import concurrent.futures as cf
import ctypes
import ctypes.util
import os
import pickle
import select
import signal
import struct
import sys
import threading
import time

from jointbench.benchmarks.harness.case import CaseResult, limit_process_to_one_blas_thread, parse_inputs, run_group
from jointbench.benchmarks.harness.workers import (DEFAULT_CASE_TIME_LIMIT_S, WorkerMismatch, identity_problem,
                                                   worker_identity)
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


_FRAME = struct.Struct("<Q")


def _send(fd: int, obj) -> None:
    """``obj`` pickled onto pipe ``fd`` as one frame (its length, then its bytes)."""
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    view = memoryview(_FRAME.pack(len(data)) + data)
    while view:
        view = view[os.write(fd, view):]


def _read_frame(fd: int, deadline: float = float("inf")) -> bytes | None:
    """One frame of pipe ``fd``; None at end of file; ``TimeoutError`` past ``deadline`` (monotonic)."""
    buf = b""
    need, size = _FRAME.size, None
    while True:
        while len(buf) < need:
            if deadline != float("inf"):
                left = deadline - time.monotonic()
                if left <= 0 or not select.select([fd], [], [], left)[0]:
                    raise TimeoutError
            chunk = os.read(fd, min(need - len(buf), 1 << 20))
            if not chunk:
                return None
            buf += chunk
        if size is not None:
            return buf[_FRAME.size:]
        size = _FRAME.unpack(buf)[0]
        need = _FRAME.size + size


def _serve(tasks_fd: int, results_fd: int, parent: int) -> None:
    """The loop of a case process (:class:`CaseProcess`): read a group of cases, run it
    (:func:`run_group`), send each result as it finishes; until the parent closes the pipe. Leaves with
    ``os._exit``, never back into the caller's stack."""
    code = 0
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)     # Ctrl-C is the parent's to handle
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        _die_with(parent)
        while True:
            frame = _read_frame(tasks_fd)
            if frame is None:
                break
            run_group(pickle.loads(frame), lambda res: _send(results_fd, res))
    except BaseException:  # noqa: BLE001 - whatever happened, this process must not return to the caller
        code = 70
    finally:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            os._exit(code)


def _how_it_ended(pid: int) -> str:
    """How a child that sent no result ended: its exit code or the signal that killed it."""
    _, status = os.waitpid(pid, 0)
    if os.WIFSIGNALED(status):
        sig = os.WTERMSIG(status)
        name = signal.Signals(sig).name if sig in signal.Signals._value2member_map_ else str(sig)
        extra = " (the OS's out-of-memory killer, or kill -9)" if sig == signal.SIGKILL else ""
        return f"killed by {name}{extra}"
    return f"exited with code {os.WEXITSTATUS(status)} (os._exit or a crash in the case's code)"


class CaseProcess:
    """A forked child process that runs groups of cases for this process, one group at a time, and is
    kept for the next group (its imports and compiled kernels stay warm) until a case times out or dies."""

    def __init__(self):
        tasks_r, self.tasks_w = os.pipe()
        self.results_r, results_w = os.pipe()
        parent = os.getpid()
        self.pid = os.fork()
        if self.pid == 0:
            os.close(self.tasks_w)
            os.close(self.results_r)
            _serve(tasks_r, results_w, parent)          # never returns
        os.close(tasks_r)
        os.close(results_w)

    def run(self, cases: list, on_result, time_limit_s: float | None) -> list:
        """The results of ``cases``: every one, or those up to the case that timed out or whose process
        died (that one included, failed; this process is then gone: :attr:`pid` is 0)."""
        got: list = []
        try:
            _send(self.tasks_w, cases)
        except BrokenPipeError:
            return [self._failed_by_death(cases[0], 0.0)]
        while len(got) < len(cases):
            started = time.monotonic()
            try:
                frame = _read_frame(self.results_r, started + (time_limit_s or float("inf")))
            except TimeoutError:
                self.close()
                res = _failed(cases[len(got)], time.monotonic() - started,
                              f"CaseTimeout: timed out after {time_limit_s:g} s (the study's case_time_limit); "
                              f"the case was killed")
            else:
                res = (pickle.loads(frame) if frame is not None
                       else self._failed_by_death(cases[len(got)], time.monotonic() - started))
            got.append(res)
            if on_result is not None:
                on_result(res)
            if not self.pid:
                break
        return got

    def alive(self) -> bool:
        """The process is still running (one forked by a thread that has since ended is not: Linux kills it
        with that thread)."""
        if not self.pid:
            return False
        try:
            done, _ = os.waitpid(self.pid, os.WNOHANG)
        except ChildProcessError:
            done = self.pid
        if done:
            self.pid = 0
            self._close_pipes()
        return not done

    def _failed_by_death(self, case, wall: float) -> CaseResult:
        how = _how_it_ended(self.pid)
        self.pid = 0
        self._close_pipes()
        return _failed(case, wall, f"CaseProcessDied: the case's process {how} before writing its result")

    def _close_pipes(self) -> None:
        for fd in (self.tasks_w, self.results_r):
            try:
                os.close(fd)
            except OSError:
                pass

    def close(self) -> None:
        """Kill the process now (a case timed out, Ctrl-C, the run ended)."""
        if self.pid:
            try:
                os.kill(self.pid, signal.SIGKILL)
                os.waitpid(self.pid, 0)
            except OSError:
                pass
            self.pid = 0
        self._close_pipes()


#: this process's case processes, by what they must share with the cases they run (see run_supervised)
_CASE_PROCESSES: dict = {}
_CASE_PROCESSES_LOCK = threading.Lock()


def run_supervised(cases: list, on_result=None, time_limit_s: float | None = DEFAULT_CASE_TIME_LIMIT_S,
                   key=None) -> list:
    """Run a group of cases (:func:`~benchmarks.harness.case.run_group`) in a :class:`CaseProcess` (a
    forked child of this process), each case within ``time_limit_s`` seconds (None: no limit): a case that
    outlives it is killed and fails with "timed out after ..."; a case whose process ends without its
    result fails with how it ended; the cases after it run in a new case process. ``key``: what the case
    process must share with the cases (the run; with the thread, since a process forked by a thread
    dies with that thread): the same key reuses it, warm. Without ``os.fork`` (Windows) the cases run in
    this process, with no time limit. Never raises for a case; on KeyboardInterrupt the case process is
    killed."""
    if not hasattr(os, "fork"):
        return run_group(cases, on_result)
    key = (key, threading.get_ident())
    with _CASE_PROCESSES_LOCK:
        proc = _CASE_PROCESSES.pop(key, None)
    out: list = []
    try:
        while len(out) < len(cases):
            if proc is None or not proc.alive():
                _import_what_they_use(cases[len(out):])
                proc = CaseProcess()
            out += proc.run(cases[len(out):], on_result, time_limit_s)
    except BaseException:
        if proc is not None:
            proc.close()
        raise
    with _CASE_PROCESSES_LOCK:
        old = _CASE_PROCESSES.pop(key, None)
        _CASE_PROCESSES[key] = proc
    if old is not None:
        old.close()
    return out


def close_case_processes(key=None) -> None:
    """Kill this process's case processes (of ``key`` only, when given): the end of a run in this process."""
    with _CASE_PROCESSES_LOCK:
        keys = [k for k in _CASE_PROCESSES if key is None or k[0] == key]
        procs = [_CASE_PROCESSES.pop(k) for k in keys]
    for proc in procs:
        proc.close()


def _import_what_they_use(cases: list) -> None:
    """Import the modules the cases' protocols and estimators live in (registered lazily) here, before the
    fork, so that each new case process starts with them imported. A case whose inputs do not parse fails
    in its case process, with the error."""
    for case in {(c.protocol, tuple(c.estimators)): c for c in cases}.values():
        try:
            parse_inputs(case)
        except Exception:  # noqa: BLE001 - reported by the case itself
            pass


def _failed(case, wall: float, error: str) -> CaseResult:
    return CaseResult(case, "failed", [], [], wall, error=error, detail=error)


def run_task(cases: list, code_hash: str | None = None, env: dict | None = None,
             cache_dir: str | None = None, plugins: dict | None = None,
             time_limit_s: float | None = DEFAULT_CASE_TIME_LIMIT_S) -> list:
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
    key = (code_hash, repr(sorted((plugins or {}).items())))     # another run's code or plugins: a new one
    return run_supervised(cases, on_result, time_limit_s, key)


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
