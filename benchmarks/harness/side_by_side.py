"""Several studies side by side: one forked process per study, after the imports they all share.

``jointbench run A B C D --jobs 4`` (``make reproduce``) runs each study in a child process forked from
the command's own, at most ``jobs`` at once. Nothing is shared: each child imports what its study needs
and opens its own history connection, cache and workers, as a command of its own would. (Importing the
modules every study needs once before forking, a speed-only mechanism, was removed in issue 34: it saved
less than the 10 % of ``make reproduce`` such a mechanism must save to stay, results/benchmarks.md.)

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
