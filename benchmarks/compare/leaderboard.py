"""The leaderboard of a comparison grid: per ranked metric and tuning column, every method's standing over the
ranked scenarios at a glance, from the full table's ranks and values
(:func:`jointbench.benchmarks.compare.tables.full_table`).

Scenarios do not all rank the same methods (a grid's ``only`` rules, skips, refusals), and they rank 8 to 16
of them, so a raw rank is not comparable across scenarios; the leaderboard uses the share of the other
methods ranked in a scenario that a method is strictly ahead of (100 %: first alone; 0 %: last), averaged
over the scenarios it is ranked in, and says over how many. How far behind the scenario's best a method is
comes beside it: the ratio to the best for an error or a time, the difference in points for a VAF. The
rankings over scenarios with a test (Friedman, post-hoc, critical difference) are the summary over
scenarios; this is the description, not a test.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from jointbench.benchmarks.compare.tables import METRICS

#: columns of :func:`leaderboard`
COLUMNS = ("metric", "tuning", "position", "method", "scenarios", "of", "first", "ahead_pct", "gap")


def gap_kind(metric: str) -> str:
    """How :func:`leaderboard` measures the distance to a scenario's best on ``metric``: 'points' (a VAF:
    best minus value) or 'ratio' (value over best, for errors and times)."""
    return "points" if metric.startswith("vaf") else "ratio"


def gap_text(metric: str) -> str:
    """The heading of the gap column for ``metric``."""
    return ("points behind the best, median over scenarios" if gap_kind(metric) == "points"
            else "times the best, median over scenarios")


def _scenario_standing(g: pd.DataFrame, better: str, kind: str) -> pd.DataFrame:
    """One scenario's ranked methods: share of the others strictly behind (%), first or not, gap to the best."""
    v = g["value"].to_numpy(float)
    n = len(v)
    sign = 1.0 if better == "max" else -1.0
    behind = np.array([int(np.sum(sign * (x - v) > 0)) for x in v])     # others strictly worse than each
    best = v.max() if better == "max" else v.min()
    if kind == "points":
        gap = best - v
    else:
        gap = v / best if best > 0 else np.full(n, np.nan)           # a ratio to a best of 0 says nothing
    return pd.DataFrame({"method": g["method"].to_numpy(), "ahead": 100.0 * behind / (n - 1) if n > 1 else np.nan,
                         "first": g["rank"].to_numpy(float) == 1, "gap": gap})


def leaderboard(table: pd.DataFrame, backend: str) -> pd.DataFrame:
    """Per ranked metric (:data:`METRICS` with a direction) and tuning column of ``backend``: every method ranked
    in some scenario, with ``scenarios`` (ranked in) of ``of`` (scenarios ranking that metric), ``first``
    (scenarios it ranks first in, ties included), ``ahead_pct`` (mean over its scenarios of the share of the
    other ranked methods it is strictly ahead of, %) and ``gap`` (median over its scenarios of the distance to
    the scenario's best, :func:`gap_kind`). ``position``: competition rank on ``ahead_pct`` (higher first).
    Only rows with a rank count (the full table ranks finite values of feasible scenarios on the primary
    backend); a scenario ranking a single method adds nothing to the share."""
    t = table[(table["backend"] == backend) & table["rank"].notna()]
    out = []
    for (metric, tuning), g in t.groupby(["metric", "tuning"], sort=False):
        better = METRICS.get(metric, ("", "", False))[1]
        if not better:
            continue
        per = pd.concat([_scenario_standing(h, better, gap_kind(metric)) for _, h in g.groupby("cell", sort=False)],
                        ignore_index=True)
        n_cells = g["cell"].nunique()
        agg = per.groupby("method").agg(scenarios=("first", "size"), first=("first", "sum"),
                                        ahead_pct=("ahead", "mean"), gap=("gap", "median")).reset_index()
        agg["position"] = agg["ahead_pct"].rank(ascending=False, method="min")
        agg = agg.sort_values(["position", "scenarios", "method"], ascending=[True, False, True], na_position="last")
        agg["metric"], agg["tuning"], agg["of"] = metric, tuning, n_cells
        out.append(agg)
    if not out:
        return pd.DataFrame(columns=list(COLUMNS))
    board = pd.concat(out, ignore_index=True)
    order = {m: k for k, m in enumerate(METRICS)}
    board["_m"] = board["metric"].map(order)
    board = board.sort_values(["_m", "tuning", "position", "method"], kind="stable").drop(columns="_m")
    board["first"] = board["first"].astype(int)
    return board[list(COLUMNS)].reset_index(drop=True)


def partial(board: pd.DataFrame) -> pd.DataFrame:
    """The rows of methods ranked in fewer scenarios than their metric and column rank (their share is over
    those only)."""
    return board[board["scenarios"] < board["of"]]


def display(board: pd.DataFrame) -> pd.DataFrame:
    """One metric and tuning column of the leaderboard as it is shown (report and page): '#', 'method',
    the share ahead (%, no decimals), 'first in', the scenarios ('n of N' when fewer than the column's) and
    the gap to the best (3 digits; '×' for a ratio, 'pts' for points)."""
    metric = str(board["metric"].iloc[0])
    n = int(board["of"].max())
    unit = "×" if gap_kind(metric) == "ratio" else " pts"
    return pd.DataFrame({
        "#": [f"{p:.0f}" if np.isfinite(p) else "" for p in board["position"]],
        "method": board["method"].to_numpy(),
        "ahead of others (%, mean)": [f"{a:.0f}" if np.isfinite(a) else "" for a in board["ahead_pct"]],
        "first in": board["first"].astype(int).astype(str).to_numpy(),
        f"scenarios (of {n})": [str(int(k)) + ("" if k == o else f" of {int(o)}")
                                for k, o in zip(board["scenarios"], board["of"])],
        gap_text(metric): [f"{x:.3g}{unit}" if np.isfinite(x) else "" for x in board["gap"]]})
