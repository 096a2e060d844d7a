"""The study report: ``results/<study>/report.md`` with checks, tables, figures and interpretation."""
from __future__ import annotations

import datetime as _dt

import pandas as pd

from benchmarks import backends
from benchmarks.config import Study
from benchmarks.tables import markdown


def _status(s: str) -> str:
    return "pass" if s == "pass" else "**MISS**"


def render(study: Study, comparison: pd.DataFrame, part_reports: dict, failed: list, meta: dict) -> str:
    """Markdown text of the report."""
    lines = [f"# {study.title}: reproduction report", ""]
    lines.append(f"Study `{study.id}` (paper `{study.paper}`), config `{study.path.name}`. Generated "
                 f"{_dt.datetime.now(_dt.timezone.utc):%Y-%m-%d %H:%M} UTC at commit `{meta['commit']}` by "
                 f"`{meta['command']}`: {meta['n_cases']} cases ({meta['n_cached']} from cache, "
                 f"{len(failed)} failed), {meta['wall_s']:.1f} s wall time on {meta['workers']} worker(s).")
    lines.append("")
    if meta["parts"] != list(study.parts):
        lines.append(f"This run computed the parts {', '.join(meta['parts'])}"
                     + (f"; the parts {', '.join(meta['from_cache'])} come from the cache of an earlier run "
                        "with the same code" if meta["from_cache"] else "") + ".")
        missing = [p for p in study.parts if p not in meta["parts"] and p not in meta["from_cache"]]
        if missing:
            lines.append(f"Not included (not run with this code): {', '.join(missing)}.")
        lines.append("")
    lines += ["## Checks against the published values", ""]
    if comparison.empty:
        lines.append("_(no check belongs to the parts run)_")
    else:
        n_pass = int((comparison["status"] == "pass").sum())
        lines.append(f"{n_pass} of {len(comparison)} checks pass. `reproduced` combines the seeds as `over` "
                     "says; `spread` is min to max over seeds; a pass needs low <= reproduced <= high.")
        lines.append("")
        t = comparison[["check", "description", "published", "reproduced", "low", "high", "status",
                        "aggregate", "spread"]].rename(columns={"aggregate": "over"})
        t["status"] = t["status"].map(_status)
        lines.append(markdown(t))
        misses = comparison[comparison["status"] != "pass"]
        if len(misses):
            lines += ["### Misses and their likely reasons", ""]
            for r in misses.itertuples():
                lines.append(f"- **{r.check}** ({r.description}): reproduced {r.reproduced:.4g}, expected "
                             f"[{r.low:.4g}, {r.high:.4g}]. {r.note or 'No explanation recorded yet.'}")
            lines.append("")
    lines += backends.section(study, comparison, meta)
    sections = {"results": [], "interpretation": []}
    for name, rep in part_reports.items():
        sections[study.parts[name].report_section].append((name, rep))
    for name, rep in sections["results"]:
        lines += _part(study, name, rep, "##")
    if failed:
        lines += ["## Failed cases", ""]
        for r in failed:
            lines.append(f"- `{r.case.case_id}`: {r.error}")
        lines += ["", "Tracebacks are in `failures.log`.", ""]
    lines += ["## Interpretation", "",
              "Every reading chosen for an ambiguous or underspecified passage (also a comment in the config):", ""]
    for r in study.readings:
        lines.append(f"- **{r.id}. {r.topic}.** Paper: {r.passage} Reading: {r.reading}"
                     + (f" Alternatives: {r.alternatives}" if r.alternatives else ""))
    if sections["interpretation"]:
        lines += ["", "What the candidate readings give (parts run for the interpretation, not checked):", ""]
        for name, rep in sections["interpretation"]:
            lines += _part(study, name, rep, "###")
    lines += ["", "## Reproduce", "", "```", meta["command"], "```", ""]
    return "\n".join(lines)


def _part(study: Study, name: str, rep, heading: str) -> list[str]:
    """The section of one part: its text, tables and figures (or why there are none)."""
    lines = [f"{heading} {name}: {study.parts[name].description}", ""]
    if rep is None:
        return lines + ["_(no figure maker for this protocol)_", ""]
    if isinstance(rep, str):
        return lines + [f"Figures could not be drawn: {rep}", ""]
    if rep.text:
        lines += [rep.text, ""]
    for title, df in rep.tables:
        lines += [f"**{title}**", "", markdown(df)]
    for fname, caption in rep.figures:
        lines += [f"![{caption}]({fname})", "", f"_{caption}_", ""]
    return lines
