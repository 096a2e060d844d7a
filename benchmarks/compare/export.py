"""The summary of a comparison grid for a paper: the leaderboard (:mod:`jointbench.benchmarks.compare.leaderboard`)
as a wide CSV (one row per method, one column per metric, tuning column and quantity) and as LaTeX tables in the
booktabs style (one per tuning column: methods x metrics), and the full table's values as a wide CSV (one row per
tuning column and method, one column per metric and scenario). The numbers are the leaderboard's and the full
table's, unrounded in the CSVs; the LaTeX rounds them for print and its caption says what they are.

References
----------
Fear, "Publication quality tables in LaTeX" (the booktabs package's documentation: rules \\toprule, \\midrule,
\\bottomrule and no vertical rules).
"""
from __future__ import annotations

import re

import numpy as np
import pandas as pd

from jointbench.benchmarks.compare.leaderboard import gap_text
from jointbench.benchmarks.compare.tables import METRICS

#: the leaderboard's quantities in the wide CSV, with their column names
WIDE_QUANTITIES = {"position": "position", "ahead_pct": "ahead of others (%)", "first": "first in",
                   "scenarios": "scenarios ranked", "of": "of", "gap": "gap to best"}


def summary_wide(board: pd.DataFrame) -> pd.DataFrame:
    """The leaderboard wide: one row per method, a column ``'<metric> | <tuning> | <quantity>'`` for each
    metric, tuning column and :data:`WIDE_QUANTITIES` (blank where a method is not ranked on that metric)."""
    if board.empty:
        return pd.DataFrame(columns=["method"])
    long = board.melt(id_vars=["metric", "tuning", "method"], value_vars=list(WIDE_QUANTITIES), var_name="quantity")
    long["column"] = [f"{m} | {t} | {WIDE_QUANTITIES[q]}" for m, t, q in zip(long["metric"], long["tuning"],
                                                                           long["quantity"])]
    order = list(dict.fromkeys(long["column"]))
    wide = long.pivot(index="method", columns="column", values="value")[order]
    first = board.drop_duplicates(["metric", "tuning"]).iloc[0]              # rows in the first board's order
    lead = board[(board["metric"] == first["metric"]) & (board["tuning"] == first["tuning"])]["method"].tolist()
    rows = lead + sorted(set(wide.index) - set(lead))
    return wide.loc[rows].reset_index().rename_axis(columns=None)


def values_wide(table: pd.DataFrame, backend: str) -> pd.DataFrame:
    """The full table's values on ``backend`` wide: one row per tuning column and method, a column
    ``'<metric> | <scenario>'`` for each metric and scenario (the median over realizations or the study's value,
    as in the full table)."""
    t = table[table["backend"] == backend].copy()
    if t.empty:
        return pd.DataFrame(columns=["tuning", "method"])
    t["column"] = t["metric"] + " | " + t["cell"]
    order = [f"{m} | {c}" for m in METRICS for c in dict.fromkeys(t["cell"]) if f"{m} | {c}" in set(t["column"])]
    wide = t.pivot_table(index=["tuning", "method"], columns="column", values="value", aggfunc="first", sort=False)
    return wide[order].reset_index().rename_axis(columns=None)


def metric_name(metric: str) -> str:
    """The metric's heading without its unit (the leaderboard's cells are shares, not the metric's values)."""
    return re.sub(r"\s*\([^)]*\)$", "", METRICS[metric][0])


def _cell(ahead: float, first: float, scenarios: float, of: float) -> str:
    if not np.isfinite(ahead):
        return "--"
    return f"{ahead:.0f} ({int(first)})" + ("" if scenarios == of else f"$^{{{int(scenarios)}/{int(of)}}}$")


def summary_latex(board: pd.DataFrame, tuning: str, label: str) -> str:
    """The leaderboard of one tuning column as a booktabs LaTeX table: methods (in the order of the first
    metric's board) x metrics, each cell 'share ahead (first places)' with 'n/N' raised where the method is
    ranked in n of the N scenarios only; the caption defines them. Empty string when the column has no board."""
    b = board[board["tuning"] == tuning]
    if b.empty:
        return ""
    metrics = list(dict.fromkeys(b["metric"]))
    methods = list(dict.fromkeys(b[b["metric"] == metrics[0]]["method"]))
    methods += sorted(set(b["method"]) - set(methods))
    by = b.set_index(["method", "metric"])
    df = pd.DataFrame({"Method": methods})
    for m in metrics:
        df[metric_name(m)] = [_cell(*by.loc[(x, m), ["ahead_pct", "first", "scenarios", "of"]].to_numpy(float))
                             if (x, m) in by.index else "--" for x in methods]
    n = int(b["of"].max())
    caption = (f"Leaderboard, {tuning} column: per metric, the mean over the ranked scenarios (up to {n}) of the "
               "share of the other methods ranked in a scenario that a method is strictly ahead of (\\%), and in "
               "parentheses the scenarios it ranks first in; $^{n/N}$: ranked in n of the N scenarios only "
               "(its share is over those); --: not ranked on that metric.")
    sty = df.style.hide(axis="index").format(escape="latex", subset=["Method"]).format_index(escape="latex", axis=1)
    return sty.to_latex(hrules=True, caption=caption, label=label, column_format="l" + "r" * len(metrics),
                        position_float="centering")


def gap_note(board: pd.DataFrame) -> str:
    """What the wide CSV's 'gap to best' means per metric (one line each)."""
    return "; ".join(f"{m}: {gap_text(m)}" for m in dict.fromkeys(board["metric"]))


def write_summary(board: pd.DataFrame, table: pd.DataFrame, backend: str, folder, name: str) -> list[str]:
    """The exports beside the report: ``<name>_summary_wide.csv``, ``<name>_summary.tex`` (one booktabs table
    per tuning column) and ``<name>_values_wide.csv``; returns the files written."""
    files = []
    if not board.empty:
        summary_wide(board).to_csv(folder / f"{name}_summary_wide.csv", index=False)
        tex = [summary_latex(board, t, f"tab:{name}-leaderboard-{t}") for t in dict.fromkeys(board["tuning"])]
        head = ("% Requires \\usepackage{booktabs}. Written by JointBench from the full table; 'gap to best' in the "
                f"wide CSV: {gap_note(board)}.\n")
        (folder / f"{name}_summary.tex").write_text(head + "\n".join(t for t in tex if t))
        files += [f"{name}_summary_wide.csv", f"{name}_summary.tex"]
    vw = values_wide(table, backend)
    if len(vw):
        vw.to_csv(folder / f"{name}_values_wide.csv", index=False)
        files.append(f"{name}_values_wide.csv")
    return files
