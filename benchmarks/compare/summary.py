"""The summary of a comparison grid over its scenarios: per metric and tuning column, Friedman's test of
whether the methods' ranks differ at all, Nemenyi's post-hoc test of every pair and the critical-difference
diagram (Demšar 2006), each scenario a block. The statistics are scipy's (Friedman) and scikit-posthocs'
(Nemenyi, the diagram); this module chooses the blocks and methods, and writes the rows and figures.

The test needs every method scored in every scenario it uses (a complete block design), while a grid has
methods that run on some scenarios only (KBR and skirt need a multisine; the framework's scenario runs five
methods): :func:`block_design` drops, one at a time, the scenario or method with the largest share of
missing values until none is missing, and the rows name what was left out. The cells of one base scenario
at two noise levels are not independent data sets: the test treats them as separate blocks, as Demšar's
data sets, which the report says.

References
----------
Friedman, "The use of ranks to avoid the assumption of normality implicit in the analysis of variance",
J. Am. Statist. Assoc. 32 (1937) 675-701. Nemenyi, *Distribution-free multiple comparisons*, PhD thesis,
Princeton University (1963). Demšar, "Statistical comparisons of classifiers over multiple data sets",
J. Mach. Learn. Res. 7 (2006) 1-30, Sec. 3.2.2 (Friedman, eq. of chi^2_F; Nemenyi's critical difference)
and Fig. 1 (the critical-difference diagram).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from jointbench.benchmarks.compare import oracle
from jointbench.benchmarks.compare import pairs as cpairs
from jointbench.benchmarks.compare.tables import ALPHA, METRICS

#: columns of the tests' rows (one per metric and tuning column)
TEST_COLUMNS = ["metric", "tuning", "scenarios", "methods", "friedman_chi2", "p", "verdict", "left out (methods)",
                "left out (scenarios)"]
#: columns of the ranks' rows (one per metric, tuning column and method: the leaderboard)
RANK_COLUMNS = ["metric", "tuning", "method", "mean_rank", "position", "tied_with_best", "nemenyi_p_vs_best",
                "median_value", "scenarios"]


def ranked_values(table: pd.DataFrame, metric: str, tuning: str, backend: str) -> pd.DataFrame:
    """Scenarios x methods of the values that were ranked (finite, feasible scenario, the ranked backend;
    :func:`tables.full_table`'s ``rank``), NaN where a method has none."""
    sel = table[(table["metric"] == metric) & (table["tuning"] == tuning) & (table["backend"] == backend)
                & np.isfinite(table["rank"].astype(float))]
    if sel.empty:
        return pd.DataFrame()
    return sel.pivot_table(index="cell", columns="method", values="value", aggfunc="first", sort=False)


def block_design(values: pd.DataFrame) -> tuple[pd.DataFrame, list[str], list[str]]:
    """The complete block design in ``values`` (scenarios x methods, NaN = missing): repeatedly drop the
    scenario or the method with the largest share of missing values (a method on a tie; then the last in
    order) until none is missing. Returns the design, the methods and the scenarios left out."""
    m = values.copy()
    gone_methods, gone_cells = [], []
    while m.size and m.isna().to_numpy().any():
        col_share = m.isna().mean(axis=0)
        row_share = m.isna().mean(axis=1)
        if col_share.max() >= row_share.max():
            worst = col_share[col_share == col_share.max()].index[-1]
            gone_methods.append(str(worst))
            m = m.drop(columns=worst)
        else:
            worst = row_share[row_share == row_share.max()].index[-1]
            gone_cells.append(str(worst))
            m = m.drop(index=worst)
    return m, gone_methods, gone_cells


def mean_ranks(design: pd.DataFrame, better: str) -> pd.Series:
    """Each method's mean rank over the scenarios (1 = best in a scenario, ties share the mean rank)."""
    from scipy.stats import rankdata

    key = -design.to_numpy(float) if better == "max" else design.to_numpy(float)
    r = rankdata(key, axis=1, method="average")
    return pd.Series(r.mean(axis=0), index=design.columns).sort_values(kind="stable")


def friedman(design: pd.DataFrame) -> tuple[float, float]:
    """Friedman's chi^2 and its p-value over the methods (columns) of a complete block design (scipy).

    References
    ----------
    Friedman (1937); Demšar (2006), Sec. 3.2.2.
    """
    from scipy.stats import friedmanchisquare

    res = friedmanchisquare(*(design[c].to_numpy(float) for c in design.columns))
    return float(res.statistic), float(res.pvalue)


def nemenyi(design: pd.DataFrame) -> pd.DataFrame:
    """Nemenyi's post-hoc p-values of every pair of methods (scikit-posthocs), method x method.

    References
    ----------
    Nemenyi (1963); Demšar (2006), Sec. 3.2.2.
    """
    import scikit_posthocs as sp

    p = sp.posthoc_nemenyi_friedman(design.reset_index(drop=True))
    p.index = p.columns = list(design.columns)
    return p


def summarize(table: pd.DataFrame, backend: str, alpha: float = ALPHA) -> tuple[pd.DataFrame, pd.DataFrame, dict]:
    """The summary over scenarios of every ranked metric and tuning column on ``backend``.

    Returns
    -------
    tests : DataFrame
        One row per metric and tuning (:data:`TEST_COLUMNS`): the scenarios and methods of the block design,
        Friedman's chi^2 and p, the verdict ('methods differ', 'no difference shown', or why not tested) and
        what was left out.
    ranks : DataFrame
        One row per metric, tuning and method of the design (:data:`RANK_COLUMNS`), best first: its mean rank,
        position, whether Nemenyi's test cannot tell it from the best (``tied_with_best``, p >= alpha), that
        p-value, its median value over the scenarios.
    posthoc : dict
        (metric, tuning) -> (mean ranks, Nemenyi p-values): what the diagram draws.
    """
    tests, ranks, posthoc = [], [], {}
    tunings = [t for t in dict.fromkeys(table["tuning"]) if t]
    for metric, (_, better, _) in METRICS.items():
        if not better:
            continue
        for tuning in tunings:
            values = ranked_values(table, metric, tuning, backend)
            if values.empty:
                continue
            design, gone_m, gone_c = block_design(values)
            listed = table[(table["metric"] == metric) & (table["tuning"] == tuning) & (table["backend"] == backend)]
            never = [f"{m} (never ranked)" for m in dict.fromkeys(listed["method"]) if m not in values.columns]
            gone_m = never + gone_m
            rec = {"metric": metric, "tuning": tuning, "scenarios": int(design.shape[0]),
                   "methods": int(design.shape[1]), "friedman_chi2": np.nan, "p": np.nan,
                   "left out (methods)": "; ".join(gone_m), "left out (scenarios)": "; ".join(gone_c)}
            if design.shape[1] < 3 or design.shape[0] < 2:
                rec["verdict"] = (f"not tested: {design.shape[1]} methods in {design.shape[0]} scenarios "
                                  "(Friedman's test needs 3 methods and 2 scenarios)")
                tests.append(rec)
                continue
            if np.all(design.to_numpy(float) == design.to_numpy(float)[:, :1]):
                rec["verdict"] = "not tested: every method ties in every scenario"
                tests.append(rec)
                continue
            rec["friedman_chi2"], rec["p"] = friedman(design)
            rec["verdict"] = "methods differ" if rec["p"] < alpha else "no difference shown"
            tests.append(rec)
            mr = mean_ranks(design, better)
            pv = nemenyi(design)
            posthoc[(metric, tuning)] = (mr, pv)
            best = mr.index[0]
            for pos, (method, r) in enumerate(mr.items(), start=1):
                p_best = 1.0 if method == best else float(pv.loc[method, best])
                ranks.append({"metric": metric, "tuning": tuning, "method": method, "mean_rank": float(r),
                              "position": pos, "tied_with_best": bool(rec["p"] >= alpha or p_best >= alpha),
                              "nemenyi_p_vs_best": p_best, "median_value": float(design[method].median()),
                              "scenarios": int(design.shape[0])})
    return pd.DataFrame(tests, columns=TEST_COLUMNS), pd.DataFrame(ranks, columns=RANK_COLUMNS), posthoc


def cd_diagram(mean_rank: pd.Series, pvalues: pd.DataFrame, title: str, folder, name: str,
               colours: dict | None = None, alpha: float = ALPHA) -> list[str]:
    """The critical-difference diagram of one metric and tuning column (scikit-posthocs): the methods at
    their mean ranks, a bar joining every group Nemenyi's test cannot tell apart at ``alpha``. Written as
    ``name`` (PNG) and the same stem as SVG and PDF (the vector formats) in ``folder``; returns the file
    names. ``colours``: method -> colour (the report's fixed palette, when given).

    References
    ----------
    Demšar (2006), Fig. 1.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import scikit_posthocs as sp

    k = len(mean_rank)
    fig, ax = plt.subplots(figsize=(9.0, 1.2 + 0.22 * k), layout="constrained")
    # one colour per method when the report gives its palette; else one dark grey (no colour that could
    # be read as a method's)
    palette = {m: (colours or {}).get(m, "0.2") for m in mean_rank.index}
    kw = {"color_palette": palette}
    sp.critical_difference_diagram(mean_rank, pvalues, ax=ax, alpha=alpha, **kw)
    ax.set_title(title, fontsize=9)
    from pathlib import Path

    from jointbench.benchmarks.compare.plots import VECTOR_FORMATS, save_formats

    stem = name.rsplit(".", 1)[0]
    save_formats(fig, Path(folder), name, dpi=150)         # the PNG, and SVG and PDF without a date
    plt.close(fig)
    return [name, *(f"{stem}.{fmt}" for fmt in VECTOR_FORMATS)]


def cd_figures(posthoc: dict, tests: pd.DataFrame, part: str, folder, colours: dict | None = None,
               alpha: float = ALPHA) -> list[tuple[str, str]]:
    """The diagram of every tested metric and tuning column (:func:`summarize`'s ``posthoc``) as
    ``<part>_cd_<metric>_<tuning>.png`` (and .svg, .pdf), with captions derived from ``tests``."""
    out = []
    by = tests.set_index(["metric", "tuning"])
    for (metric, tuning), (mr, pv) in posthoc.items():
        t = by.loc[(metric, tuning)]
        head = METRICS[metric][0]
        title = (f"{head}, {tuning} column: mean rank over {t['scenarios']} scenarios "
                 f"(Friedman p = {t['p']:.2g})")
        files = cd_diagram(mr, pv, title, folder, f"{part}_cd_{metric}_{tuning}.png", colours, alpha)
        left = "; ".join(x for x in (t["left out (methods)"] and f"methods left out: {t['left out (methods)']}",
                                     t["left out (scenarios)"] and f"scenarios left out: {t['left out (scenarios)']}")
                         if x)
        out.append((files[0], f"Critical-difference diagram, {head} ({tuning} column): mean rank of {t['methods']} "
                              f"methods over {t['scenarios']} scenarios (1 = best); a bar joins methods Nemenyi's "
                              f"test cannot tell apart at {alpha:g}; Friedman chi^2 = {t['friedman_chi2']:.3g}, "
                              f"p = {t['p']:.2g} ({t['verdict']})" + (f"; {left}" if left else "")
                              + "; also as SVG and PDF"))
    return out


def summary_text(tests: pd.DataFrame, ranks: pd.DataFrame, backend: str, alpha: float = ALPHA) -> str:
    """The report's paragraph on the summary over scenarios, from its rows."""
    text = ("Summary over scenarios (Demšar 2006): per metric and tuning column, each ranked scenario on the "
            f"{backend} backend is a block and Friedman's test asks whether the methods' ranks differ at all "
            f"(level {alpha:g}); where they do, Nemenyi's post-hoc test compares every pair and the "
            "critical-difference diagram joins the methods it cannot tell apart. The test needs every method "
            "scored in every scenario used: the scenario or method with the largest share of missing values is "
            "dropped until none is (each row names what was left out). The noise levels and variations of one "
            "base scenario count as separate blocks, though they share the joint and the apparatus.")
    if tests.empty:
        return text + " No metric could be summarised in this run."
    tested = tests[np.isfinite(tests["p"].astype(float))]
    differ = tested[tested["verdict"] == "methods differ"]
    text += f" The ranks differ in {len(differ)} of the {len(tested)} tested metric-column pairs."
    if not ranks.empty:
        lead = []
        for (metric, tuning), g in ranks.groupby(["metric", "tuning"], sort=False):
            if metric not in ("vaf_stiffness", "total_error"):
                continue
            top = g[g["tied_with_best"]]["method"].tolist()
            lead.append(f"{METRICS[metric][0]} ({tuning}): {g.iloc[0]['method']} first (mean rank "
                        f"{g.iloc[0]['mean_rank']:.2f} of {len(g)})"
                        + (f", not distinguishable from it: {', '.join(top[1:])}" if len(top) > 1 else ""))
        if lead:
            text += " " + "; ".join(lead) + "."
    return text


# ------------------------------------------------------------------------------------- for the report
@dataclasses.dataclass
class SummaryParts:
    """What the summary over scenarios and the oracle bound add to a comparison report, each derived from
    the rows once: the tidy frames (also written as CSV), the report's paragraphs, tables and figures."""

    tests: pd.DataFrame              # :data:`TEST_COLUMNS` + the paired families that can reject
    ranks: pd.DataFrame              # the leaderboard rows (:data:`RANK_COLUMNS`)
    efficiency: pd.DataFrame         # oracle.efficiency: cell, backend, method, tuning, ..., efficiency
    oracle: pd.DataFrame             # oracle.oracle_table: the bound per cell and backend
    text: list[str]
    tables: list[tuple[str, pd.DataFrame]]
    figures: list[tuple[str, str]]


def _with_attainability(tests: pd.DataFrame, pairs: pd.DataFrame, alpha: float) -> pd.DataFrame:
    """The tests' rows with ``paired families that can reject`` ('a of f': families of the metric and column
    where Holm's first threshold is attainable, :func:`pairs.families`; '' for metrics not tested in pairs)."""
    out = tests.copy()
    fam = cpairs.families(pairs, alpha)
    counts = {k: f"{int(g['attainable'].sum())} of {len(g)}" for k, g in fam.groupby(["metric", "tuning"])}
    out["paired families that can reject"] = [counts.get((m, t), "") for m, t in zip(out["metric"], out["tuning"])]
    return out


def _leaderboard(ranks: pd.DataFrame, metrics: tuple[str, ...]) -> pd.DataFrame:
    """The leaderboard rows of ``metrics`` as the report shows them."""
    sel = ranks[ranks["metric"].isin(metrics)]
    return pd.DataFrame({"metric": [METRICS[m][0] for m in sel["metric"]], "tuning": sel["tuning"],
                         "#": sel["position"], "method": sel["method"], "mean rank": sel["mean_rank"].round(2),
                         "not distinguishable from the first (Nemenyi)": np.where(sel["tied_with_best"], "yes", ""),
                         "median over scenarios": sel["median_value"]})


def _efficiency_tables(eff: pd.DataFrame, orc: pd.DataFrame, primary: str) -> list[tuple[str, pd.DataFrame]]:
    """Per method the efficiency over the scenarios; per scenario the bound and the method closest to it."""
    sel = eff[(eff["backend"] == primary) & np.isfinite(eff["efficiency"].astype(float))]
    if sel.empty:
        return []
    per_method = sel.groupby(["method", "tuning"], sort=True)["efficiency"].agg(
        ["median", "min", "max", "size"]).reset_index()
    per_method.columns = ["method", "tuning", "median efficiency", "best", "worst", "scenarios"]
    per_method = per_method.sort_values(["tuning", "median efficiency"], kind="stable")
    recs = []
    for cell, g in sel.groupby("cell", sort=False):
        o = orc[(orc["cell"] == cell) & (orc["backend"] == primary)]
        best = g.loc[g["efficiency"].idxmin()]
        recs.append({"scenario": cell,
                     "oracle total error": float(o["oracle_total_error"].iloc[0]) if len(o) else np.nan,
                     "oracle, ensembles": (float(o["oracle_total_error_ensemble"].iloc[0])
                                           if len(o) and "oracle_total_error_ensemble" in o else np.nan),
                     "closest method": f"{best['method']}, {best['tuning']}",
                     "its efficiency": float(best["efficiency"])})
    return [("Efficiency against the oracle bound, per method: total error / the oracle's on the same scenario "
             f"({primary}; an ensemble method against the oracle fitted to the same ensembles; 1 = as good as the "
             "oracle)", per_method),
            ("The oracle bound per scenario (total error of least squares knowing the form of K(t); never ranked) "
             "and the method closest to it", pd.DataFrame(recs))]


def report_parts(part: str, table: pd.DataFrame, rows: pd.DataFrame, pairs: pd.DataFrame, primary: str, folder,
                 colours: dict | None = None, alpha: float = ALPHA) -> SummaryParts:
    """The summary over scenarios (:func:`summarize`, :func:`cd_figures`) and the oracle bound
    (:mod:`.oracle`) of a comparison grid part, for its report and page; writes ``<part>_summary.csv`` (the
    tests), ``<part>_leaderboard.csv`` (the ranks), ``<part>_efficiency.csv`` and the diagrams in
    ``folder``. ``table``: the full table; ``rows``: the labelled tidy rows; ``pairs``: the paired
    comparisons (:func:`pairs.paired`); ``colours``: method -> colour for the diagrams."""
    tests, ranks, posthoc = summarize(table, primary, alpha)
    tests = _with_attainability(tests, pairs, alpha)
    eff = oracle.efficiency(table, rows)
    orc = oracle.oracle_table(rows)
    for frame, name in ((tests, "summary"), (ranks, "leaderboard"), (eff, "efficiency")):
        if not frame.empty:
            frame.to_csv(folder / f"{part}_{name}.csv", index=False)
    figures = cd_figures(posthoc, tests, part, folder, colours, alpha) if posthoc else []
    text = [summary_text(tests, ranks, primary, alpha), oracle.bound_text(eff, primary)]
    tables = []
    if not tests.empty:
        shown = tests.assign(metric=[METRICS[m][0] for m in tests["metric"]])
        tables.append(("Summary over scenarios: Friedman's test per metric and tuning column (scenarios and methods "
                       "of the complete block design, what was left out) and the paired families of the metric "
                       "where a rejection is attainable at all", shown))
    board = _leaderboard(ranks, ("total_error", "vaf_stiffness"))
    if not board.empty:
        tables.append(("Leaderboard over scenarios (total error and VAF of k; every metric in "
                       f"`{part}_leaderboard.csv`): mean rank, 1 = best", board))
    tables += _efficiency_tables(eff, orc, primary)
    return SummaryParts(tests, ranks, eff, orc, text, tables, figures)
