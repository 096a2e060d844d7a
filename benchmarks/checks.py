"""A study's checks: its tidy rows judged against the published values, one row per check (``checks.csv``).

:func:`judge` is the one place a check passes or misses (value, trend and difference checks, each over its
selected rows and domain, aggregated over seeds as the check says); the rest counts what was judged: the
headline (reproduction checks), the method differences beside it, the counts per kind of evidence
(:func:`evidence_counts`), the fidelity per published table or figure (:func:`fidelity`), and whether a
check tells two methods apart (:func:`swap_survival`). Reports, the README's status block and the nightly
read the judged ``status``; nothing re-judges a check.
"""
from __future__ import annotations

import dataclasses
from typing import Mapping

import numpy as np
import pandas as pd

from jointbench.benchmarks.config import Check
from jointbench.benchmarks.selection import select
from jointbench.benchmarks.tables import stamp


def _out_of_domain(rows: pd.DataFrame, part: str, where: Mapping, domain: Mapping) -> pd.DataFrame:
    """The rows of ``part`` matching ``where`` but not ``domain``."""
    every = select(rows, part, where)
    inside = select(every, part, domain)
    return every[~every.index.isin(inside.index)]


def aggregate(values, how: str) -> float:
    """One of :data:`benchmarks.config.AGGREGATES` over finite values (``std``: sample SD, ddof 1)."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if how == "std":
        return float(np.std(v, ddof=1)) if len(v) > 1 else np.nan
    return float(getattr(np, how)(v)) if len(v) else np.nan


def _grouped(sel: pd.DataFrame, column: str, how: str) -> pd.Series:
    """Aggregate of the finite values per value of ``column`` (numeric order when numeric)."""
    sel = sel[np.isfinite(sel["value"].to_numpy(float))]
    if not column:
        return pd.Series({"": aggregate(sel["value"], how)}) if len(sel) else pd.Series(dtype=float)
    if column not in sel.columns:
        return pd.Series(dtype=float)
    g = sel.groupby(sel[column].astype(str), sort=False)["value"].agg(lambda v: aggregate(v, how))
    num = pd.to_numeric(pd.Series(g.index, index=g.index), errors="coerce")
    order = num.sort_values().index if num.notna().all() else sorted(g.index)
    return g.loc[list(order)]


def _trend(c: Check, rows: pd.DataFrame) -> tuple[float, str, int]:
    """Largest move against ``c.direction`` between consecutive aggregates over ``c.over``; with ``c.by``, the
    trend of each value of ``by`` (e.g. each parameter of one claim), the largest move of any of them."""
    sel = select(rows, c.part, {**c.select, **(c.domain or {})})
    if c.by and c.by not in sel.columns:
        return np.nan, "", len(sel)
    groups = [("", sel)] if not c.by else list(sel.groupby(sel[c.by].astype(str), sort=True))
    worst, spreads = np.nan, []
    for key, g in groups:
        m = _grouped(g, c.over, c.aggregate)
        if len(m) < 2:
            return np.nan, "", len(sel)
        d = np.diff(m.to_numpy(float))
        against = float(np.max(d if c.direction == "decreasing" else -d))
        worst = against if not np.isfinite(worst) else max(worst, against)
        body = ", ".join(f"{k}: {v:.4g}" for k, v in m.items())
        spreads.append((f"{key}: " if c.by else "") + f"{c.over} -> {body}")
    return worst, "; ".join(spreads), len(sel)


def _differences(c: Check, a: pd.DataFrame, b: pd.DataFrame) -> pd.Series:
    ma, mb = _grouped(a, c.by, c.aggregate), _grouped(b, c.by, c.aggregate)
    keys = [k for k in ma.index if k in mb.index]
    return pd.Series({k: float(ma[k] - mb[k]) for k in keys}, dtype=float)


def _difference(c: Check, rows: pd.DataFrame) -> tuple[float, str, int]:
    """aggregate(select) - aggregate(versus) per value of ``c.by``; the group closest to (or furthest
    beyond) a bound is the reproduced value."""
    dom = c.domain or {}
    a = select(rows, c.part, {**c.select, **dom})
    b = select(rows, c.part, {**(c.versus or {}), **dom})
    d = _differences(c, a, b)
    if d.empty:
        return np.nan, "", len(a) + len(b)
    margin = np.minimum(d - c.low, c.high - d)
    worst = margin.idxmin()
    spread = ", ".join(f"{k}: {v:+.4g}" for k, v in d.items()) if c.by else ""
    return float(d[worst]), (f"{c.by} -> {spread}" if c.by else spread), len(a) + len(b)


def _outside(c: Check, rows: pd.DataFrame) -> str:
    """What the rows outside the check's domain give (shown, not scored)."""
    if not c.domain:
        return ""
    if c.kind == "difference":
        a = _out_of_domain(rows, c.part, c.select, c.domain)
        b = _out_of_domain(rows, c.part, c.versus or {}, c.domain)
        d = _differences(c, a, b)
        body = ", ".join(f"{k}: {v:+.4g}" for k, v in d.items())
        return f"{c.by} -> {body}" if body else ""
    col = next(iter(c.domain))
    out = _out_of_domain(rows, c.part, c.select, c.domain)
    g = _grouped(out, col if col in out.columns else "", c.aggregate)
    return f"{col} -> " + ", ".join(f"{k}: {v:.4g}" for k, v in g.items()) if len(g) else ""


