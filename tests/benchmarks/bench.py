"""``make bench``: speed benchmarks compared against the last stored run, and the wall times of the studies.

    python -m tests.benchmarks.bench [--save-only | --studies-only | --no-studies]

1. pytest-benchmark over ``tests/benchmarks`` with timings on. When a run is stored under
   ``.benchmarks/<machine>/`` (pytest-benchmark's storage, not committed: timings belong to a machine),
   the run is compared with the latest one on **same-run ratios**: each benchmark's median divided by the
   median of its baseline in the same run (:func:`tests.benchmarks.summary.gate`); the run fails when a
   ratio grew by more than :data:`~tests.benchmarks.summary.RATIO_FACTOR` (2x) and again on an
   immediate re-run of the flagged benchmarks with their baselines (the reasons are there).
   Absolute medians are printed beside, not judged: on the shared machine they move with the load. A run
   that passes is stored as the new reference; a failing one is not (the reference it failed against
   stays). ``--save-only`` stores the run without comparing (``make bench-save``: a first reference, or
   one after an accepted slowdown). The full report is also written to ``results/benchmarks.json``.
2. The studies of ``make reproduce``, each run from scratch (no cache) into a temporary folder (the
   committed results are not touched), their wall times appended to ``.benchmarks/study_times.csv``
   with the commit, the number of cases and the load average, and printed beside the previous time.
   Recorded, not judged: the machine may be shared; compare times taken on an idle machine.
3. ``make reproduce`` on a fresh clone (``--fresh-clone``, also part of a full ``make bench``): the commit
   cloned into a temporary folder, its ``.venv`` made (not timed), then ``make reproduce`` timed with an
   empty cache (``XDG_CACHE_HOME`` a new folder: no cached case, no matplotlib font cache), as a
   newcomer's first run; wall and CPU seconds (the children's) appended to
   ``.benchmarks/reproduce_times.csv``. Issue 22's target is under 60 s on 2 idle cores.
4. ``results/benchmarks.md`` (committed; the README points to it), generated from the JSON report, the
   study times and the fresh-clone time of this run (:mod:`tests.benchmarks.summary`): no benchmark
   figure is typed by hand.
"""
from __future__ import annotations

import argparse
import csv
import datetime
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tests.benchmarks.summary import RATIO_FACTOR

REPO = Path(__file__).resolve().parents[2]
STORAGE = REPO / ".benchmarks"
STUDIES = ("westwick2012", "xu1998", "vanderuit2018_table1", "vanderuit2018_table2")     # make reproduce


def _stored() -> set[Path]:
    return set(STORAGE.glob("*/[0-9][0-9][0-9][0-9]_*.json"))


def micro(compare: bool) -> tuple[int, tuple[str, str], Path | None]:
    """Run the pytest benchmarks; compare with the latest stored run (if any and ``compare``); store on
    success. Returns the exit status, the 1-minute load average before and after, and the stored run
    compared with (None when there was none)."""
    load0 = f"{os.getloadavg()[0]:.2f}"
    before = _stored()
    latest = None
    (REPO / "results").mkdir(exist_ok=True)
    args = [sys.executable, "-m", "pytest", "-q", "tests/benchmarks", "--benchmark-enable",
            f"--benchmark-storage=file://{STORAGE}", "--benchmark-autosave",
            "--benchmark-json=results/benchmarks.json", "--benchmark-sort=name",
            "--benchmark-columns=median,iqr,min,rounds"]
    if compare and before:
        latest = max(before, key=lambda p: p.name)
        print(f"comparing with the stored run {latest.relative_to(REPO)} (a ratio to the same-run baseline "
              f"grown by more than x{RATIO_FACTOR:g} fails; medians are reported)")
    elif compare:
        print("no stored run to compare with: this run becomes the reference")
    rc = subprocess.call(args, cwd=REPO)
    if rc == 0 and latest is not None:
        rc = judge(REPO / "results" / "benchmarks.json", latest, args[:args.index("tests/benchmarks")])
    new = _stored() - before
    if rc != 0:
        for p in new:
            p.unlink()
        print(f"benchmarks failed (exit {rc}): this run is not stored; the reference stays as it was")
    else:
        for p in new:
            print(f"stored as the new reference: {p.relative_to(REPO)}")
    return rc, (load0, f"{os.getloadavg()[0]:.2f}"), latest


