"""Paired comparisons of a comparison grid's methods over the same realizations (realization r is the same
simulation for every method of a scenario, and for both tuning columns): every pair of methods per
feasible scenario, tuning column and per-realization metric (two-sided Wilcoxon signed-rank, Holm over
the pairs of that family), the win counts over scenarios, and the tuned column against the paper column.

References
----------
Wilcoxon, "Individual comparisons by ranking methods", Biometrics Bulletin 1 (1945) 80-83; Holm, "A simple
sequentially rejective multiple test procedure", Scand. J. Statist. 6 (1979) 65-70.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from jointbench.benchmarks.compare import stats as cs
from jointbench.benchmarks.compare.tables import ALPHA, METRICS, feasibility, primary_backend, with_nothing_to_tune


def paired(rows: pd.DataFrame, table: pd.DataFrame) -> pd.DataFrame:
    """Wilcoxon signed-rank tests of every pair of methods over the realizations they share, per feasible
    cell of the primary backend, tuning and per-realization metric; Holm's correction over the pairs of
    each (cell, tuning, metric)."""
    rows = with_nothing_to_tune(rows)
    primary = primary_backend(rows)
    feas = feasibility(table)
    if "realization" not in rows.columns:
        return pd.DataFrame()
    per = rows[(rows["status"] == "ok") & rows["realization"].notna() & (rows["backend"] == primary)
               & rows["metric"].isin([m for m, x in METRICS.items() if x[2] and x[1]])]
    recs = []
    for (cell, tuning, metric), g in per.groupby(["cell", "tuning", "metric"], sort=False):
        if not feas.get((cell, primary), np.nan) > 0:
            continue
        values = {m: dict(zip(h["realization"].astype(int), h["value"].astype(float)))
                  for m, h in g.groupby("method", sort=False)}
        for r in cs.paired_comparisons(values, METRICS[metric][1], ALPHA):
            recs.append({"cell": cell, "tuning": tuning, "metric": metric, **r})
    return pd.DataFrame(recs)


def families(pairs: pd.DataFrame, alpha: float = ALPHA) -> pd.DataFrame:
    """One row per family of paired tests (scenario, tuning column, metric): ``pairs`` (m), ``n`` (the most
    realizations a pair of it shares), ``smallest p`` (:func:`stats.min_signed_rank_p` of n: every
    difference of one sign), ``Holm threshold`` (alpha / m: the smallest p must be below it for anything
    to be rejected), ``attainable`` (whether it is), ``rejected`` (pairs with a verdict)."""
    cols = ["cell", "tuning", "metric", "pairs", "n", "smallest p", "Holm threshold", "attainable", "rejected"]
    if pairs.empty:
        return pd.DataFrame(columns=cols)
    fam = pairs.groupby(["cell", "tuning", "metric"], sort=False).agg(
        pairs=("p", "size"), n=("n", "max"), rejected=("verdict", lambda v: int((v.fillna("") != "").sum())))
    fam = fam.reset_index()
    fam["smallest p"] = [cs.min_signed_rank_p(int(n)) for n in fam["n"]]
    fam["Holm threshold"] = [cs.holm_first_threshold(int(m), alpha) for m in fam["pairs"]]
    fam["attainable"] = [cs.rejection_attainable(int(n), int(m), alpha) for n, m in zip(fam["n"], fam["pairs"])]
    return fam[cols]


def attainability_text(pairs: pd.DataFrame, alpha: float = ALPHA) -> str:
    """Sentences for the report: in how many families a rejection is attainable at all (:func:`families`),
    and, in the largest families that can reject, how many of the fewest realizations among them may point
    the other way."""
    fam = families(pairs, alpha)
    if fam.empty:
        return ""
    ok = int(fam["attainable"].sum())
    m = int(fam["pairs"].max())
    can = fam[(fam["pairs"] == m) & fam["attainable"]]
    n = int(can["n"].min()) if len(can) else 0        # the fewest realizations of the largest families that can
    text = (f" A rejection is attainable in {ok} of the {len(fam)} families ({100 * ok / len(fam):.0f} %): a "
            f"family of m pairs over n realizations can reject only if 2/2^n, the smallest exact p-value (every "
            f"difference of one sign), is below Holm's first threshold {alpha:g}/m.")
    if ok < len(fam):
        blind = fam[~fam["attainable"]]
        text += (f" In the {len(blind)} others (n = {int(blind['n'].min())} to {int(blind['n'].max())} realizations, "
                 f"m up to {int(blind['pairs'].max())} pairs) no data could reach significance: more realizations are "
                 "needed for a verdict there (the counts 'ahead' say which way the median paired difference points).")
    d = max((k for k in range(n + 1) if cs.rejection_attainable(n, m, alpha, k)), default=None)
    if n and d is not None:
        text += (f" In the largest family (m = {m} pairs, n = {n}) a pair can still be significant when its "
                 f"{d} smallest of {n} differences point the other way (exact p "
                 f"{cs.discordant_signed_rank_p(n, d):.2g} < {alpha:g}/{m} = {alpha / m:.2g}).")
    return text


def wins(pairs: pd.DataFrame, metric: str, tuning: str) -> pd.DataFrame:
    """Method x method: 'w/a/n' = significantly better in w, ahead (median paired difference) in a, of
    the n feasible scenarios where the row's method and the column's were compared on ``metric``."""
    if pairs.empty:
        return pd.DataFrame()
    sel = pairs[(pairs["metric"] == metric) & (pairs["tuning"] == tuning)]
    if sel.empty:
        return pd.DataFrame()
    counts = cs.win_counts({c: g.to_dict("records") for c, g in sel.groupby("cell", sort=False)})
    methods = sorted({m for pair in counts for m in pair})
    out = []
    for a in methods:
        rec = {"method (row) against column": a}
        for b in methods:
            c = counts.get((a, b))
            rec[b] = "" if c is None else f"{c['wins']}/{c['ahead']}/{c['of']}"
        out.append(rec)
    return pd.DataFrame(out)


def beats_sentences(pairs: pd.DataFrame, metric: str, tuning: str, top: int = 12) -> list[str]:
    """'A beats B on <metric> in w of n scenarios' for the pairs with the most significant wins."""
    if pairs.empty:
        return []
    sel = pairs[(pairs["metric"] == metric) & (pairs["tuning"] == tuning)]
    counts = cs.win_counts({c: g.to_dict("records") for c, g in sel.groupby("cell", sort=False)})
    best = sorted(((c["wins"], c["of"], a, b) for (a, b), c in counts.items() if c["wins"]), reverse=True)[:top]
    head = METRICS[metric][0]
    return [f"`{a}` beats `{b}` on {head} in {w} of {n} scenarios" for w, n, a, b in best]


def tuning_effect(rows: pd.DataFrame, table: pd.DataFrame, metric: str = "vaf_stiffness") -> pd.DataFrame:
    """Per method, the tuned column against the paper column on ``metric`` over the same realizations of
    each feasible cell (primary backend): signed-rank p-values, Holm over the methods of a cell; counts of
    the cells where tuning helped or hurt significantly, and the median over cells of the median paired
    change. Methods with nothing to tune are left out (the same fit in both columns)."""
    if "realization" not in rows.columns or not (rows["tuning"] == "tuned").any():
        return pd.DataFrame()
    primary = primary_backend(rows)
    feas = feasibility(table)
    better = METRICS[metric][1]
    per = rows[(rows["status"] == "ok") & rows["realization"].notna() & (rows["backend"] == primary)
               & (rows["metric"] == metric)]
    recs = []
    for cell, g in per.groupby("cell", sort=False):
        if not feas.get((cell, primary), np.nan) > 0:
            continue
        fam = []
        for method, h in g.groupby("method", sort=False):
            a, b = ({int(r): v for r, v in zip(h.loc[h["tuning"] == c, "realization"],
                                                h.loc[h["tuning"] == c, "value"])} for c in ("tuned", "paper"))
            shared = [r for r in a if r in b and np.isfinite(a[r]) and np.isfinite(b[r])]
            if shared:
                d = np.array([a[r] - b[r] for r in shared], float)
                fam.append({"method": method, "change": float(np.median(d)), "p": cs.signed_rank_p(d)})
        for rec, ph in zip(fam, cs.holm([f["p"] for f in fam])):
            good = rec["change"] > 0 if better == "max" else rec["change"] < 0
            rec["helped"] = bool(ph < ALPHA and good)
            rec["hurt"] = bool(ph < ALPHA and not good and rec["change"] != 0)
            recs.append(rec)
    if not recs:
        return pd.DataFrame()
    df = pd.DataFrame(recs)
    head = METRICS[metric][0].replace(" (%)", " (points)")
    out = df.groupby("method", sort=True).agg(scenarios=("p", "size"), helped=("helped", "sum"), hurt=("hurt", "sum"),
                                              change=("change", "median")).reset_index()
    return out.rename(columns={"helped": "tuned significantly better", "hurt": "tuned significantly worse",
                               "change": f"median change of {head}"})