CHECK_COLUMNS = ["check", "description", "published", "reproduced", "low", "high", "status", "evidence",
                      "reading", "free_parameter", "aggregate", "n", "spread", "out_of_domain", "part",
                      "source", "tolerance_reason", "domain_reason", "note", "count", "target", "cause",
                      "discriminating", "discrimination", "commit"]


def verdict(c: Check, rows: pd.DataFrame, part: str | None = None) -> tuple[float, str, int, float, float, str]:
    """One check judged on ``rows``: ``(reproduced, spread, n, low, high, status)``, the one place a
    pass or a miss is decided (:func:`judge` for ``checks.csv``; a figure showing a check's bounds against
    another part's rows passes that ``part``, the check's own ``aggregate`` applied to them).
    ``status`` is ``"pass"`` when the reproduced value lies in ``[low, high]``, ``"miss"`` otherwise (a
    non-finite one included: no result)."""
    if part is not None and part != c.part:
        c = dataclasses.replace(c, part=part)
    if c.kind == "value":
        v = select(rows, c.part, {**c.select, **(c.domain or {})})["value"].to_numpy(float)
        v = v[np.isfinite(v)]
        n = len(v)
        rep = aggregate(v, c.aggregate)
        spread = f"{v.min():.4g} to {v.max():.4g}" if n > 1 else ""
        low, high = c.low, c.high
    else:
        rep, spread, n = _trend(c, rows) if c.kind == "trend" else _difference(c, rows)
        low, high = (-np.inf, c.slack) if c.kind == "trend" else (c.low, c.high)
    status = "pass" if np.isfinite(rep) and low <= rep <= high else "miss"
    return rep, spread, n, low, high, status


def judge(checks: tuple[Check, ...], rows: pd.DataFrame, parts_run: set[str], commit: str = "",
          swap=None) -> pd.DataFrame:
    """One row per check: published, reproduced, tolerance, pass/miss, and the kind of evidence.

    Check kinds: ``value`` (aggregate over seeds of the selected rows within [low, high]); ``trend``
    (aggregates per value of ``over`` must move in ``direction``; reproduced = the largest move against
    it, which must not exceed ``slack``); ``difference`` (aggregate of ``select`` minus that of ``versus``
    per value of ``by``, every one within [low, high]; reproduced = the one closest to or beyond a bound).
    A check's ``domain`` restricts the scored rows; what the rest gives is in ``out_of_domain``. A miss's
    ``note`` and every ``cause`` are filled from the judged values (:func:`render_note`). With ``swap`` (a
    study's ``method_swap``: part and two estimators) each check of one of the two methods says whether it
    tells them apart (:func:`discrimination`).
    ``commit`` is stamped on every row (``...-dirty`` rows say loudly that they must not be committed).
    """
    judged = {c.id: (c, verdict(c, rows)) for c in checks if c.part in parts_run}
    figures = {cid: (v[0], c.published) for cid, (c, v) in judged.items()}
    swapped = swap_estimators(rows, swap.part, tuple(swap.estimators)) if swap is not None else None
    out = []
    for c, (rep, spread, n, low, high, status) in judged.values():
        if not np.isfinite(rep):
            note = "no result: the case failed or produced no such metric (see the failed cases)"
        elif status == "pass":
            note = ""
        else:
            side = c.if_missed_below if rep < low else c.if_missed_above if rep > high else ""
            note = render_note(side or c.if_missed, c, rep, figures)
        tells, why = discrimination(c, checks, swapped, swap, low, high) if swap is not None else ("", "")
        out.append({"check": c.id, "description": c.description, "published": c.published,
                    "reproduced": rep, "low": low, "high": high, "status": status,
                    "evidence": c.evidence, "reading": c.reading, "free_parameter": c.free_parameter,
                    "aggregate": c.aggregate if c.kind == "value" else f"{c.kind} of {c.aggregate}s",
                    "n": n, "spread": spread, "out_of_domain": _outside(c, rows), "part": c.part,
                    "source": c.source, "tolerance_reason": c.tolerance_reason,
                    "domain_reason": c.domain_reason, "note": note, "count": c.count, "target": c.target,
                    "cause": render_note(c.cause, c, rep, figures),
                    "discriminating": tells, "discrimination": why, "commit": stamp(commit)})
    return pd.DataFrame(out, columns=CHECK_COLUMNS)


