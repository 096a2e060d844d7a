"""Command line: ``jointbench run STUDY [STUDY ...]``, ``status``, ``history``, ``diff``, ``nightly``, ``cache``,
``estimate``, ``list``, ``data fetch``.

Errors caused by the user (config, data, options, an unwritable results folder) print one line and exit
with status 2. Ctrl-C (and SIGTERM) stop a run within about a second, keeping every finished case: exit
status 130 (143 for SIGTERM); run again to resume. A run in which a case failed exits 1 (unless its study
says ``expected_failures: true``); a lost Dask scheduler stops the run with one line and exit status 75,
keeping every finished case (run again to resume).
"""
from __future__ import annotations

import argparse
import os
import signal
import sys

from jointbench.cli import data, estimate, history, studies
from jointbench.cli.common import BLAS_THREAD_VARIABLES, OneLineParser, guarded, on_sigterm


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="jointbench", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=OneLineParser)
    studies.add_parsers(sub)
    history.add_parsers(sub)
    estimate.add_parser(sub)
    data.add_parsers(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    if argv is None:                       # the real command line: its own process, numpy not loaded yet
        for v in BLAS_THREAD_VARIABLES:
            os.environ.setdefault(v, "1")
    parser = build_parser()
    args = parser.parse_args(estimate.joined_signed_values(sys.argv[1:] if argv is None else argv))
    args.command_line = [str(a) for a in (sys.argv[1:] if argv is None else argv)]   # what the history records
    previous = None
    if argv is None:                       # the real command line (not a call from a test)
        previous = signal.signal(signal.SIGTERM, on_sigterm)
    try:
        return guarded(lambda: args.func(args), real=argv is None)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