def judge(report: Path, reference: Path, pytest: list[str] | None = None) -> int:
    """Compare ``report`` with the stored run ``reference`` on same-run ratios (:func:`summary.gate`) and
    print it. A ratio grown beyond :data:`RATIO_FACTOR` is measured again at once (those benchmarks and
    their baselines, with the ``pytest`` command line; not stored): 1 when it is still beyond, else 0."""
    import json

    from tests.benchmarks.summary import confirmed, gate, to_recheck

    now, then = json.loads(report.read_text()), json.loads(reference.read_text())
    lines, failed = gate(now, then, RATIO_FACTOR)
    print("\n".join(lines))
    if not failed or pytest is None:
        return 1 if failed else 0
    ids = to_recheck(now, failed)
    print(f"\nmeasuring again: {', '.join(failed)} (and their baselines)")
    with tempfile.TemporaryDirectory(prefix="jointbench-bench-") as tmp:
        out = Path(tmp) / "recheck.json"
        subprocess.call([*pytest, *ids, "--benchmark-enable", f"--benchmark-json={out}"], cwd=REPO)
        recheck = json.loads(out.read_text()) if out.is_file() else {"benchmarks": []}
    still = confirmed(now, recheck, then, RATIO_FACTOR)
    print(f"beyond x{RATIO_FACTOR:g} again on the re-run: {', '.join(still)}" if still else
          f"the re-run is within x{RATIO_FACTOR:g}: load noise, not a regression")
    return 1 if still else 0


def _commit() -> str:
    try:
        out = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=REPO, capture_output=True,
                             text=True, timeout=10)
        return out.stdout.strip() or "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def _cpu_seconds() -> float:
    """User + system CPU seconds of this process and its finished children (the pool's workers)."""
    import resource

    me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def _append(log: Path, fields: list[str], rows: list[dict]) -> None:
    """Append ``rows`` to the CSV ``log`` (in :data:`STORAGE`), with its header when the file is new."""
    STORAGE.mkdir(exist_ok=True)
    new_file = not log.is_file()
    with open(log, "a", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=fields)
        if new_file:
            w.writeheader()
        w.writerows(rows)


def reproduce_executor() -> tuple[bool, int | None]:
    """``(serial, workers)`` of each study in ``make reproduce`` on this machine, as the Makefile decides it
    (``make reproduce-where``: ``--serial`` below 8 cores, else ``--workers N``)."""
    where = subprocess.run(["make", "-s", "--no-print-directory", "reproduce-where"], cwd=REPO, check=True,
                           capture_output=True, text=True).stdout.split()
    if where[:1] == ["--workers"]:
        return False, int(where[1])
    return True, None


def studies() -> tuple[int, list[dict]]:
    """Run every study of ``make reproduce`` without cache into a temporary folder; record the wall times."""
    from jointbench.benchmarks.study import run_study

    log = STORAGE / "study_times.csv"
    previous: dict[str, dict] = {}
    if log.is_file():
        with open(log, newline="") as fh:
            for row in csv.DictReader(fh):
                previous[row["study"]] = row
    fields = ["date", "commit", "study", "cases", "wall_s", "cpu_s", "cpus", "where", "load_before", "load_after"]
    serial, workers = reproduce_executor()
    where = "in its own process (--serial)" if serial else f"on {workers} workers"
    if log.is_file() and open(log).readline().strip().split(",") != fields:
        log.rename(log.with_suffix(".old.csv"))     # an older layout: kept beside, a new file begins
        previous = {}
    rows, rc = [], 0
    with tempfile.TemporaryDirectory(prefix="jointbench-bench-") as tmp:
        for study in STUDIES:
            load0 = os.getloadavg()[0]
            cpu0 = _cpu_seconds()
            t0 = time.perf_counter()
            run = run_study(study, out_root=Path(tmp), use_cache=False, progress=False, serial=serial,
                            workers=workers, command=f"make bench ({study})")
            wall = time.perf_counter() - t0
            cpu = _cpu_seconds() - cpu0
            if run.failed:
                print(f"{study}: {len(run.failed)} case(s) failed", file=sys.stderr)
                rc = 1
            rows.append({"date": datetime.datetime.now().isoformat(timespec="seconds"), "commit": _commit(),
                         "study": study, "cases": len(run.results), "wall_s": f"{wall:.1f}", "cpu_s": f"{cpu:.1f}",
                         "cpus": os.cpu_count(), "where": where, "load_before": f"{load0:.2f}",
                         "load_after": f"{os.getloadavg()[0]:.2f}"})
    _append(log, fields, rows)
    print(f"\nstudy wall times (no cache; appended to {log.relative_to(REPO)}):")
    print(f"{'study':24s} {'cases':>6s} {'wall s':>8s} {'CPU s':>8s} {'previous':>9s} {'ratio':>6s}  "
          f"load 1 min (before/after)")
    for r in rows:
        prev = previous.get(r["study"])
        ratio = f"{float(r['wall_s']) / float(prev['wall_s']):.2f}" if prev else "-"
        print(f"{r['study']:24s} {r['cases']:>6} {r['wall_s']:>8s} {r['cpu_s']:>8s} "
              f"{prev['wall_s'] if prev else '-':>9s} {ratio:>6s}  {r['load_before']}/{r['load_after']}")
    print(f"total {sum(float(r['wall_s']) for r in rows):.1f} s wall, {sum(float(r['cpu_s']) for r in rows):.1f} "
          f"CPU-s on {os.cpu_count()} cores")
    return rc, rows


