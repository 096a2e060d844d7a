"""The study report: ``results/<study>/report.md`` and ``report.html`` with checks, tables, figures and
interpretation.

:func:`model` turns a run into plain data (headline, check groups by kind of evidence, tolerance reasons,
swap test, parts, not reproduced, readings); :func:`page` lays that out as a page of the report model
(:mod:`benchmarks.harness.pages`), which :func:`write` renders to markdown and to one self-contained HTML
file (figures inline). The nightly report embeds the same page (``StudyRun.report``).
"""
from __future__ import annotations

import dataclasses
import datetime as _dt
from pathlib import Path

import pandas as pd

from jointbench.benchmarks import backends
from jointbench.benchmarks.config import EVIDENCE, Study
from jointbench.benchmarks.harness.pages import (Code, Figure, Items, Page, Paragraph, Section, paragraphs, table,
                                                 to_html, to_markdown)
from jointbench.benchmarks.tables import DIRTY_BANNER
from jointbench.benchmarks.checks import (difference_counts, difference_rows, discriminating_counts, evidence_counts,
                                          fidelity, headline, headline_rows)
from jointbench.core.files import write_text

#: what each kind of evidence means, as the report says it
EVIDENCE_TEXT = {
    "reproduction": "an independent published value or claim, judged by the harness: the headline count",
    "conditional": "passes only under a reading of an ambiguous passage that was chosen by its outcome "
                   "(the reading is named): shown beside the headline, not in it",
    "calibrated": "a free parameter was chosen to match the published value (the parameter is named): "
                  "shown, never counted as a pass",
    "sanity": "arithmetic on the paper's own numbers, or a self-consistency of the harness (e.g. a fit "
              "recovering the simulation's own truth): shown separately",
    "recording": "a value the paper measured on real subjects (a human recording): a simulation reaches it only "
                 "by inventing dynamics the paper does not give, so it is shown beside the reproduced value and "
                 "never counted, pass or miss",
    "unrecorded": "generated before the kind of evidence was recorded",
    "method_difference": "the difference between two methods' published cells (e.g. KBR - skirt), whose cells "
                         "are checked one by one already: counted on their own line, never in the headline",
}


@dataclasses.dataclass
class CheckGroup:
    """The checks of one kind of evidence, with the footnoted reasons of their bands."""

    evidence: str
    passed: int
    total: int
    table: pd.DataFrame
    reasons: list[tuple[str, str]]          # (label, reason)
    misses: list[dict]


def _status(s: str) -> str:
    return "pass" if s == "pass" else "**MISS**"


def _footnotes(comparison: pd.DataFrame) -> tuple[list[str], list[tuple[str, str]]]:
    """A label per row for its tolerance reason (and domain reason), shared reasons sharing a label."""
    labels, reasons, seen = [], [], {}
    for r in comparison.itertuples():
        row = []
        for prefix, text in (("", getattr(r, "tolerance_reason", "")), ("domain: ", getattr(r, "domain_reason", ""))):
            text = "" if pd.isna(text) else str(text)
            if not text:
                continue
            key = prefix + text
            if key not in seen:
                seen[key] = f"[{len(seen) + 1}]"
                reasons.append((seen[key], key))
            row.append(seen[key])
        labels.append(" ".join(row))
    return labels, reasons


def _group(comp: pd.DataFrame, evidence: str) -> CheckGroup:
    cols = ["check", "description", "published", "reproduced", "low", "high", "status", "aggregate", "spread"]
    if evidence == "conditional":
        cols.insert(7, "reading")
    if evidence == "calibrated":
        cols.insert(7, "free_parameter")
    if "out_of_domain" in comp and comp["out_of_domain"].fillna("").astype(str).str.len().gt(0).any():
        cols.append("out_of_domain")
    if "discriminating" in comp and comp["discriminating"].fillna("").astype(str).str.len().gt(0).any():
        cols.append("discriminating")
    t = comp[[c for c in cols if c in comp.columns]].rename(
        columns={"aggregate": "over", "free_parameter": "free parameter",
                 "out_of_domain": "outside the domain (shown, not scored)"})
    t["status"] = t["status"].map(_status)
    labels, reasons = _footnotes(comp)
    t["band: why"] = labels
    misses = [{"check": r.check, "description": r.description, "reproduced": r.reproduced, "low": r.low,
               "high": r.high, "note": r.note} for r in comp[comp["status"] != "pass"].itertuples()]
    return CheckGroup(evidence, int((comp["status"] == "pass").sum()), len(comp), t, reasons, misses)


