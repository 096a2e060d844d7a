"""``jointbench run STUDY [STUDY ...]``, ``status``, ``nightly`` and ``list``: the studies of the harness."""
from __future__ import annotations

import shlex
import sys
from pathlib import Path

from jointbench.cli.common import budget_minutes, guarded, positive_int
from jointbench.core.errors import JointBenchError, worded_as


def _command(args) -> str:
    """The command as the run history records it: ``jointbench`` and the arguments :func:`main` parsed (its
    ``argv``, or the process's own)."""
    return " ".join(["jointbench", *(shlex.quote(a) for a in getattr(args, "command_line", []))])


def _root(args) -> Path:
    from jointbench.benchmarks.study import results_root

    return results_root(Path(args.out) if getattr(args, "out", None) else None)


def _plugins(args) -> None:
    """Import the ``--plugin`` modules (outside estimators, :mod:`jointbench.core.plugins`)."""
    from jointbench.core import plugins

    for ref in getattr(args, "plugin", None) or ():
        plugins.load(ref, "--plugin")


def _run(args) -> int:
    """``jointbench run STUDY [STUDY ...]``: one study, or several one after another (``--jobs 1``, the
    default) or side by side in forked processes (:mod:`jointbench.benchmarks.harness.side_by_side`)."""
    _plugins(args)
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
        code = _run_one(args, studies[0])
    elif args.jobs == 1:
        code = max(_run_one(args, study) for study in studies)
    else:
        from jointbench.benchmarks.harness import side_by_side

        code = max(side_by_side.run_forked(studies, args.jobs,
                                           lambda study: guarded(lambda: _run_one(args, study))))
    if args.write_readme and code == 0:       # what `jointbench status --write-readme` does, without its start-up
        from jointbench.benchmarks import status

        path, changed = status.write_readme(_root(args))
        print(f"{path}: status block {'rewritten' if changed else 'already up to date'}")
    return code


#: how ``jointbench run`` words the arguments of :func:`jointbench.api.run` in its messages
RUN_FLAGS = {"backend": "--backend", "plugins": "--plugin", "executor": "--executor", "workers": "--workers",
             "scheduler": "--scheduler"}


def _run_one(args, study: str) -> int:
    """One study of ``jointbench run``, through :func:`jointbench.api.run`; its summary printed in one piece
    (studies side by side print theirs whole)."""
    from jointbench import api
    from jointbench.benchmarks.checks import headline

    # ``--out`` as given (None without it): the API decides where a run writes, and a run with ``--set`` and no
    # ``--out`` goes to results/set-runs/, never over the study's own results (benchmarks.study._output_folder)
    with worded_as(RUN_FLAGS):
        run = api.run(study, parts=args.parts, out=args.out, executor="serial" if args.serial else
                      (args.executor or "process"), workers=args.workers, scheduler=args.scheduler,
                      use_cache=not args.no_cache, overrides=args.set or (), backend=args.backend,
                      budget=args.budget, confirm=args.yes, progress=not args.quiet, record_as=_command(args))
    comp = run.checks
    n_pass = int((comp["status"] == "pass").sum()) if len(comp) else 0
    n_cached = int(run.cases["cached"].sum())
    failed, refusals = len(run.failures), run.refusals
    lines = [f"{run.study}: {len(run.cases)} cases ({n_cached} from cache, {len(run.cases) - n_cached} "
             f"computed), {failed} failed, {len(refusals)} refused; {headline(comp)}"]
    lines += [f"  refused  {r.case_id}: {r.error}" for r in refusals.head(10).itertuples()]
    if len(refusals) > 10:
        lines.append(f"  ... {len(refusals) - 10} more refused cases (report.md, 'Refused cases')")
    lines += [f"  {r.status:4s}  {r.evidence:12s}  {r.check:18s} reproduced {r.reproduced:.5g}  "
              f"[{r.low:.5g}, {r.high:.5g}]" for r in comp.itertuples()]
    lines.append(f"wrote {run.folder}/report.md, checks.csv, cases.csv, cases.parquet; history run {run.run_id}")
    sys.stdout.write("\n".join(lines) + "\n")       # one write: under PYTHONUNBUFFERED print() makes two,
    sys.stdout.flush()                                # and a study side by side could land between them
    if failed:
        from jointbench.benchmarks.runner import failure_summary

        print("\n".join(failure_summary(run.failures.itertuples(index=False), run.folder / "failures.log")),
              file=sys.stderr)
    if failed and not run.expected_failures:
        print(f"jointbench: {failed} of {len(run.cases)} cases failed (tracebacks in "
              f"{run.folder / 'failures.log'}); exit 1 (a study whose failures are expected says "
              f"'expected_failures: true')", file=sys.stderr)
        return 1
    if args.strict and (failed or n_pass < len(comp)):
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
    from jointbench.benchmarks.nightly import DEFAULT_CONFIG, load_config
    from jointbench.benchmarks.nightly import run_nightly

    config = load_config(Path(args.config) if args.config else DEFAULT_CONFIG)
    if args.studies:
        import dataclasses

        config = dataclasses.replace(config, studies=tuple(args.studies))
    res = run_nightly(config, _root(args), workers=args.workers, serial=args.serial, progress=not args.quiet,
                      command=_command(args))
    print(f"nightly {res.nightly_id}: {res.verdict}")
    for line in res.regressions:
        print(f"  {line}")
    print(f"wrote {res.index} and {res.history_page.name}")
    return 1 if res.verdict == "regression" else 0


def add_parsers(sub) -> None:
    """Add ``run``, ``status``, ``nightly`` and ``list`` to an :mod:`argparse` subparsers object."""
    p = sub.add_parser("run", help="run a study: results/<study>/{checks.csv,cases.csv,report.md}")
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
    p = sub.add_parser("status", help="status of every study from results/*/checks.csv (README tables)")
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
    p = sub.add_parser("list", help="list studies, estimators and protocols")
    p.add_argument("--plugin", action="append", metavar="MODULE", help="import an outside estimator first")
    p.set_defaults(func=_list)