class _Figure(float):
    """A judged value in a note: formats as a float (``n/a`` when not finite or not run), ``.published``."""

    def __new__(cls, value, published):
        self = super().__new__(cls, value)
        self.published = published
        return self

    def __format__(self, spec: str) -> str:
        if not np.isfinite(self):
            return "n/a"
        return format(float(self), spec or ".4g")


def render_note(text: str, c: Check, value: float, figures: Mapping[str, tuple[float, object]]) -> str:
    """A note with its placeholders filled: ``{value}`` / ``{published}`` this check's reproduced and published
    values, ``{ID}`` / ``{ID.published}`` another check's (``n/a`` for a check not judged in this run). The
    one way a note states a result figure (issue 35: notes typed by hand had gone stale against the rows)."""
    if not text or "{" not in text:
        return text
    fields = {cid: _Figure(v, p) for cid, (v, p) in figures.items()}
    fields["value"] = _Figure(value, c.published)
    fields["published"] = c.published

    class _Missing(dict):
        def __missing__(self, key):
            return _Figure(np.nan, "n/a")

    return text.format_map(_Missing(fields))


def counterpart(c: Check, checks, estimators) -> Check | None:
    """The check of the same published cell for the other of the two ``estimators`` (same part, kind and
    selection but the estimator), or None."""
    a, b = (str(e) for e in estimators)
    mine = str(c.select.get("estimator", ""))
    if mine not in (a, b) or c.kind != "value":
        return None
    other = b if mine == a else a
    want = {**c.select, "estimator": other}
    for d in checks:
        if d.part == c.part and d.kind == "value" and dict(d.select) == want and d.domain == c.domain \
                and d.aggregate == c.aggregate:
            return d
    return None


def _number(published) -> float | None:
    try:
        return float(published)
    except (TypeError, ValueError):
        return None


def discrimination(c: Check, checks, swapped: pd.DataFrame, swap, low: float, high: float) -> tuple[str, str]:
    """Whether check ``c`` of one of the two compared methods tells them apart: ``("no", why)`` when it passes
    with the other method's reproduced values too, or when the other method's published cell lies inside its
    band (and no ``discrimination_reason`` argues the band); ``("yes", why)`` otherwise; ``("", "")`` for a
    check of neither method or outside the swap's part (issue 35: the per-cell bands of Table I could not see
    the paper's factor-2 method differences)."""
    if c.part != swap.part or str(c.select.get("estimator", "")) not in {str(e) for e in swap.estimators} \
            or c.kind != "value":
        return "", ""
    other = counterpart(c, checks, swap.estimators)
    other_name = next(str(e) for e in swap.estimators if str(e) != str(c.select.get("estimator")))
    if verdict(c, swapped)[5] == "pass":
        return "no", f"passes with {other_name}'s reproduced values too"
    pub = _number(other.published) if other is not None else None
    if pub is not None and low <= pub <= high:
        if c.discrimination_reason.strip():
            return "yes", f"{other_name}'s published {pub:g} lies inside the band; argued: {c.discrimination_reason}"
        return "no", f"{other_name}'s published {pub:g} lies inside the band"
    return "yes", f"misses with {other_name}'s reproduced values" + (
        f"; {other_name}'s published {pub:g} lies outside the band" if pub is not None else "")