def _swap_text(swap: dict | None) -> str:
    if not swap or not swap.get("n"):
        return ""
    a, b = swap["estimators"]
    text = (f"**Swap test** (part `{swap['part']}`): with the reproduced values of `{a}` and `{b}` exchanged, "
            f"{swap['pass_swapped']} of the {swap['n']} checks that name one of them still pass ({swap['pass']} pass "
            f"as reproduced); {len(swap['survivors'])} pass both ways and so do not tell the methods apart. ")
    if swap.get("differences"):
        n_surv = len(swap["difference_survivors"])
        text += (f"Of the {swap['differences']} checks of a difference between the two, "
                 + ("none passes both ways." if not n_surv else
                    f"{n_surv} pass both ways: {', '.join(swap['difference_survivors'])}."))
    return text


def model(study: Study, comparison: pd.DataFrame, part_reports: dict, failed: list, meta: dict) -> dict:
    """Everything the report says, as data."""
    groups = []
    if not comparison.empty:
        once = headline_rows(comparison)
        ev = once["evidence"].fillna("unrecorded") if "evidence" in once else None
        for kind in (*EVIDENCE, "unrecorded"):
            sel = (once[ev == kind] if ev is not None
                   else once if kind == "unrecorded" else once.iloc[0:0])
            if len(sel):
                groups.append(_group(sel, kind))
        diff = difference_rows(comparison)
        if len(diff):
            groups.append(_group(diff, "method_difference"))
    sections = {"results": [], "interpretation": []}
    for name, rep in part_reports.items():
        sections[study.parts[name].report_section].append((name, rep))
    commit = meta["commit"]
    return {
        "title": f"{study.title}: {'reproduction' if study.checks else 'comparison'} report",
        "dirty": commit.endswith("-dirty"),
        "commit": commit,
        "generated": f"{_dt.datetime.now(_dt.timezone.utc):%Y-%m-%d %H:%M} UTC",
        "meta": meta,
        "comparison": comparison,
        "counts": evidence_counts(comparison),
        "differences": difference_counts(comparison),
        "headline": headline(comparison),
        "groups": groups,
        "swap": _swap_text(meta.get("method_swap")),
        "results": sections["results"],
        "interpretation": sections["interpretation"],
        "failed": failed,
        "not_reproduced": list(study.not_reproduced),
        "readings": list(study.readings),
    }


def _headline_sentence(counts: dict, differences: tuple[int, int] | None = None,
                       discriminating: tuple[int, int] | None = None) -> str:
    rep = counts.get("reproduction", (0, 0))
    out = f"**Reproduction: {rep[0]} of {rep[1]} checks pass.** (One published value or claim each.)"
    if discriminating:
        out += (f" **{discriminating[0]} of those {discriminating[1]} passes tell the compared methods apart** (column "
                "`discriminating`: they would miss with the other method's reproduced values, and their band does "
                "not hold the other method's published cell unless argued).")
    if differences:
        out += (f" **Method differences: {differences[0]} of {differences[1]}** (gaps between two methods' "
                "published cells, whose cells are counted above already: their own line, not in the headline).")
    beside = []
    for kind, what in (("conditional", "each under a reading chosen by its outcome"),
                       ("calibrated", "a free parameter was chosen to match them: not evidence, not counted"),
                       ("sanity", "arithmetic or self-consistency"),
                       ("recording", "values measured on the paper's subjects: shown, not counted"),
                       ("unrecorded", "kind of evidence not recorded")):
        if kind in counts:
            p, n = counts[kind]
            beside.append(f"{kind} {p} of {n} pass ({what})")
    if beside:
        out += " Beside them, not in that count: " + "; ".join(beside) + "."
    return out