def fresh_clone() -> tuple[int, dict]:
    """``make reproduce`` on a fresh clone of HEAD with an empty cache (module docstring, 3); its row."""
    import shutil

    fields = ["date", "commit", "wall_s", "cpu_s", "cpus", "load_before", "load_after", "exit"]
    with tempfile.TemporaryDirectory(prefix="jointbench-fresh-") as tmp:
        clone, cache = Path(tmp) / "clone", Path(tmp) / "cache"
        subprocess.run(["git", "clone", "--quiet", "--no-hardlinks", str(REPO), str(clone)], check=True)
        print("fresh clone: making its .venv (not timed) ...", flush=True)
        subprocess.run(["make", "venv"], cwd=clone, check=True, stdout=subprocess.DEVNULL)
        env = {**os.environ, "XDG_CACHE_HOME": str(cache), "MPLCONFIGDIR": str(cache / "matplotlib")}
        load0 = os.getloadavg()[0]
        import resource

        kids0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        print("fresh clone: make reproduce (timed) ...", flush=True)
        done = subprocess.run(["make", "reproduce"], cwd=clone, env=env, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t0
        kids = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (kids.ru_utime - kids0.ru_utime) + (kids.ru_stime - kids0.ru_stime)
        shutil.rmtree(clone / ".venv", ignore_errors=True)
    row = {"date": datetime.datetime.now().isoformat(timespec="seconds"), "commit": _commit(),
           "wall_s": f"{wall:.1f}", "cpu_s": f"{cpu:.1f}", "cpus": os.cpu_count(), "load_before": f"{load0:.2f}",
           "load_after": f"{os.getloadavg()[0]:.2f}", "exit": done.returncode}
    log = STORAGE / "reproduce_times.csv"
    _append(log, fields, [row])
    print(f"fresh clone: make reproduce {row['wall_s']} s wall, {row['cpu_s']} CPU-s, exit {done.returncode} "
          f"(load {row['load_before']}/{row['load_after']}; appended to {log.relative_to(REPO)})")
    return (0 if done.returncode == 0 else 1), row


def write_summary(study_rows: list[dict], load: tuple[str, str] | None, reference: Path | None = None,
                  fresh: dict | None = None) -> None:
    """``results/benchmarks.md`` from ``results/benchmarks.json``, this run's study rows and the stored
    run it was compared with."""
    import json

    from tests.benchmarks.summary import render

    src = REPO / "results" / "benchmarks.json"
    if not src.is_file():
        return
    out = REPO / "results" / "benchmarks.md"
    ref = json.loads(reference.read_text()) if reference is not None and reference.is_file() else None
    from tests.benchmarks import versus

    out.write_text(render(json.loads(src.read_text()), study_rows, load, ref, RATIO_FACTOR, fresh, versus.read()))
    print(f"wrote {out.relative_to(REPO)}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tests.benchmarks.bench", description=__doc__.split("\n\n")[0])
    mode = ap.add_mutually_exclusive_group()
    mode.add_argument("--save-only", action="store_true", help="store the benchmark run without comparing")
    mode.add_argument("--studies-only", action="store_true", help="only the study wall times")
    mode.add_argument("--no-studies", action="store_true", help="only the pytest benchmarks")
    mode.add_argument("--fresh-clone", action="store_true", help="only make reproduce on a fresh clone")
    a = ap.parse_args(argv)
    rc, rows, load, reference, fresh = 0, [], None, None, None
    if a.fresh_clone:
        return fresh_clone()[0]
    if not a.studies_only:
        rc, load, reference = micro(compare=not a.save_only)
    if not (a.no_studies or a.save_only):
        rc_studies, rows = studies()
        rc_fresh, fresh = fresh_clone()
        rc = rc or rc_studies or rc_fresh
    if not a.studies_only and (rows or a.no_studies or a.save_only):
        write_summary(rows, load, reference, fresh)      # the micro-benchmarks of this run, with its studies if run
    return rc


if __name__ == "__main__":
    sys.exit(main())