def _is_difference(comparison: pd.DataFrame) -> pd.Series:
    """Rows of checks counted as method differences (their own line, never in the headline)."""
    if "count" not in comparison:
        return pd.Series(False, index=comparison.index)
    return comparison["count"].fillna("headline").astype(str) == "method_difference"


def headline_rows(comparison: pd.DataFrame) -> pd.DataFrame:
    """The checks that count one published value or claim each (method differences left out)."""
    return comparison[~_is_difference(comparison)]


def difference_rows(comparison: pd.DataFrame) -> pd.DataFrame:
    """The method-difference checks (differences of published cells already checked one by one)."""
    return comparison[_is_difference(comparison)]


def evidence_counts(comparison: pd.DataFrame) -> dict[str, tuple[int, int]]:
    """Evidence kind -> (passes, checks), in :data:`benchmarks.config.EVIDENCE` order (kinds present),
    over the checks of one published value each: method-difference checks (``count``) are left out, so
    that a published cell is counted once (:func:`difference_counts` counts them).

    The headline of a report or of the README is ``reproduction`` alone; the others go beside it.
    A comparison written before the evidence column existed counts under ``unrecorded``.
    """
    from jointbench.benchmarks.config import EVIDENCE

    if comparison.empty:
        return {}
    comparison = headline_rows(comparison)
    ev = comparison["evidence"].fillna("unrecorded") if "evidence" in comparison else \
        pd.Series("unrecorded", index=comparison.index)
    out = {}
    for kind in (*EVIDENCE, "unrecorded"):
        sel = comparison[ev == kind]
        if len(sel):
            out[kind] = (int((sel["status"] == "pass").sum()), len(sel))
    return out


def difference_counts(comparison: pd.DataFrame) -> tuple[int, int] | None:
    """(passes, checks) of the method-difference checks, or None when there are none."""
    d = difference_rows(comparison) if not comparison.empty else comparison
    if d.empty:
        return None
    return int((d["status"] == "pass").sum()), len(d)


def discriminating_counts(comparison: pd.DataFrame) -> tuple[int, int] | None:
    """(passing reproduction checks that tell the compared methods apart, passing reproduction checks), or None
    when no check of the study says (no ``method_swap``; a comparison written before the column existed)."""
    if comparison.empty or "discriminating" not in comparison:
        return None
    rep = headline_rows(comparison)
    rep = rep[(rep["evidence"] == "reproduction") & (rep["status"] == "pass")]
    said = rep["discriminating"].astype(object).fillna("").astype(str)
    if not (said != "").any():
        return None
    return int((said == "yes").sum()), len(rep)


def headline(comparison: pd.DataFrame) -> str:
    """``reproduction 9 of 14 pass; method differences 20 of 30; beside them: conditional 3 of 3, ...``"""
    counts = evidence_counts(comparison)
    diff = difference_counts(comparison)
    if not counts and not diff:
        return "no checks"
    rep = counts.get("reproduction")
    head = f"reproduction {rep[0]} of {rep[1]} pass" if rep else "no reproduction check"
    disc = discriminating_counts(comparison)
    if disc:
        head += f" ({disc[0]} of those {disc[1]} passes tell the compared methods apart)"
    if diff:
        head += f"; method differences {diff[0]} of {diff[1]}"
    notes = {"calibrated": " (not counted)", "recording": " (measured on subjects: not counted)"}
    others = [f"{k} {p} of {n}{notes.get(k, '')}" for k, (p, n) in counts.items() if k != "reproduction"]
    return head + ("; beside them: " + ", ".join(others) if others else "")


def method_specific(checks, estimators: tuple[str, str]) -> list[Check]:
    """Checks whose ``select`` or ``versus`` names one of ``estimators``."""
    names = set(estimators)
    return [c for c in checks
            if str(c.select.get("estimator", "")) in names or str((c.versus or {}).get("estimator", "")) in names]