def _checks_section(m: dict, empty: bool) -> Section:
    sec = Section("Checks against the published values", anchor="checks")
    if empty:
        return sec.add(Paragraph("_(no check belongs to the parts run)_"))
    sec.add(Paragraph(_headline_sentence(m["counts"], m.get("differences"), discriminating_counts(m["comparison"]))),
            Paragraph("`reproduced` combines the seeds as `over` says; `spread` is min to max over seeds; a pass "
                      "needs low <= reproduced <= high. The reason for each band is under its table (column "
                      "`band: why`)."))
    fid = fidelity(m["comparison"])
    if len(fid):
        sec.add(Section("Fidelity", anchor="fidelity", body=[
            Paragraph("Per published table, figure or claim: the checks that pass (reproduction: the headline; "
                      "conditional: under a named reading; method differences: gaps between two methods' cells), "
                      "those shown beside them, and how many misses a one-line cause explains (key `cause` of the "
                      "check; the full reason is under 'Misses and their likely reasons')."),
            table("", fid)]))
    if m["swap"]:
        sec.add(Paragraph(m["swap"]))
    for g in m["groups"]:
        title = "Method differences" if g.evidence == "method_difference" else f"{g.evidence.capitalize()} checks"
        sec.add(Section(f"{title} ({g.passed} of {g.total} pass)",
                        anchor=f"checks-{g.evidence}", body=[
                            Paragraph(f"_{EVIDENCE_TEXT[g.evidence].capitalize()}._"),
                            table("", g.table, classes=lambda r: {"status": "pass" if r["status"] == "pass"
                                                                  else "miss"}),
                            Paragraph("Why the bands are what they are:"),
                            Items([f"{label} {text}" for label, text in g.reasons])]))
    misses = [f"**{r['check']}** ({g.evidence}; {r['description']}): reproduced {r['reproduced']:.4g}, "
              f"expected [{r['low']:.4g}, {r['high']:.4g}]. {r['note'] or 'No explanation recorded yet.'}"
              for g in m["groups"] for r in g.misses]
    if misses:
        sec.add(Section("Misses and their likely reasons", anchor="misses", body=[Items(misses)]))
    return sec


def _part(study: Study, name: str, rep, folder) -> Section:
    """The section of one part: its text, tables and figures (or why there are none)."""
    sec = Section(f"{name}: {getattr(rep, 'title', '') or study.parts[name].description}", anchor=f"part-{name}")
    if rep is None:
        return sec.add(Paragraph("_(no figure maker for this protocol)_"))
    if isinstance(rep, str):
        return sec.add(Paragraph(f"Figures could not be drawn: {rep}"))
    sec.add(*paragraphs(rep.text))
    sec.add(*[table(title, df, empty="no rows") for title, df in rep.tables])
    sec.add(*[Figure(caption, path=(folder / fname) if folder is not None else Path(fname))
              for fname, caption in rep.figures])
    return sec


def plugins_sentence(plugins: dict[str, str] | None) -> str:
    """`` Plugin estimators (distribution==version, source hash): ...`` of the estimators from outside
    jointbench a run's cases used (the code that made their numbers, beside the commit); '' when none."""
    if not plugins:
        return ""
    return (" Plugin estimators (distribution==version, source hash; also the rows' column `plugin`): "
            + "; ".join(f"`{name}` from `{text}`" for name, text in sorted(plugins.items())) + ".")


