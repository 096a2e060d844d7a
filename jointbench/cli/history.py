"""``jointbench history [RUN]``, ``jointbench diff RUN_A RUN_B`` and ``jointbench cache [prune]``."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from jointbench.cli.common import positive_int

if TYPE_CHECKING:  # pragma: no cover - pandas is imported where a table is made (`jointbench estimate
    import pandas as pd  # --list` builds this parser and must start fast)


def _history(args):
    """The run history of ``--out`` (:class:`jointbench.api.History`)."""
    from jointbench import api

    return api.History(args.out)


def _text(df: pd.DataFrame) -> str:
    return df.to_string(index=False, na_rep="", max_colwidth=70) if len(df) else "  (none)"


def _list_runs(args) -> int:
    import pandas as pd

    h = _history(args)
    if args.run is not None:
        return _show_run(h, args.run)
    runs = h.runs(study=args.study, kind=args.kind, limit=args.limit)
    if runs.empty:
        print("no runs recorded" + (f" for study {args.study}" if args.study else ""))
        return 0
    runs = runs.sort_values("id")
    t = pd.DataFrame({
        "run": runs["id"], "kind": runs["kind"], "study": runs["study"], "started": runs["started"].str[:19],
        "status": runs["status"], "commit": runs["commit_id"] + runs["dirty"].map({1: "-dirty", 0: ""}),
        "cases": [f"{d}/{n}" if s != "ok" else str(n)
                  for d, n, s in zip(runs["n_done"], runs["n_cases"], runs["status"])],
        "failed": runs["n_failed"].fillna(0).astype(int), "refused": runs["n_refused"].fillna(0).astype(int),
        "cached": runs["n_cached"].fillna(0).astype(int),
        "checks": [f"{p}/{c}" if c else "" for p, c in zip(runs["n_pass"], runs["n_checks"])],
        "wall s": runs["wall_s"].round(1)})
    print(_text(t))
    return 0


def _show_run(h, run_id: int) -> int:
    r = h.run(run_id)
    env = r["environment"]
    cases = h.cases(run_id)
    n_refused = int((cases["status"] == "refused").sum()) if len(cases) else 0
    print(f"run {r['id']} ({r['kind']}{', nightly ' + str(r['nightly_id']) if r['nightly_id'] else ''}): "
          f"study {r['study']}, status {r['status']}")
    for k, v in [("parts", ", ".join(r["parts"])), ("started", r["started"]), ("ended", r["ended"] or ""),
                 ("commit", r["commit_id"] + ("-dirty" if r["dirty"] else "")), ("code hash", r["code_hash"]),
                 ("config hash", r["config_hash"]), ("python", r["python"]),
                 ("packages", ", ".join(f"{k} {v}" for k, v in sorted(env.get("packages", {}).items()))),
                 ("plugins", "; ".join(f"{k}: {v}" for k, v in sorted((env.get("plugins") or {}).items()))),
                 ("machine", r["machine"]), ("command", r["command"] or ""), ("workers", r["workers"]),
                 ("cases", f"{r['n_done']} of {r['n_cases']} done, {r['n_failed'] or 0} failed, {n_refused} refused, "
                           f"{r['n_cached'] or 0} from the cache"),
                 ("wall time", f"{r['wall_s']:.1f} s" if r["wall_s"] is not None else ""), ("error", r["error"] or "")]:
        if v not in ("", None):
            print(f"  {k:12s} {v}")
    checks = h.checks(run_id)
    if len(checks):
        print(f"\nchecks ({int((checks['status'] == 'pass').sum())} of {len(checks)} pass):")
        print(_text(checks.assign(evidence=checks["evidence"].fillna("unrecorded"))[
            ["check_id", "evidence", "part", "status", "reproduced", "low", "high", "description"]]))
    for status in ("failed", "refused"):
        sel = cases[cases["status"] == status]
        if len(sel):
            print(f"\n{status} cases:")
            print(_text(sel[["case_id", "error"]]))
    if len(cases):
        per = cases.groupby("part", sort=False).agg(cases=("case_id", "size"),
                                                    failed=("status", lambda s: int((s == "failed").sum())),
                                                    refused=("status", lambda s: int((s == "refused").sum())),
                                                    cached=("cached", "sum"), compute_s=("wall_time_s", "sum"))
        print("\nparts:")
        print(_text(per.reset_index().round(2)))
    return 0


def _diff(args) -> int:
    import pandas as pd

    from jointbench.benchmarks.harness.diff import by_evidence

    h = _history(args)
    d = h.diff(args.run_a, args.run_b, config=args.config)
    a, b = d.before, d.after
    print(f"{d.study}: run {args.run_a} ({a['started'][:19]}, {a['status']}) -> run {args.run_b} "
          f"({b['started'][:19]}, {b['status']})")
    sections = [
        ("code, config and versions that changed", pd.DataFrame(d.changes, columns=["what", "before", "after"])),
        ("checks that changed status (grouped by kind of evidence)",
         pd.concat([g for _, g in by_evidence(d.flipped)])[["check", "evidence", "before", "after", "change",
                                                            "reproduced_before", "reproduced_after"]]
         if len(d.flipped) else d.flipped),
        ("metrics that drifted beyond their threshold", d.drift),
        ("cases that fail now and did not", d.new_failures),
        ("cases fixed", d.fixed),
        ("values in only one run", d.coverage),
        ("compute time per part (cases computed in both runs)", d.timings),
    ]
    changed = [r for r in d.checks.itertuples() if r.reproduced_before != r.reproduced_after
               and not (pd.isna(r.reproduced_before) and pd.isna(r.reproduced_after))]
    for title, df in sections:
        print(f"\n{title}:")
        print(_text(df))
    print(f"\n{len(changed)} of {len(d.checks)} checks' reproduced values differ at all")
    if d.regressions:
        print("\nregressions:")
        for line in d.regressions:
            print(f"  {line}")
    return 1 if (args.strict and d.regressions) else 0


def _cache(args) -> int:
    from jointbench.benchmarks.harness import cache as cache_mod
    from jointbench.benchmarks.study import CACHE_FOLDER, results_root

    folder = results_root(Path(args.out) if args.out else None) / CACHE_FOLDER
    entries = list(cache_mod.entries(folder))
    size = sum(p.stat().st_size for p in entries)
    if args.action == "prune":
        from jointbench.benchmarks.harness.history import History
        from jointbench.benchmarks.study import HISTORY_FILE

        with History(folder.parent / HISTORY_FILE, create=False) as h:
            keep = h.keys_in_use(args.keep_runs)
        gone = cache_mod.prune(folder, keep, dry_run=args.dry_run)
        freed = sum(p.stat().st_size for p in gone) if args.dry_run else None
        print(f"{folder}: {'would remove' if args.dry_run else 'removed'} {len(gone)} of {len(entries)} entries"
              + (f" ({freed / 1e6:.1f} MB)" if freed is not None else "")
              + f"; kept those used by the last {args.keep_runs} run(s) of each study")
        return 0
    print(f"{folder}: {len(entries)} entries, {size / 1e6:.1f} MB")
    return 0


def add_parsers(sub) -> None:
    out = dict(metavar="DIR", help="results folder (default: ./results)")
    p = sub.add_parser("history", help="list recorded runs, or show one (results/history.sqlite)")
    p.add_argument("run", nargs="?", type=positive_int, help="a run id: show it in full")
    p.add_argument("--study", help="only runs of this study")
    p.add_argument("--kind", choices=["run", "nightly"], help="only this kind of run")
    p.add_argument("--limit", type=positive_int, default=30, help="the latest N runs (default 30)")
    p.add_argument("--out", **out)
    p.set_defaults(func=_list_runs)
    p = sub.add_parser("diff", help="what changed between two recorded runs of a study")
    p.add_argument("run_a", type=positive_int, metavar="RUN_A")
    p.add_argument("run_b", type=positive_int, metavar="RUN_B")
    p.add_argument("--config", metavar="FILE", help="thresholds (default: configs/nightly.yaml)")
    p.add_argument("--strict", action="store_true", help="exit 1 when something regressed")
    p.add_argument("--out", **out)
    p.set_defaults(func=_diff)
    p = sub.add_parser("cache", help="size of the case cache; 'prune' removes entries no recent run used")
    p.add_argument("action", nargs="?", choices=["prune"], help="remove unused entries")
    p.add_argument("--keep-runs", type=positive_int, default=3,
                   help="keep the entries used by the last N finished runs of each study (default 3)")
    p.add_argument("--dry-run", action="store_true", help="only say what would be removed")
    p.add_argument("--out", **out)
    p.set_defaults(func=_cache)