def swap_estimators(rows: pd.DataFrame, part: str, estimators: tuple[str, str]) -> pd.DataFrame:
    """The rows with the two estimators' labels exchanged in ``part`` (their reproduced values swapped)."""
    a, b = estimators
    out = rows.copy()
    inside = out["part"] == part
    col = out["estimator"].astype(str)
    out.loc[inside & (col == a), "estimator"] = b
    out.loc[inside & (col == b), "estimator"] = a
    return out


def swap_survival(checks, rows: pd.DataFrame, part: str, estimators: tuple[str, str]) -> dict:
    """How many method-specific checks of ``part`` pass with the two estimators' values swapped.

    Returns ``n`` (method-specific checks), ``pass`` and ``pass_swapped`` (how many pass as reproduced
    and with the values swapped), ``survivors`` (ids passing both ways: they do not tell the methods
    apart) and ``difference_survivors`` (those of kind ``difference`` comparing the two estimators).
    """
    own = [c for c in method_specific(checks, estimators) if c.part == part]
    if not own:
        return {"n": 0, "pass": 0, "pass_swapped": 0, "survivors": [], "difference_survivors": []}
    before = judge(tuple(own), rows, {part}).set_index("check")["status"]
    after = judge(tuple(own), swap_estimators(rows, part, estimators), {part}).set_index("check")["status"]
    both = [c.id for c in own if before[c.id] == "pass" and after[c.id] == "pass"]
    between = {c.id for c in own if c.kind == "difference"
               and {str(c.select.get("estimator")), str((c.versus or {}).get("estimator"))} == set(estimators)}
    return {"n": len(own), "pass": int((before == "pass").sum()), "pass_swapped": int((after == "pass").sum()),
            "survivors": both, "difference_survivors": [i for i in both if i in between],
            "differences": len(between)}


def _target(row) -> str:
    """The published table or figure a check belongs to: its ``target``, else its family (the id up to the
    first '-') with the first phrase of its source."""
    t = str(row.get("target", "") or "").strip()
    if t and t != "nan":
        return t
    fam = str(row["check"]).split("-")[0]
    src = str(row.get("source", "") or "")
    head = src.replace("'", ":").split(":")[0].split(";")[0].strip().rstrip(",")
    head += ")" * max(0, head.count("(") - head.count(")"))   # a cut inside a bracket closes it
    return f"{fam} ({head})" if head and head != "nan" else fam


def fidelity(comparison: pd.DataFrame) -> pd.DataFrame:
    """Per published table or figure: the checks passing (reproduction, conditional, method differences),
    the calibrated and sanity ones beside them, the misses explained by a one-line cause and those causes
    (``cause: n checks``), from the comparison rows (never typed)."""
    if comparison.empty:
        return pd.DataFrame()
    comp = comparison.copy()
    comp["_target"] = [_target(r) for r in comp.to_dict("records")]
    comp["_diff"] = _is_difference(comp)
    ev = comp["evidence"].fillna("unrecorded") if "evidence" in comp else pd.Series("unrecorded", index=comp.index)
    cause = (comp["cause"].astype(object).fillna("").astype(str).replace("nan", "") if "cause" in comp
             else pd.Series("", index=comp.index))
    passed = comp["status"] == "pass"
    recs = []
    for target in dict.fromkeys(comp["_target"]):
        sel = comp["_target"] == target

        def count(mask):             # counted on the masks (cutting the frame for each cost 0.1 CPU-s a README)
            m = sel & mask
            n = int(m.sum())
            return f"{int((m & passed).sum())} of {n}" if n else "–"
        miss = sel & (comp["status"] != "pass")
        causes = cause[miss]
        named = causes[causes != ""].value_counts()
        recs.append({"published": target,
                     "reproduction": count(~comp["_diff"] & (ev == "reproduction")),
                     "conditional": count(~comp["_diff"] & (ev == "conditional")),
                     "method differences": count(comp["_diff"]),
                     "calibrated (not counted)": count(~comp["_diff"] & (ev == "calibrated")),
                     "sanity": count(~comp["_diff"] & (ev == "sanity")),
                     "recordings (not counted)": count(~comp["_diff"] & (ev == "recording")),
                     "misses explained": f"{int((causes != '').sum())} of {int(miss.sum())}" if miss.any() else "–",
                     "causes of the misses": "; ".join(f"{c}: {n} check{'s' if n > 1 else ''}"
                                                       for c, n in named.items())})
    return pd.DataFrame(recs)
