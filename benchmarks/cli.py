"""Command line: ``jointbench run STUDY``, ``jointbench estimate ...``, ``jointbench list``.

Errors caused by the user (config, data, options) print one line and exit with status 2.
"""
from __future__ import annotations

import os

# One BLAS thread per process: cases already run in parallel, and results do not depend on the
# thread count. Must be set before numpy is imported.
for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import shlex  # noqa: E402
import sys  # noqa: E402

from jointbench.errors import JointBenchError  # noqa: E402


def _run(args) -> int:
    from benchmarks.config import check_backend
    from benchmarks.study import run_study

    cmd = "jointbench " + " ".join(shlex.quote(a) for a in sys.argv[1:]) if sys.argv[1:] else ""
    backend = check_backend(args.backend, "option --backend") if args.backend else None
    run = run_study(args.study, parts=args.parts or None, serial=args.serial, workers=args.workers,
                    use_cache=not args.no_cache, progress=not args.quiet, command=cmd, backend=backend)
    comp = run.comparison
    n_pass = int((comp["status"] == "pass").sum()) if len(comp) else 0
    print(f"{run.study.id}: {len(run.results)} cases, {len(run.failed)} failed; "
          f"{n_pass}/{len(comp)} checks pass")
    for r in comp.itertuples():
        print(f"  {r.status:4s}  {r.check:18s} reproduced {r.reproduced:.5g}  [{r.low:.5g}, {r.high:.5g}]")
    print(f"wrote {run.folder}/report.md, comparison.csv, cases.csv")
    if args.strict and (len(run.failed) or n_pass < len(comp)):
        return 1
    return 0


def _list(args) -> int:
    import estimators
    from benchmarks import protocols
    from benchmarks.config import CONFIGS

    print("studies:   " + ", ".join(sorted(p.stem for p in (CONFIGS / "studies").glob("*.yaml"))))
    print("estimators: " + ", ".join(estimators.REGISTRY.names()))
    print("protocols: " + ", ".join(protocols.REGISTRY.names()))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="jointbench", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("run", help="run a study: results/<study>/{comparison.csv,cases.csv,report.md}")
    p.add_argument("study", help="study id (configs/studies/<id>.yaml) or path to a study config")
    p.add_argument("--parts", nargs="+", metavar="PART", help="only these parts (e.g. fig4 table1)")
    p.add_argument("--serial", action="store_true", help="run cases one after another in this process")
    p.add_argument("--workers", type=int, default=None, help="processes (default: all cores)")
    p.add_argument("--no-cache", action="store_true", help="recompute cases even when cached")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--strict", action="store_true", help="exit 1 if a case fails or a check misses")
    p.add_argument("--backend", metavar="NAME", default=None,
                   help="simulate every part on this backend (analytic, mujoco, ...); outputs in "
                        "results/<study>/backend-NAME/")
    p.set_defaults(func=_run)
    p = sub.add_parser("list", help="list studies, estimators and protocols")
    p.set_defaults(func=_list)
    from benchmarks import cli_estimate

    cli_estimate.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except JointBenchError as exc:
        print(f"jointbench: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:   # output piped into e.g. `head`
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except KeyboardInterrupt:
        print("jointbench: interrupted (finished cases are cached; run again to resume)", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