def page(study: Study, comparison: pd.DataFrame, part_reports: dict, failed: list, meta: dict) -> Page:
    """The report as a page of the report model (every section of :func:`model`, in reading order)."""
    m = model(study, comparison, part_reports, failed, meta)
    folder = meta.get("stage") or meta.get("folder")      # where the figures are (being) written
    folder = None if folder is None else Path(folder)
    body: list = [Paragraph(
        f"Study `{study.id}` (paper `{study.paper}`), config `{study.path.name}`. Generated {m['generated']} at "
        f"commit `{m['commit']}` by `{meta['command']}`: {meta['n_cases']} cases ({meta['n_cached']} from cache, "
        f"{len(failed)} failed, {len(meta.get('refused') or [])} refused), {meta['wall_s']:.1f} s wall time on "
        f"{meta.get('ran_on') or str(meta['workers']) + ' worker(s)'}."
        + plugins_sentence(meta.get("plugins")))]
    if meta["parts"] != list(study.parts):
        lines = [f"This run computed the parts {', '.join(meta['parts'])}"
                 + (f"; the parts {', '.join(meta['from_cache'])} come from the cache of an earlier run with the "
                    "same code" if meta["from_cache"] else "") + "."]
        missing = [p for p in study.parts if p not in meta["parts"] and p not in meta["from_cache"]]
        if missing:
            lines.append(f"Not included (not run with this code): {', '.join(missing)}.")
        body.append(Paragraph("\n".join(lines)))
    body.append(_checks_section(m, comparison.empty))
    body += backends.sections(study, comparison, meta)
    body += [_part(study, name, rep, folder) for name, rep in m["results"]]
    if failed:
        body.append(Section("Failed cases", anchor="failed", cls="changed", body=[
            Items([f"`{r.case.case_id}`: {r.error}" for r in failed]),
            Paragraph("Tracebacks are in `failures.log`.")]))
    if meta.get("refused"):
        body.append(Section("Refused cases", anchor="refused", cls="changed", body=[
            Paragraph("Cases with an estimate the output gate refused (the gate of `jointbench estimate` and "
                      "`api.fit`: a prediction of the fitted record worse than a constant, a non-finite value "
                      "or bound, an interval of zero width). Counted apart from failures; a refused estimate "
                      "is never scored; the case's other fits (other estimators or inputs), when it has any, "
                      "keep their rows."),
            Items([f"`{r.case.case_id}` ({'every fit' if r.status == 'refused' else 'some fits'}): "
                   f"{'; '.join(r.refusals)}" for r in meta["refused"]])]))
    body.append(Section("Not reproduced", anchor="not-reproduced", body=[
        Paragraph("Published tables, figures and values this study leaves out, and why (from the study config):"),
        Items([f"**{n.item}**: {n.reason}" for n in m["not_reproduced"]]) if m["not_reproduced"] else
        Paragraph("_(nothing: the study config lists no left-out item)_")]))
    interp = Section("Interpretation", anchor="interpretation", body=[
        Paragraph("Every reading chosen for an ambiguous or underspecified passage (also a comment in the "
                  "config):"),
        Items([f"**{r.id}. {r.topic}.** Paper: {r.passage} Reading: {r.reading}"
               + (f" Alternatives: {r.alternatives}" if r.alternatives else "") for r in m["readings"]])])
    if m["interpretation"]:
        interp.add(Paragraph("What the candidate readings give (parts run for the interpretation, not checked):"),
                   *[_part(study, name, rep, folder) for name, rep in m["interpretation"]])
    body.append(interp)
    body.append(Section("Reproduce", anchor="reproduce", body=[Code(meta["command"])]))
    banner = (f"**WARNING: {DIRTY_BANNER}.** Commit `{m['commit']}` has uncommitted changes, so these numbers "
              "cannot be traced to any commit. Commit the code, then regenerate.") if m["dirty"] else ""
    links = [(f"#{s.anchor}", s.title.split(":")[0]) for s in body if isinstance(s, Section) and s.anchor
             and not s.anchor.startswith("part-")]
    return Page(m["title"], body, banner=banner, banner_cls="dirty" if m["dirty"] else "", links=links)


def render(study: Study, comparison: pd.DataFrame, part_reports: dict, failed: list, meta: dict) -> str:
    """Markdown text of the report."""
    folder = meta.get("folder")
    return to_markdown(page(study, comparison, part_reports, failed, meta), folder and Path(folder))


def write(folder: Path, report: Page) -> tuple[Path, Path]:
    """``report.md`` (figures linked) and ``report.html`` (self-contained, figures inline) in ``folder``."""
    folder = Path(folder)
    write_text(folder / "report.md", to_markdown(report, folder))
    write_text(folder / "report.html", to_html(report))
    return folder / "report.md", folder / "report.html"


def relocate(page: Page, old: Path, new: Path) -> None:
    """Point the page's figure files under ``old`` (the staging folder of a run) to ``new`` (where the set
    was moved), so that the page object still finds them (the nightly report inlines them)."""
    old, new = Path(old), Path(new)

    def walk(body) -> None:
        for b in body:
            if isinstance(b, Section):
                walk(b.body)
            elif isinstance(b, Figure) and b.path is not None and Path(b.path).is_relative_to(old):
                object.__setattr__(b, "path", new / Path(b.path).relative_to(old))
    walk(page.body)
