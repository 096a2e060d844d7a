"""``python -m tools.catalogue [--python PY] [--kind KIND ...] [--case REGEX] [--jobs N] [--out DIR]``.

Runs every case of the catalogue of bad inputs (tools/catalogue/kind_*.py) against the jointbench that
``--python`` imports (default: this interpreter), each in its own folder and process with a timeout, and
writes ``DIR/summary.md`` (counts by kind and class) and ``DIR/cases.csv`` (one row per case).
``make catalogue`` runs it; ``make test`` never does.
"""
from __future__ import annotations

import argparse
import concurrent.futures as cf
import csv
import re
import sys
import time
from collections import Counter
from pathlib import Path

from tools.catalogue import core
from tools.catalogue import (kind_config, kind_disk, kind_executor, kind_grid, kind_history,  # noqa: F401
                             kind_inputs, kind_nightly, kind_profiles, kind_runs)


def summary(rows: list[dict], python: str, seconds: float) -> str:
    classes = list(core.CLASSES) + sorted({r["class"] for r in rows} - set(core.CLASSES))
    kinds = list(dict.fromkeys(r["kind"] for r in rows))
    count = Counter((r["kind"], r["class"]) for r in rows)
    head = "| kind | cases | " + " | ".join(classes) + " |"
    lines = [f"# Catalogue of bad inputs: {len(rows)} cases", "",
             f"jointbench of `{python}`, {seconds:.0f} s. Classes: tools/catalogue/core.py.", "", head,
             "|" + "---|" * (len(classes) + 2)]
    for k in kinds + ["all"]:
        n = [sum(count[(kk, c)] for kk in (kinds if k == "all" else [k])) for c in classes]
        lines.append(f"| {k} | {sum(n)} | " + " | ".join(str(x) for x in n) + " |")
    lines += ["", "## Cases not clean", "", "| case | class | exit | message |", "|---|---|---|---|"]
    for r in rows:
        if r["class"] != "clean":
            msg = str(r["message"]).replace("|", "\\|")
            lines.append(f"| {r['kind']}/{r['case']} | {r['class']} | {r['rc']} | {msg} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tools.catalogue", description=__doc__.splitlines()[0])
    ap.add_argument("--python", default=sys.executable, help="the Python whose jointbench is measured")
    ap.add_argument("--kind", action="append", help="only these kinds")
    ap.add_argument("--case", help="only cases whose kind/name matches this regular expression")
    ap.add_argument("--jobs", type=int, default=2, help="cases at once (default 2)")
    ap.add_argument("--out", default="/tmp/jointbench-catalogue", help="folder of summary.md and cases.csv")
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    args = ap.parse_args(argv)
    cases = [c for c in core.CASES if (not args.kind or c.kind in args.kind)
             and (not args.case or re.search(args.case, c.id))]
    if args.list:
        for c in cases:
            print(f"{c.id:55s} expect {c.expect}")
        print(f"{len(cases)} cases")
        return 0
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.monotonic()
    rows = []
    with cf.ThreadPoolExecutor(args.jobs) as pool:
        futs = {pool.submit(core.run_one, c, args.python): c for c in cases}
        for i, fut in enumerate(cf.as_completed(futs), 1):
            r = fut.result()
            rows.append(r)
            print(f"[{i}/{len(cases)}] {r['class']:13s} {r['kind']}/{r['case']} ({r['seconds']} s): "
                  f"{str(r['message'])[:110]}", flush=True)
    order = {c.id: i for i, c in enumerate(cases)}
    rows.sort(key=lambda r: order[f"{r['kind']}/{r['case']}"])
    with open(out / "cases.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["kind", "case", "class", "rc", "seconds", "stderr_lines", "message"])
        w.writeheader()
        w.writerows(rows)
    text = summary(rows, args.python, time.monotonic() - t0)
    (out / "summary.md").write_text(text)
    print(text.split("## Cases not clean")[0])
    print(f"wrote {out / 'summary.md'} and {out / 'cases.csv'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
