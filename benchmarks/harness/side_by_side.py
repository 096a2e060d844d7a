"""Several studies side by side: one forked process per study, after the imports they all share.

``jointbench run A B C D --jobs 4`` (``make reproduce``) runs each study in a child process forked from
the command's own, at most ``jobs`` at once. Before forking, :func:`preload` imports what every study run
imports (numpy, scipy, pandas, pyarrow, matplotlib, Jinja2, the harness, every registered protocol and
estimator): the children share those pages instead of importing them again each. A study run imports
about 2 CPU-s of modules on the 2-core machine, so four studies started as four commands (``make -j4``)
spent 6 CPU-s on imports their neighbours had already made (issue 22). Nothing else is shared: each
child opens its own history connection, cache and workers, as a command of its own would.

Signals: each child runs in a process group of its own, so a signal meant for the command (Ctrl-C at the
terminal, a SIGTERM to the command or to its process group) reaches the command alone, which passes it on
to every running child once and waits for them; each child stops as a single run does, keeping its
finished cases. The exit status is the largest of the children's (143 SIGTERM > 130 Ctrl-C > 75 lost Dask
scheduler > 2 user error > 1 failed case > 0).
"""
from __future__ import annotations

import os
import signal
import sys
import traceback
from collections.abc import Callable, Sequence


def preload() -> None:
    """Import what every study run imports, and compile the simulator's loops, so that children forked
    afterwards share them.

    The compiled loops (numba) cost seconds to compile on a machine where they never were, and loading
    them from numba's disk cache after that. This process compiles the simulator's
    (:func:`jointbench.sims.backend_ltv.warm`: every study simulates); meanwhile a child of its own
    compiles the estimators' into the disk cache (:func:`_compile_aside`), on the core this process
    leaves idle while it imports, so a study that fits them loads them from there.

    Starts no thread (the BLAS thread count is fixed by the command line before numpy loads, Arrow's
    thread pool starts on first use), so forking afterwards is safe."""
    _compile_aside()
    import matplotlib

    matplotlib.use("Agg")
    import jinja2  # noqa: F401
    import matplotlib.pyplot  # noqa: F401
    import pandas  # noqa: F401
    import pyarrow.parquet  # noqa: F401
    import scipy.signal  # noqa: F401

    from jointbench import estimators
    from jointbench.benchmarks import protocols, report, study, tables  # noqa: F401
    from jointbench.sims import backend_ltv

    for registry in (protocols.REGISTRY, estimators.REGISTRY):
        for name in registry.names():
            registry.get(name)
    backend_ltv.warm()


def _compile_aside() -> int | None:
    """A forked child that compiles the estimators' loops (the ensemble solver's,
    :func:`jointbench.estimators._small_eigh.warm`, and FSEWLS's, :func:`jointbench.estimators._ewls_loops.warm`)
    into numba's disk cache and exits, silently (its pid; None when no process can be forked). A study
    that first imports those loops waits for it (:func:`jointbench.core.compiled.wait_aside`: the pipe it holds
    closes when it exits) and loads them from the cache, so they are compiled once; when numba has no
    writable cache folder it exits at once (its work could not be shared). :func:`run_forked` reaps it
    with the studies (a pid that is not a study's)."""
    sys.stdout.flush()
    sys.stderr.flush()
    try:
        done_r, done_w = os.pipe()                # closed by the child's exit: what wait_aside waits for
    except OSError:
        return None
    try:
        pid = os.fork()
    except OSError:
        os.close(done_r)
        os.close(done_w)
        return None
    if pid == 0:                                  # the child: compile, leave the cache, exit
        code = 1
        try:
            os.close(done_r)
            quiet = os.open(os.devnull, os.O_WRONLY)    # warnings are the studies' to print
            os.dup2(quiet, 1)
            os.dup2(quiet, 2)
            from jointbench.core import compiled
            from jointbench.estimators import _ewls_loops, _small_eigh

            if not compiled.uncached():
                _small_eigh.warm()
                _ewls_loops.warm()
            code = 0
        except BaseException:                     # noqa: BLE001 - a fit compiles them then
            pass
        finally:
            os._exit(code)
    os.close(done_w)
    from jointbench.core import compiled

    compiled.compiling_aside(done_r)              # the studies forked from here wait for it (wait_aside)
    return pid


def exit_code(status: int) -> int:
    """A child's wait status as a shell reports it (128 + signal number when a signal ended it)."""
    code = os.waitstatus_to_exitcode(status)
    return 128 - code if code < 0 else code


def run_forked(items: Sequence, jobs: int, run_one: Callable[[object], int]) -> list[int]:
    """``run_one(item)`` for every item, each in a child forked from this process, at most ``jobs`` at once
    (in the order given); the children's exit statuses, in the order of ``items``.

    ``run_one`` returns the child's exit status; an exception escaping it is printed and gives 1. On a
    KeyboardInterrupt (Ctrl-C, or the SIGTERM handler of the command line) no further child is started,
    the signal is passed on to the running children (SIGTERM for a SIGTERM, else SIGINT; each child is in
    a process group of its own, so that is the only copy it gets) and they are waited for; their
    statuses are returned as usual, and an item never started gets the signal's status (128 + its
    number): an interrupted command never reports success.
    """
    if jobs < 1:
        raise ValueError(f"jobs must be >= 1, got {jobs}")
    codes: list[int | None] = [None] * len(items)
    running: dict[int, int] = {}
    queue = list(range(len(items)))
    stopping = None
    while queue or running:
        try:
            while queue and len(running) < jobs and stopping is None:
                i = queue.pop(0)
                sys.stdout.flush()
                sys.stderr.flush()
                pid = os.fork()
                if pid == 0:                       # the child: run, flush, leave without the parent's cleanup
                    code = 1
                    try:
                        os.setpgid(0, 0)
                        code = int(run_one(items[i]) or 0)
                    except SystemExit as exc:
                        code = exc.code if isinstance(exc.code, int) else 1
                    except BaseException:
                        traceback.print_exc()
                    finally:
                        sys.stdout.flush()
                        sys.stderr.flush()
                        os._exit(code)
                try:
                    os.setpgid(pid, pid)           # as the child does: whichever runs first
                except (PermissionError, ProcessLookupError):
                    pass                           # the child got there first (and may have exec'd or ended)
                running[pid] = i
            if not running:
                break
            pid, status = os.wait()
            if pid in running:
                codes[running.pop(pid)] = exit_code(status)
        except KeyboardInterrupt as exc:           # Ctrl-C or SIGTERM: stop starting, pass it on, wait
            stopping = signal.SIGTERM if "SIGTERM" in str(getattr(exc, "reason", "")) else signal.SIGINT
            queue.clear()
            for pid in running:
                try:
                    os.kill(pid, stopping)
                except ProcessLookupError:
                    pass
    stopped = 128 + int(stopping) if stopping is not None else 1
    return [c if c is not None else stopped for c in codes]   # never started: as the signal that stopped it
