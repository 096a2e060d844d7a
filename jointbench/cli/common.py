"""What every subcommand of the command line shares: one-line usage errors, the argument types, and
how errors and interruptions become one line and an exit status (:func:`guarded`)."""
from __future__ import annotations

import argparse
import os
import sys

from jointbench.core import arguments
from jointbench.core.errors import ConfigError, JointBenchError

#: one BLAS thread per process for the command (cases already run in parallel, and results do not depend
#: on the thread count); set by :func:`jointbench.cli.command.main` on the real command line only, before numpy is
#: imported: importing the CLI (or jointbench.api) changes nothing for the caller
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


class Terminated(KeyboardInterrupt):
    """SIGTERM, turned into an exception so that every cleanup runs (temporaries, workers, history)."""

    reason = "terminated (SIGTERM)"


def on_sigterm(signum, frame):
    raise Terminated()


class OneLineParser(argparse.ArgumentParser):
    """Usage errors are one line (and exit status 2), like every other user error."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _decided(rule, value, *args, **kwargs):
    """``rule(value, "value", ...)`` of :mod:`jointbench.core.arguments` (the API's own rule for the argument),
    its error as argparse's (which names the flag)."""
    try:
        return rule(value, "value", *args, **kwargs)
    except ConfigError as exc:
        raise argparse.ArgumentTypeError(str(exc).split(": ", 1)[-1]) from None


def positive_int(text: str) -> int:
    """A whole number >= 1 (``--workers``, ``--limit``, a run id...): the text parsed here, decided by
    :func:`jointbench.core.arguments.whole`."""
    try:
        value = int(text)
    except ValueError:
        value = text
    return _decided(arguments.whole, value, minimum=1)


def budget_minutes(text: str) -> float:
    """Minutes > 0 (``--budget``; a unit allowed: ``2h``), decided by :func:`jointbench.core.arguments.positive`."""
    return _decided(arguments.positive, text, "min")


def guarded(call, real: bool = False) -> int:
    """``call()``'s exit status, with the command's errors and interruptions turned into one line on stderr
    and their statuses (module docstring). ``real``: this process is the command line's own, which then
    leaves at once after an interruption (no interpreter teardown)."""
    try:
        return int(call() or 0)
    except JointBenchError as exc:
        print(f"jointbench: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:   # output piped into e.g. `head`
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except KeyboardInterrupt as exc:
        if getattr(exc, "exit_code", None):        # lost infrastructure (a Dask scheduler): not Ctrl-C
            run = f" (history run {exc.run_id})" if getattr(exc, "run_id", None) else ""
            print(f"jointbench: error: {exc.reason}{run}", file=sys.stderr)
            if real:
                sys.stdout.flush()
                sys.stderr.flush()
                os._exit(exc.exit_code)
            return exc.exit_code
        sigterm = isinstance(exc, Terminated) or isinstance(exc.__context__, Terminated) or \
            "SIGTERM" in str(getattr(exc, "reason", ""))
        what = "terminated" if sigterm else "interrupted"
        finished, total = getattr(exc, "finished", None), getattr(exc, "total", None)
        kept = (f": {len(finished)} of {total} cases finished and kept" if finished is not None else "")
        run = f" (history run {exc.run_id})" if getattr(exc, "run_id", None) else ""
        print(f"jointbench: {what}{kept}{run}; run again to resume", file=sys.stderr)
        code = 143 if sigterm else 130
        if real:                # the real command line: everything is stored and the workers are gone;
            sys.stdout.flush()  # skip the interpreter's teardown of numpy, scipy, pandas, matplotlib
            sys.stderr.flush()  # (0.5-1 s on a busy machine) so that Ctrl-C returns at once
            os._exit(code)
        return code
