"""Command line: ``jointbench run STUDY [STUDY ...]``, ``status``, ``history``, ``diff``, ``nightly``, ``cache``,
``estimate``, ``list``.

Errors caused by the user (config, data, options, an unwritable results folder) print one line and exit
with status 2. Ctrl-C (and SIGTERM) stop a run within about a second, keeping every finished case: exit
status 130 (143 for SIGTERM); run again to resume. A run in which a case failed exits 1 (unless its study
says ``expected_failures: true``); a lost Dask scheduler stops the run with one line and exit status 75,
keeping every finished case (run again to resume).
"""
from __future__ import annotations

import argparse
import os
import shlex
import signal
import sys
from pathlib import Path

from jointbench.errors import JointBenchError

#: one BLAS thread per process for the command (cases already run in parallel, and results do not depend
#: on the thread count); set by :func:`main` on the real command line only, before numpy is imported:
#: importing this module (or jointbench.api) changes nothing for the caller
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


class Terminated(KeyboardInterrupt):
    """SIGTERM, turned into an exception so that every cleanup runs (temporaries, workers, history)."""

    reason = "terminated (SIGTERM)"


def _on_sigterm(signum, frame):
    raise Terminated()


class OneLineParser(argparse.ArgumentParser):
    """Usage errors are one line (and exit status 2), like every other user error."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {value}")
    return value


def budget_minutes(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected minutes > 0, got {text!r}") from None
    if not value > 0:              # NaN as well: it would compare false with every estimate
        raise argparse.ArgumentTypeError(f"expected minutes > 0, got {text!r}")
    return value


def _command() -> str:
    return "jointbench " + " ".join(shlex.quote(a) for a in sys.argv[1:]) if sys.argv[1:] else ""


def _root(args) -> Path:
    from jointbench.benchmarks.study import results_root

    return results_root(Path(args.out) if getattr(args, "out", None) else None)


def _plugins(args) -> None:
    """Import the ``--plugin`` modules (outside estimators, :mod:`jointbench.plugins`)."""
    from jointbench import plugins

    for ref in getattr(args, "plugin", None) or ():
        plugins.load(ref, "--plugin")


def _run(args) -> int:
    """``jointbench run STUDY [STUDY ...]``: one study, or several one after another (``--jobs 1``, the
    default) or side by side in forked processes (:mod:`jointbench.benchmarks.harness.side_by_side`)."""
    _plugins(args)
    from jointbench.benchmarks.config import check_backend

    backend = check_backend(args.backend, "option --backend") if args.backend else None
    if args.serial and args.executor not in (None, "serial"):
        raise JointBenchError(f"--serial and --executor {args.executor} contradict each other")
    studies = list(dict.fromkeys(args.study))
    if len(studies) > 1:
        from jointbench.benchmarks.overrides import parse_override

        named = [o for o in args.set or () if parse_override(o).part != "*"]
        for option, given in (("--parts", args.parts), ("--set", named)):
            if given:
                raise JointBenchError(f"{option} {' '.join(given)} names parts of one study: give one study, "
                                      f"not {len(studies)} (a --set '*.KEY=VALUE' applies to every study)")
    if args.write_readme:                     # before the studies, not after them
        from jointbench.benchmarks import status

        status.readme_text()
    if len(studies) > 1 and args.jobs > 1 and args.executor == "dask":
        raise JointBenchError("--executor dask with --jobs > 1: one cluster serves the studies one after "
                              "another (--jobs 1)")
    if len(studies) == 1:
        code = _run_one(args, studies[0], backend)
    elif args.jobs == 1:
        code = max(_run_one(args, study, backend) for study in studies)
    else:
        from jointbench.benchmarks.harness import side_by_side

        side_by_side.preload()
        code = max(side_by_side.run_forked(studies, args.jobs,
                                           lambda study: _guarded(lambda: _run_one(args, study, backend))))
    if args.write_readme and code == 0:       # what `jointbench status --write-readme` does, without its start-up
        from jointbench.benchmarks import status

        path, changed = status.write_readme(_root(args))
        print(f"{path}: status block {'rewritten' if changed else 'already up to date'}")
    return code


def _run_one(args, study: str, backend: str | None) -> int:
    """One study of ``jointbench run`` (``backend``: the checked ``--backend``); its summary printed in one
    piece (studies side by side print theirs whole)."""
    from jointbench.benchmarks.harness.pool import make_executor
    from jointbench.benchmarks.study import run_study

    executor = make_executor(args.executor or "process", args.workers, args.scheduler)
    try:
        run = run_study(study, parts=args.parts or None, out_root=_root(args), serial=args.serial,
                        workers=args.workers, use_cache=not args.no_cache, progress=not args.quiet,
                        command=_command(), backend=backend, executor=executor, overrides=args.set or (),
                        budget_minutes=args.budget, confirm=args.yes)
    finally:
        if executor is not None:
            executor.shutdown(wait=True)
    from jointbench.benchmarks.tables import headline

    comp = run.comparison
    n_pass = int((comp["status"] == "pass").sum()) if len(comp) else 0
    n_cached = sum(r.cached for r in run.results)
    lines = [f"{run.study.id}: {len(run.results)} cases ({n_cached} from cache, {len(run.results) - n_cached} "
             f"computed), {len(run.failed)} failed; {headline(comp)}"]
    lines += [f"  {r.status:4s}  {r.evidence:12s}  {r.check:18s} reproduced {r.reproduced:.5g}  "
              f"[{r.low:.5g}, {r.high:.5g}]" for r in comp.itertuples()]
    lines.append(f"wrote {run.folder}/report.md, comparison.csv, cases.csv, cases.parquet; history run {run.run_id}")
    sys.stdout.write("\n".join(lines) + "\n")       # one write: under PYTHONUNBUFFERED print() makes two,
    sys.stdout.flush()                                # and a study side by side could land between them
    if run.failed and not run.study.expected_failures:
        print(f"jointbench: {len(run.failed)} of {len(run.results)} cases failed (tracebacks in "
              f"{run.folder / 'failures.log'}); exit 1 (a study whose failures are expected says "
              f"'expected_failures: true')", file=sys.stderr)
        return 1
    if args.strict and (len(run.failed) or n_pass < len(comp)):
        return 1
    return 0


def _status(args) -> int:
    from pathlib import Path

    from jointbench.benchmarks import status

    results = Path(args.results) if args.results else None
    if results is not None and not results.is_dir():
        raise JointBenchError(f"--results {results}: no such folder (the results folder of `jointbench run`)")
    if args.write_readme:
        readme = Path(args.readme) if args.readme else None
        path, changed = status.write_readme(results, readme)
        print(f"{path}: status block {'rewritten' if changed else 'already up to date'}")
    else:
        print(status.block(results))
    return 0


def _list(args) -> int:
    _plugins(args)
    from jointbench import estimators
    from jointbench.benchmarks import protocols
    from jointbench.benchmarks.locate import study_ids

    print("studies:   " + ", ".join(study_ids()))
    print("estimators: " + ", ".join(estimators.REGISTRY.names()))
    print("protocols: " + ", ".join(protocols.REGISTRY.names()))
    return 0


def _nightly(args) -> int:
    from jointbench.benchmarks.harness.nightly import DEFAULT_CONFIG, load_config
    from jointbench.benchmarks.nightly import run_nightly

    config = load_config(Path(args.config) if args.config else DEFAULT_CONFIG)
    if args.studies:
        import dataclasses

        config = dataclasses.replace(config, studies=tuple(args.studies))
    res = run_nightly(config, _root(args), workers=args.workers, serial=args.serial, progress=not args.quiet,
                      command=_command() or "jointbench nightly")
    print(f"nightly {res.nightly_id}: {res.verdict}")
    for line in res.regressions:
        print(f"  {line}")
    print(f"wrote {res.index} and {res.history_page.name}")
    return 1 if res.verdict == "regression" else 0


def build_parser() -> argparse.ArgumentParser:
    from jointbench.benchmarks import cli_history

    parser = OneLineParser(prog="jointbench", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=OneLineParser)
    p = sub.add_parser("run", help="run a study: results/<study>/{comparison.csv,cases.csv,report.md}")
    p.add_argument("study", nargs="+", help="a shipped study's id (jointbench list) or the path of a study file; "
                                            "several: one after another, or side by side with --jobs")
    p.add_argument("--jobs", type=positive_int, default=1, metavar="N",
                   help="with several studies: run N at once, each in a process forked after the imports "
                        "they share (default 1: one after another); each study's cases still run where "
                        "--serial or --workers says")
    p.add_argument("--write-readme", action="store_true",
                   help="when every study ends well, rewrite README.md's status block from the results folder "
                        "(as `jointbench status --write-readme`; make reproduce)")
    p.add_argument("--parts", nargs="+", metavar="PART", help="only these parts (e.g. fig4 table1)")
    p.add_argument("--serial", action="store_true", help="run cases one after another in this process")
    p.add_argument("--workers", type=positive_int, default=None, help="processes (default: all cores)")
    p.add_argument("--no-cache", action="store_true", help="recompute cases even when cached")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--strict", action="store_true", help="exit 1 if a case fails or a check misses")
    p.add_argument("--out", metavar="DIR", help="results folder (default: ./results)")
    p.add_argument("--plugin", action="append", metavar="MODULE",
                   help="import an outside estimator first: a module name or the path of a .py file; repeatable")
    p.add_argument("--backend", metavar="NAME", default=None,
                   help="simulate every part on this backend (analytic, mujoco, ...); outputs in "
                        "results/<study>/backend-NAME/")
    p.add_argument("--set", action="append", metavar="PART.KEY=VALUE",
                   help="override one value of a part before the config is checked, e.g. table1.seeds=3 or "
                        "matrix.grid.noise=[0.1] ('*.seeds=2': every part); repeatable")
    p.add_argument("--executor", choices=("process", "serial", "dask"), default=None,
                   help="where cases run: a process pool on this machine (default), this process, or a Dask "
                        "cluster (a local one, or --scheduler's)")
    p.add_argument("--scheduler", metavar="ADDRESS", default=None,
                   help="with --executor dask: a running Dask scheduler, e.g. tcp://10.0.0.5:8786")
    p.add_argument("--budget", type=budget_minutes, metavar="MINUTES", default=None,
                   help="refuse a comparison grid estimated to take longer (default: its config's budget)")
    p.add_argument("--yes", action="store_true", help="run a grid even when it is estimated over its budget")
    p.set_defaults(func=_run)
    p = sub.add_parser("status", help="status of every study from results/*/comparison.csv (README tables)")
    p.add_argument("--write-readme", action="store_true",
                   help="rewrite the block between <!-- status:begin --> and <!-- status:end --> in README.md")
    p.add_argument("--results", metavar="DIR", help="results folder (default: ./results)")
    p.add_argument("--readme", metavar="FILE", help="README to rewrite (default: ./README.md)")
    p.set_defaults(func=_status)
    p = sub.add_parser("nightly", help="run every paper study, compare with the previous nightly, write "
                                       "results/nightly/index.html; exit 1 on a regression")
    p.add_argument("--config", metavar="FILE", help="nightly config (default: configs/nightly.yaml)")
    p.add_argument("--studies", nargs="+", metavar="STUDY", help="these studies instead of the config's")
    p.add_argument("--serial", action="store_true", help="run cases one after another in this process")
    p.add_argument("--workers", type=positive_int, default=None, help="processes (default: all cores)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--out", metavar="DIR", help="results folder (default: ./results)")
    p.set_defaults(func=_nightly)
    cli_history.add_parsers(sub, positive_int)
    p = sub.add_parser("list", help="list studies, estimators and protocols")
    p.add_argument("--plugin", action="append", metavar="MODULE", help="import an outside estimator first")
    p.set_defaults(func=_list)
    from jointbench.benchmarks.recordings.cli import add_parser as add_estimate_parser

    add_estimate_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    if argv is None:                       # the real command line: its own process, numpy not loaded yet
        for v in BLAS_THREAD_VARIABLES:
            os.environ.setdefault(v, "1")
    parser = build_parser()
    args = parser.parse_args(argv)
    previous = None
    if argv is None:                       # the real command line (not a call from a test)
        previous = signal.signal(signal.SIGTERM, _on_sigterm)
    try:
        return _guarded(lambda: args.func(args), real=argv is None)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _guarded(call, real: bool = False) -> int:
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


if __name__ == "__main__":
    sys.exit(main())
