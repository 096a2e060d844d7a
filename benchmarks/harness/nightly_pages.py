"""The pages of ``jointbench nightly``: ``index.html`` (what changed first, then every study against its
published values, with its tables and figures) and ``history.html`` (passing checks, compute time and key
metrics over the recorded nightlies), plus ``summary.md`` (the index as markdown)."""
from __future__ import annotations

import datetime as _dt
import json
import math
import os
from pathlib import Path

import numpy as np
import pandas as pd

from jointbench.benchmarks.harness.history import History
from jointbench.benchmarks.harness.diff import by_evidence
from jointbench.benchmarks.harness.pages import (Figure, Items, Page, Paragraph, Section, Table, figure_png, table,
                                                 to_html, to_markdown)
from jointbench.benchmarks.checks import headline
from jointbench.core.files import write_text

VERDICT_TEXT = {
    "regression": "REGRESSION",
    "ok": "No regression against the previous nightly",
    "baseline": "Baseline: the first nightly of this history (nothing to compare with yet)",
}


def _flipped_tables(flips: list[dict]) -> list[Table]:
    """The checks that flipped, one table per kind of evidence (regressions of every kind count)."""
    cls_change = lambda r: {"change": "bad" if r["change"] == "regressed"  # noqa: E731
                            else "good" if r["change"] == "improved" else "warn"}
    cols = {"study": "study", "check": "check", "evidence": "evidence", "description": "description",
            "before": "before", "after": "after", "change": "change", "reproduced_before": "reproduced before",
            "reproduced_after": "reproduced now", "low": "low", "high": "high"}
    out = []
    for kind, g in by_evidence(pd.DataFrame(flips)) if flips else []:
        n = g["change"].value_counts()
        counts = ", ".join(f"{n[c]} {c}" for c in ("regressed", "improved", "changed", "new", "gone") if c in n)
        out.append(table(f"Checks that flipped: {kind} ({counts})", g, cols, classes=cls_change))
    return out


def _changed_section(outcomes, regressions: list[str]) -> Section:
    sec = Section("What changed", anchor="changed", cls="changed" if regressions else "")
    if regressions:
        sec.add(Paragraph("Regressions (the reasons for the non-zero exit status):"), Items(list(regressions)))
    flips, moved, drifts, fails, fixed, cover, times, changes = [], [], [], [], [], [], [], []
    for o in outcomes:
        d = o.diff
        if d is None:
            continue
        flips += [{"study": o.study, **r} for r in d.flipped.to_dict("records")]
        c = d.checks
        same = c[(c["change"] == "") & ~_same(c["reproduced_before"], c["reproduced_after"])]
        moved += [{"study": o.study, **r} for r in same.to_dict("records")]
        for r in d.drift.to_dict("records"):
            drifts.append({"study": o.study, **r, "drifted": f"{r['n_drifted']} of {r['n_compared']}"})
        fails += [{"study": o.study, **r} for r in d.new_failures.to_dict("records")]
        fixed += [{"study": o.study, **r} for r in d.fixed.to_dict("records")]
        cover += [{"study": o.study, **r} for r in d.coverage.to_dict("records")]
        times += [{"study": o.study, **r} for r in d.timings_grew.to_dict("records")]
        changes += [{"study": o.study, "what": w, "before": a, "after": b} for w, a, b in d.changes]
    candidates = [
        (_flipped_tables(flips), "no check changed status"),
        ([table("Checks whose reproduced value moved (same status)", pd.DataFrame(moved),
                {"study": "study", "check": "check", "evidence": "evidence", "after": "status",
                 "reproduced_before": "reproduced before", "reproduced_after": "reproduced now", "low": "low",
                 "high": "high"} if moved else {})] if moved else [], "no check's reproduced value moved"),
        ([table("Metrics that drifted beyond their threshold", pd.DataFrame(drifts),
                {"study": "study", "part": "part", "estimator": "estimator", "metric": "metric",
                 "drifted": "values drifted", "max_abs_delta": "largest |change|", "limit": "threshold",
                 "example": "example case", "before": "before", "after": "now"} if drifts else {},
                note="A value drifted when |now - before| > abs + rel |before| (configs/nightly.yaml); "
                     "'before' and 'now' are those of the example case.")] if drifts else [],
         "no metric drifted beyond its threshold"),
        ([table("Cases that fail now and did not", pd.DataFrame(fails))] if fails else [],
         "no case fails that did not"),
        ([table("Cases that failed before and pass now", pd.DataFrame(fixed))] if fixed else [], "no case was fixed"),
        ([table("Values present in only one of the two runs", pd.DataFrame(cover),
                {"study": "study", "part": "part", "only_before": "only before", "only_after": "only now"})]
         if cover else [], "every value is in both runs"),
        ([table("Compute times that grew", pd.DataFrame(times),
                {"study": "study", "part": "part", "cases": "cases", "before_s": "before (s)",
                 "after_s": "now (s)", "ratio": "ratio"},
                note="Sum of the wall times of the cases computed in both runs (cached ones left out).")]
         if times else [], "no part's compute time grew beyond the threshold"),
        ([table("Code, config and versions that changed", pd.DataFrame(changes))] if changes else [],
         "code, config and library versions are the same"),
    ]
    compared = [o for o in outcomes if o.diff is not None]
    if not compared:
        sec.add(Paragraph("No study has a previous nightly run to compare with: this run is the baseline."))
    else:
        sec.add(*[t for tables, _ in candidates for t in tables])
        quiet = [phrase for tables, phrase in candidates if not tables]
        if quiet:
            sec.add(Section("Unchanged", body=[Paragraph(
                f"Compared with the previous nightly ({', '.join(o.study for o in compared)}): "
                + "; ".join(quiet) + ".")]))
    errors = [f"{o.study}: {o.error}" for o in outcomes if o.error]
    if errors:
        sec.add(Section("Studies that could not run", body=[Items(errors)], cls="changed"))
    return sec


