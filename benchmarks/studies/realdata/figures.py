"""Table and figure of the realdata study (protocol ``realdata.crossval``), drawn from the tidy rows: the
cross-validated output VAF of every estimator on every trial, and why an estimator has no number."""
from __future__ import annotations

import pandas as pd

from jointbench.benchmarks.figures import PartReport, new_figure, register, save

#: the rows that say why an estimator has no cross-validated VAF
WHY = ("skipped", "not_fitted", "not_scored", "refused")


def crossval_table(rows: pd.DataFrame) -> pd.DataFrame:
    """``vaf_cv_mean`` (%) per estimator (rows, best mean first) and trial (columns), with the in-sample
    ``vaf_fit`` mean beside it and the fit time (s, both folds, all trials)."""
    ok = rows[rows["metric"] == "vaf_cv_mean"]
    if ok.empty:
        return pd.DataFrame()
    t = ok.pivot_table(index="estimator", columns="trial", values="value")
    t["mean (held out)"] = t.mean(axis=1)
    fit = rows[rows["metric"] == "vaf_fit"].groupby("estimator")["value"].mean()
    t["mean (fitted half)"] = fit.reindex(t.index)
    t["fit time (s)"] = rows[rows["metric"] == "fit_time_s"].groupby("estimator")["value"].sum().reindex(t.index)
    t = t.sort_values("mean (held out)", ascending=False)
    return t.round({c: 1 for c in t.columns if c != "fit time (s)"}).round({"fit time (s)": 2}).reset_index()


def why_table(rows: pd.DataFrame) -> pd.DataFrame:
    """One row per estimator without a number: what happened and the first reason given."""
    sel = rows[rows["metric"].isin(WHY)]
    if sel.empty:
        return pd.DataFrame()
    first = sel.drop_duplicates("estimator")
    return pd.DataFrame({"estimator": first["estimator"], "outcome": first["metric"],
                         "reason": first["reason"].astype(str).str.slice(0, 240)}).reset_index(drop=True)


@register("realdata.crossval")
def realdata_crossval(part, rows, curves, folder, checks) -> PartReport:
    if "status" in rows.columns:
        rows = rows[rows["status"] == "ok"]
    missing = rows[rows["metric"] == "not_run"]
    if len(missing) and not (rows["metric"] == "vaf_cv_mean").any():
        return PartReport(text=f"Not run: {missing['reason'].iloc[0]}.")
    table = crossval_table(rows)
    report = PartReport(tables=[("Cross-validated output VAF (%): mean of the two folds per trial", table)])
    why = why_table(rows)
    if len(why):
        report.tables.append(("Estimators without a cross-validated VAF, and why", why))
    if len(table):
        trials = [c for c in table.columns if c not in ("estimator", "mean (held out)", "mean (fitted half)",
                                                         "fit time (s)")]
        fig, ax = new_figure(figsize=(9, 0.35 * len(table) + 1.8))
        y = range(len(table))
        for k, trial in enumerate(trials):
            ax.plot(table[trial], y, "o", ms=5, label=trial, alpha=0.8)
        ax.plot(table["mean (fitted half)"], y, "k|", ms=12, label="fitted half (mean)")
        ax.set_yticks(list(y), table["estimator"])
        ax.invert_yaxis()
        ax.set_xlabel("output VAF of the held-out half (%)")
        ax.set_title("Two-fold cross-validated output VAF, REKLAB's ankle trials (100 Hz)")
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        ax.grid(axis="x", alpha=0.3)
        report.figures.append((save(fig, folder, "realdata_vaf.png"),
                               "Held-out output VAF per estimator and trial (dots); the bar is the mean VAF of the "
                               "half each estimate was fitted on"))
    return report