def _same(a: pd.Series, b: pd.Series) -> pd.Series:
    """Equal values, NaN equal to NaN."""
    x, y = a.to_numpy(float), b.to_numpy(float)
    return pd.Series((x == y) | (np.isnan(x) & np.isnan(y)), index=a.index)


def _summary_table(outcomes) -> Table:
    recs = []
    for o in outcomes:
        if o.error:
            recs.append({"study": o.study, "run": "", "compared with run": "", "cases": "", "failed": "",
                         "checks": "", "wall time (s)": "", "regressions": "could not run"})
            continue
        recs.append({"study": f"[{o.study}](#study-{o.study})", "run": o.run.run_id,
                     "compared with run": o.previous or "", "cases": len(o.run.results),
                     "failed": len(o.run.failed), "checks": headline(o.run.checks),
                     "wall time (s)": round(o.run.wall_s, 1), "regressions": len(o.regressions)})
    return table("", pd.DataFrame(recs),
                 classes=lambda r: {"regressions": "bad" if r["regressions"] not in (0, "") else "good"})


def _study_section(o, site: Path) -> Section:
    """The study's own report page (the same model as its report.md and report.html), under a line
    with the run and links to the report files."""
    run = o.run
    rel = Path(os.path.relpath(run.folder, site)).as_posix()
    sec = Section(f"{run.study.id}: {run.study.title}", anchor=f"study-{run.study.id}")
    sec.add(Paragraph(f"Run {run.run_id}: {len(run.results)} cases, {len(run.failed)} failed; "
                      f"{headline(run.checks)}; {run.wall_s:.1f} s. Its report: "
                      f"[{rel}/report.html]({rel}/report.html) ([markdown]({rel}/report.md)); the same report "
                      "follows."))
    if run.report is not None:
        sec.add(*run.report.body)
    return sec


def _history_data(history: History, nightly_id: int, verdict: str) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Per nightly and study: passing checks, wall time; and every check's reproduced value."""
    nights = history.nightlies()
    nights = nights[(nights["status"] == "complete") | (nights["id"] == nightly_id)].sort_values("id")
    recs, checks = [], []
    for n in nights.itertuples():
        for study, run_id in history.nightly_runs(int(n.id)).items():
            run = history.run(run_id)
            if run["status"] != "ok":
                continue
            c = history.checks(run_id)
            recs.append({"nightly": int(n.id), "started": n.started,
                         "commit": n.commit_id + ("-dirty" if n.dirty else ""),
                         "verdict": verdict if int(n.id) == nightly_id else str(n.verdict),
                         "study": study, "run": run_id,
                         "pass": int((c["status"] == "pass").sum()), "checks": len(c), "wall_s": run["wall_s"]})
            c = c.assign(nightly=int(n.id), study=study)
            checks.append(c)
    return pd.DataFrame(recs), (pd.concat(checks, ignore_index=True) if checks else pd.DataFrame())


def _default_key_checks(c: pd.DataFrame, n: int = 6) -> list[str]:
    """Checks against a published number first (a value with a scale), in file order."""
    def numeric(text) -> bool:
        try:
            return isinstance(json.loads(text), (int, float))
        except (TypeError, ValueError):
            return False

    ids = list(dict.fromkeys(c["check_id"]))
    pub = dict(zip(c["check_id"], c["published"]))
    return ([i for i in ids if numeric(pub[i])] + [i for i in ids if not numeric(pub[i])])[:n]


def _history_figures(study: str, per: pd.DataFrame, checks: pd.DataFrame, key: tuple[str, ...]) -> list[Figure]:
    from matplotlib.ticker import MaxNLocator

    from jointbench.benchmarks.figures import new_figure

    s = per[per["study"] == study].sort_values("nightly")
    figs = []
    fig, (a, b) = new_figure(1, 2, figsize=(10, 3))
    a.plot(s["nightly"], s["pass"], "o-", color="tab:green", label="checks passing")
    a.plot(s["nightly"], s["checks"], "--", color="0.5", label="checks")
    for ax in (a, b):
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    a.set_xlabel("nightly")
    a.set_ylabel("checks")
    a.set_ylim(bottom=0)
    a.legend(fontsize=8)
    b.plot(s["nightly"], s["wall_s"], "o-", color="tab:blue")
    b.set_xlabel("nightly")
    b.set_ylabel("wall time (s)")
    b.set_ylim(bottom=0)
    fig.suptitle(f"{study}: passing checks and wall time per nightly")
    figs.append(Figure(f"{study}: checks passing (of all checks) and wall time of the study, per nightly run.",
                       figure_png(fig)))
    c = checks[checks["study"] == study] if len(checks) else checks
    if len(c):
        ids = [k for k in key if k in set(c["check_id"])] or _default_key_checks(c)
        ncol = min(3, len(ids))
        nrow = math.ceil(len(ids) / ncol)
        fig, axes = new_figure(nrow, ncol, figsize=(3.6 * ncol, 2.6 * nrow), squeeze=False)
        for ax, cid in zip(axes.flat, ids):
            d = c[c["check_id"] == cid].sort_values("nightly")
            x, y = d["nightly"].to_numpy(float), d["reproduced"].to_numpy(float)
            lo, hi = d["low"].to_numpy(float), d["high"].to_numpy(float)
            ax.plot(x, y, "o-", color="k", ms=4)
            ok = d["status"].to_numpy() == "pass"
            ax.plot(x[~ok], y[~ok], "o", color="tab:red", ms=5)
            if np.isfinite(lo).any() or np.isfinite(hi).any():
                ax.fill_between(x, np.where(np.isfinite(lo), lo, np.nanmin(y)),
                                np.where(np.isfinite(hi), hi, np.nanmax(y)), color="tab:green", alpha=0.15, lw=0,
                                step="mid")
            ax.set_title(cid, fontsize=9)
            ax.xaxis.set_major_locator(MaxNLocator(integer=True))
            ax.tick_params(labelsize=7)
        for ax in list(axes.flat)[len(ids):]:
            ax.set_visible(False)
        fig.suptitle(f"{study}: key checks, reproduced value per nightly (green: tolerance; red: miss)", fontsize=10)
        fig.tight_layout()
        figs.append(Figure(f"{study}: reproduced value of the key checks ({', '.join(ids)}) per nightly; the "
                           "shaded band is the tolerance, red points are misses.", figure_png(fig)))
    return figs


def write_pages(history: History, nightly_id: int, verdict: str, regressions: list[str], outcomes, config,
                site: Path, command: str) -> tuple[Path, Path]:
    from jointbench.benchmarks.harness import fingerprint

    commit, dirty = fingerprint.git_state()
    env = fingerprint.environment()
    stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    facts = [("nightly", str(nightly_id)), ("generated", stamp), ("commit", commit + ("-dirty" if dirty else "")),
             ("code hash", fingerprint.code_hash()),
             ("machine", f"{env['host']} ({env['machine']}, {env['cpus']} cpus)"),
             ("python", env["python"]),
             ("libraries", ", ".join(f"{k} {v}" for k, v in sorted(env["packages"].items()))),
             ("config", str(config.path.name)), ("command", command)]
    prev = sorted({o.previous for o in outcomes if o.previous})
    if prev:
        facts.append(("compared with runs", ", ".join(map(str, prev))))
    banner = VERDICT_TEXT[verdict] + (f": {len(regressions)} reason(s) below" if regressions else "")
    sections = [_changed_section(outcomes, regressions),
                Section("Studies", anchor="studies", body=[_summary_table(outcomes)])]
    sections += [_study_section(o, site) for o in outcomes if not o.error]
    index = Page(title="JointBench nightly report", banner=f"**{banner}**", banner_cls=verdict, facts=facts,
                 links=[("#changed", "What changed"), ("#studies", "Studies"), ("history.html", "History")],
                 body=sections, footer=f"Written by `{command}`; the run history is results/history.sqlite "
                                           "(`jointbench history`, `jointbench diff RUN_A RUN_B`).")
    per, checks = _history_data(history, nightly_id, verdict)
    hsections = []
    if len(per):
        wide = per.assign(cell=[f"{p} of {c}" for p, c in zip(per["pass"], per["checks"])]).pivot_table(
            index=["nightly", "started", "commit", "verdict"], columns="study", values="cell", aggfunc="first")
        wide = wide.reset_index().sort_values("nightly", ascending=False)
        hsections.append(Section("Nightly runs", anchor="runs",
                                 body=[table("Checks passing per study", wide.fillna(""))]))
        for study in sorted(per["study"].unique()):
            hsections.append(Section(study, anchor=f"history-{study}",
                                     body=_history_figures(study, per, checks, config.key_checks.get(study, ()))))
    hist = Page(title="JointBench nightly history",
                facts=[("generated", stamp), ("nightlies", str(per["nightly"].nunique() if len(per) else 0))],
                links=[("index.html", "Latest nightly")], body=hsections,
                footer="Every nightly run recorded in results/history.sqlite.")
    write_text(site / "index.html", to_html(index))
    write_text(site / "history.html", to_html(hist))
    write_text(site / "summary.md", to_markdown(index, site))
    return site / "index.html", site / "history.html"
