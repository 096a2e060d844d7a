"""The tables of a comparison grid, from its tidy rows only: every method x scenario x metric with an
interval that contains its value and its rank, the scenarios' identifiability and feasibility, the
agreement of the backends, and the settings each method ran with (the paired comparisons:
:mod:`jointbench.benchmarks.compare.pairs`).

A *method* is an estimator with the data it was given (``kbr``, ``kbr (ensemble)``); a *scenario* (a
cell of the grid) is one combination of the grid's other axes but the backend (scenario, time variation,
noise, ...); rankings use one backend (:data:`PRIMARY_BACKEND` when present) and the others are compared
with it in one line per scenario. The statistics are :mod:`jointbench.benchmarks.compare.stats`.

References
----------
van de Ruit, Mugge, Cavallo, Lataire, Ludvig & Schouten, "Quantitative comparison of time-varying system
identification methods to describe human joint impedance" (the metrics).
"""
from __future__ import annotations

import json

import numpy as np
import pandas as pd

from jointbench.benchmarks.compare import stats as cs

#: grid axes that make a scenario (a cell), in the order of its label; the backend is kept apart
CELL_AXES = ("scenario", "joint", "variation", "perturbation", "noise", "fs")
PRIMARY_BACKEND = "analytic"
#: the estimator name of the identifiability rows of a scenario (no method)
SCENARIO_ROWS = "(scenario)"
#: metric -> (heading, better: 'max' | 'min' | '' (not ranked), per realization?)
METRICS = {
    "vaf_stiffness": ("VAF of k (%)", "max", True),
    "error_rms": ("RMS error of k per realization (N·m/rad)", "min", True),
    "total_error": ("total error (N·m/rad)", "min", False),
    "bias_rms": ("bias, RMS (N·m/rad)", "min", False),
    "bias_mean": ("bias, mean (N·m/rad)", "", False),
    "random_error": ("random error (N·m/rad)", "min", False),
    "rise_time_s": ("rise time (s)", "min", False),
    "vaf_output": ("output VAF (%)", "max", True),
    "fit_time_s": ("fit time (s)", "min", True),
}
#: the identifiability metrics of a scenario (rows of estimator SCENARIO_ROWS)
IDENTIFIABILITY = {
    "stiffness_share": "stiffness torque, % of the measured torque's variance",
    "tv_share": "time-varying stiffness torque, %",
    "noise_share": "noise, %",
    "tv_snr_db": "SNR of the time-varying stiffness torque (dB)",
}
FAILURES = ("skipped", "not_fitted", "not_scored", "refused")
ALPHA = 0.05


def _num(v) -> str:
    """A number as the tables show it (3 significant digits; infinities as ∞)."""
    if v is None or (isinstance(v, float) and np.isnan(v)):
        return ""
    v = float(v)
    if not np.isfinite(v):
        return "∞" if v > 0 else "-∞"
    return f"{v:.3g}" if abs(v) < 1e4 else f"{v:.2e}"


def cell_axes(rows: pd.DataFrame) -> list[str]:
    """The cell axes that vary in these rows (the scenario name always)."""
    return [a for a in CELL_AXES if a in rows.columns
            and (a == "scenario" or rows[a].dropna().astype(str).nunique() > 1)]


def labelled(rows: pd.DataFrame) -> pd.DataFrame:
    """The rows with ``method``, ``tuning``, ``backend`` and ``cell`` (the scenario's label) filled in;
    rows written before a column existed get its default (tuning 'paper', data 'trial')."""
    out = rows.copy()
    out["estimator"] = out["estimator"].fillna("").astype(str)
    data = out["data"].fillna("trial").astype(str) if "data" in out.columns else pd.Series("trial", index=out.index)
    out["method"] = np.where(data == "ensemble", out["estimator"] + " (ensemble)", out["estimator"])
    out["tuning"] = (out["tuning"].fillna("").astype(str).replace("", "paper") if "tuning" in out.columns
                     else "paper")
    out["tuning"] = np.where(out["estimator"] == SCENARIO_ROWS, "", out["tuning"])
    out["backend"] = out["backend"].fillna("").astype(str) if "backend" in out.columns else ""
    axes = cell_axes(out)
    label = pd.Series("", index=out.index, dtype=object)
    for i, a in enumerate(axes):
        col = out[a]
        if a in ("noise", "fs"):
            text = col.map(lambda v, a=a: "" if pd.isna(v) else v if isinstance(v, str) else f"{a} {v:g}")
        else:
            text = col.fillna("").astype(str)
        label = text if i == 0 else label + " / " + text
    out["cell"] = label
    return out


def primary_backend(rows: pd.DataFrame) -> str:
    """The backend the rankings use: analytic when it ran, else the first one in the rows."""
    b = [x for x in dict.fromkeys(rows["backend"]) if x]
    return PRIMARY_BACKEND if PRIMARY_BACKEND in b or not b else b[0]


def realizations(rows: pd.DataFrame) -> list[int]:
    """The distinct realization counts of the methods' cases (R), from the per-realization rows."""
    if "realization" not in rows.columns:
        return []
    per = rows[rows["realization"].notna() & (rows["metric"] == "vaf_stiffness")]
    return sorted({int(n) for n in per.groupby(["case_id"])["realization"].nunique()})


# ----------------------------------------------------------------------------------- the full table
def with_nothing_to_tune(rows: pd.DataFrame) -> pd.DataFrame:
    """Paper rows copied into the tuned column for the methods the study did not tune because they have
    no smoothing setting (reason 'nothing to tune'): the same fit, so the same scores."""
    if not (rows["tuning"] == "tuned").any():
        return rows
    skip = rows[(rows["tuning"] == "tuned") & rows["metric"].isin(FAILURES)
                & rows.get("reason", pd.Series("", index=rows.index)).fillna("").str.contains("nothing to tune",
                                                                                             case=False)]
    if skip.empty:
        return rows
    keys = set(zip(skip["method"], skip["cell"], skip["backend"]))
    paper = rows[(rows["tuning"] == "paper") & ~rows["metric"].isin(FAILURES)]
    add = paper[[k in keys for k in zip(paper["method"], paper["cell"], paper["backend"])]].copy()
    add["tuning"] = "tuned"
    add["tuned_as"] = "paper (nothing to tune)"
    drop = rows.index.isin(skip.index)
    return pd.concat([rows[~drop], add], ignore_index=True)


def constant_methods(curves: pd.DataFrame | None, rows: pd.DataFrame) -> set[tuple[str, str]]:
    """(method, cell) pairs whose mean estimate is constant in time (a time-invariant fit), from the
    stored curves: their random error measures no tracking and is not ranked."""
    if curves is None or curves.empty or "series" not in curves.columns:
        return set()
    c = labelled(curves.assign(metric="curve"))
    c = c[c["series"] == "mean estimate"]
    out = set()
    for (m, cell), g in c.groupby(["method", "cell"]):
        y = g["y"].astype(float).to_numpy()
        if y.size and np.all(np.isfinite(y)) and np.ptp(y) <= 1e-9 * max(1.0, np.abs(y).max()):
            out.add((m, cell))
    return out


def full_table(rows: pd.DataFrame, curves: pd.DataFrame | None = None) -> pd.DataFrame:
    """One row per cell, backend, method, tuning and metric: ``value`` (median over realizations for a
    per-realization metric, else the study's value), ``lo``/``hi`` (an interval that contains ``value``:
    the percentile bootstrap of the median over realizations, or the study's ``p05``/``p95`` when they
    contain it), ``interval`` (which), ``n``, ``rank`` and ``ranked`` (methods ranked in the cell; ranks
    only among finite values of feasible cells on the primary backend), ``note`` (why not ranked)."""
    rows = with_nothing_to_tune(rows)
    ok = rows[(rows["status"] == "ok") & rows["metric"].isin(list(METRICS))
              & (rows["estimator"] != SCENARIO_ROWS)]
    recs = []
    for (cell, backend, method, tuning, metric), g in ok.groupby(["cell", "backend", "method", "tuning", "metric"],
                                                                   sort=False):
        v = g["value"].astype(float).to_numpy()
        per = METRICS[metric][2] and "realization" in g and g["realization"].notna().all()
        if per:
            value = float(np.median(v))
            lo, hi = cs.bootstrap_interval(v)
            kind = "percentile bootstrap of the median over realizations (90 %)"
        else:
            value = float(np.median(v))
            lo = hi = float("nan")
            kind = ""
            if len(g) == 1 and "p05" in g and "p95" in g:
                p05, p95 = float(g["p05"].iloc[0]), float(g["p95"].iloc[0])
                if np.isfinite(value) and not (np.isnan(p05) or np.isnan(p95)) and p05 <= value <= p95:
                    lo, hi, kind = p05, p95, "study's bootstrap over realizations (90 %)"
                elif not np.isfinite(value):
                    lo = hi = value
                    kind = "infinite"
                elif not np.isnan(p05):
                    kind = "study's interval excludes its value: not shown"
        n = int(g["realization"].nunique()) if per else (int(g["n"].iloc[0]) if "n" in g and g["n"].notna().any()
                                                         else int(len(v)))
        settings = ""
        if "settings" in g and g["settings"].notna().any():
            settings = str(g["settings"].dropna().iloc[0])
        tuned_as = str(g["tuned_as"].dropna().iloc[0]) if "tuned_as" in g and g["tuned_as"].notna().any() else ""
        recs.append({"cell": cell, "backend": backend, "method": method, "tuning": tuning, "metric": metric,
                     "value": value, "lo": lo, "hi": hi, "interval": kind, "n": n, "settings": settings,
                     "tuned_as": tuned_as})
    cols = ["cell", "backend", "method", "tuning", "metric", "value", "lo", "hi", "interval", "n", "settings",
            "tuned_as", "rank", "ranked", "note"]
    t = pd.DataFrame(recs, columns=cols[:12])
    return _rank(t, rows, curves)[cols] if len(t) else pd.DataFrame(columns=cols)


def feasibility(table: pd.DataFrame) -> dict[tuple[str, str], float]:
    """(cell, backend) -> the best median VAF of k over its methods (any tuning; NaN without VAF rows).
    A cell is feasible (rankable) when that is above 0 %: some method beats a constant at the true mean."""
    v = table[table["metric"] == "vaf_stiffness"]
    best = v.groupby(["cell", "backend"])["value"].max()
    out = {k: float(x) for k, x in best.items()}
    for k in set(zip(table["cell"], table["backend"])) - set(out):
        out[k] = float("nan")
    return out


def _rank(t: pd.DataFrame, rows: pd.DataFrame, curves) -> pd.DataFrame:
    t = t.copy()
    t["rank"], t["ranked"], t["note"] = np.nan, 0, ""
    primary = primary_backend(rows)
    feas = feasibility(t)
    const = constant_methods(curves, rows)
    for (cell, backend, tuning, metric), g in t.groupby(["cell", "backend", "tuning", "metric"], sort=False):
        better = METRICS[metric][1]
        if backend != primary:
            t.loc[g.index, "note"] = f"not ranked: rankings use the {primary} backend"
            continue
        if not feas.get((cell, backend), np.nan) > 0:
            t.loc[g.index, "note"] = "not ranked: infeasible scenario (no method's median VAF of k is above 0 %)"
            continue
        if not better:
            t.loc[g.index, "note"] = "not ranked (signed)"
            continue
        vals = g["value"].to_numpy(float).copy()
        if metric == "random_error":
            flat = np.array([(m, cell) in const for m in g["method"]])
            vals[flat] = np.nan
            t.loc[g.index[flat], "note"] = "not ranked: constant estimate (no tracking spread)"
        r = cs.ranks(vals, better)
        t.loc[g.index, "rank"] = r
        n = int(np.isfinite(r).sum())
        t.loc[g.index, "ranked"] = n
        if n == 0:
            t.loc[g.index, "note"] = t.loc[g.index, "note"].where(
                t.loc[g.index, "note"] != "", "cannot rank: no finite value")
        else:
            nonfinite = g.index[~np.isfinite(g["value"].to_numpy(float))]
            t.loc[nonfinite, "note"] = "not ranked: not finite"
    return t


# ----------------------------------------------------------------------------- identifiability
def identifiability(rows: pd.DataFrame, table: pd.DataFrame) -> pd.DataFrame:
    """One row per cell and backend: the identifiability figures (when the rows carry them), the best
    median VAF of k and whether the cell is ranked."""
    feas = feasibility(table)
    idr = rows[(rows["estimator"] == SCENARIO_ROWS) & rows["metric"].isin(list(IDENTIFIABILITY))]
    recs = []
    for (cell, backend) in dict.fromkeys(zip(table["cell"], table["backend"])):
        rec = {"scenario": cell, "backend": backend}
        g = idr[(idr["cell"] == cell) & (idr["backend"] == backend)]
        for m, head in IDENTIFIABILITY.items():
            x = g[g["metric"] == m]["value"]
            rec[head] = float(x.median()) if len(x) else np.nan
        best = feas.get((cell, backend), np.nan)
        rec["best median VAF of k (%)"] = best
        rec["ranked"] = "yes" if best > 0 else "no: infeasible"
        recs.append(rec)
    out = pd.DataFrame(recs)
    if idr.empty and len(out):
        out = out.drop(columns=list(IDENTIFIABILITY.values()))
    return out


def unranked_hint(rows: pd.DataFrame, table: pd.DataFrame, primary: str) -> str:
    """Why each scenario of the ``primary`` backend is not ranked, in one line ('' when every one is): no method
    was scored there (every combination skipped, failed or refused); or none beats a constant, with how much of
    the measured torque the time-varying stiffness explains (the identifiability rows), or, without those rows,
    how to get them (``params.identify``, on by default)."""
    ident = identifiability(rows, table)
    if ident.empty:
        return ""
    v = table[(table["metric"] == "vaf_stiffness") & (table["backend"] == primary)]
    scored = set(v[np.isfinite(v["value"].to_numpy(float))]["cell"])
    tv, snr = IDENTIFIABILITY["tv_share"], IDENTIFIABILITY["tv_snr_db"]
    why = []
    for r in ident[(ident["backend"] == primary) & (ident["ranked"] != "yes")].to_dict("records"):
        cell, best = r["scenario"], r["best median VAF of k (%)"]
        if cell not in scored:
            why.append(f"{cell}: no method was scored (see the combinations skipped or not fitted)")
        elif pd.notna(r.get(tv, np.nan)):
            why.append(f"{cell}: best median VAF of k {_num(best)} %; the time-varying stiffness torque is "
                       f"{_num(r[tv])} % of the measured torque's variance, SNR {_num(r[snr])} dB")
        else:
            why.append(f"{cell}: best median VAF of k {_num(best)} %; no identifiability rows (the part's "
                       f"params.identify is false; true, the default, says how much of the torque the time-varying "
                       f"stiffness explains)")
    return ("Not ranked, and why: " + "; ".join(why) + ".") if why else ""


# ----------------------------------------------------------------------------- backends, settings
def backend_agreement(table: pd.DataFrame, primary: str) -> list[str]:
    """One line per cell run on more than one backend: how far the other backend's values lie from the
    primary one's over the methods and metrics both have (VAF in percentage points, the others relative;
    fit times left out: they measure the machine, not the backend) and whether the best method on VAF of k
    is the same."""
    lines = []
    vaf = {"vaf_stiffness", "vaf_output"}
    for cell, g in table[table["metric"] != "fit_time_s"].groupby("cell", sort=False):
        others = [b for b in dict.fromkeys(g["backend"]) if b != primary]
        if not others or primary not in set(g["backend"]):
            continue
        base = g[g["backend"] == primary].set_index(["method", "tuning", "metric"])["value"]
        for b in others:
            o = g[g["backend"] == b].set_index(["method", "tuning", "metric"])["value"]
            common = base.index.intersection(o.index)
            if not len(common):
                lines.append(f"**{cell}**: {b} against {primary}: no value in common")
                continue
            x, y = base[common].to_numpy(float), o[common].to_numpy(float)
            fin = np.isfinite(x) & np.isfinite(y)
            same_inf = int(np.sum(~np.isfinite(x) & (x == y)))
            differ_inf = int(np.sum(~fin)) - same_inf
            is_vaf = np.array([k[2] in vaf for k in common])
            parts = []
            sel = fin & is_vaf
            if sel.any():
                d = np.abs(y[sel] - x[sel])
                w = common[sel][int(np.argmax(d))]
                parts.append(f"VAF within {d.max():.2g} points (median {np.median(d):.2g}; largest: {w[0]}, "
                             f"{METRICS[w[2]][0]})")
            sel = fin & ~is_vaf
            if sel.any():
                rel = np.abs(y[sel] - x[sel]) / np.maximum(np.abs(x[sel]), 1e-12)
                w = common[sel][int(np.argmax(rel))]
                parts.append(f"the other metrics within {100 * rel.max():.2g} % (median {100 * np.median(rel):.2g} %; "
                             f"largest: {w[0]}, {METRICS[w[2]][0]})")

            def top(vals):
                v = vals[[k for k in vals.index if k[2] == "vaf_stiffness"]]
                v = v[np.isfinite(v.to_numpy(float))]
                return None if v.empty else v.idxmax()[0]
            ta, tb = top(base[common]), top(o[common])
            n_methods = len({k[0] for k in common})
            lines.append(
                f"**{cell}**: {b} against {primary}, {n_methods} methods, {len(common)} values: " + "; ".join(parts)
                + (f"; {same_inf} equally infinite" if same_inf else "")
                + (f"; {differ_inf} finite on one backend only" if differ_inf else "")
                + ("" if ta is None else f"; best on VAF of k: {ta}" + (" on both" if ta == tb else f" vs {tb}"))
                + ".")
    return lines


def _settings_text(s: str) -> str:
    try:
        d = json.loads(s)
    except (TypeError, ValueError):
        return str(s)
    if not isinstance(d, dict):
        return str(s)
    return ", ".join(f"{k}={v}" for k, v in d.items()) or "(defaults)"


def settings_table(rows: pd.DataFrame) -> pd.DataFrame:
    """Method, tuning, settings (from the rows' ``settings`` column) and the scenarios that used them."""
    if "settings" not in rows.columns:
        return pd.DataFrame()
    rows = with_nothing_to_tune(rows)
    sel = rows[rows["settings"].notna() & (rows["settings"].astype(str) != "") & (rows["estimator"] != SCENARIO_ROWS)
               & ~rows["metric"].isin(FAILURES)]
    recs = []
    for (method, tuning, s), g in sel.groupby(["method", "tuning", "settings"], sort=True):
        cells = list(dict.fromkeys(g["cell"]))
        how = str(g["tuned_as"].dropna().iloc[0]) if "tuned_as" in g and g["tuned_as"].notna().any() else tuning
        recs.append({"method": method, "tuning": how, "settings": _settings_text(s), "scenarios": len(cells),
                     "which": "; ".join(cells[:3]) + (f"; ... ({len(cells) - 3} more)" if len(cells) > 3 else "")})
    return pd.DataFrame(recs)


def tuning_table(rows: pd.DataFrame) -> pd.DataFrame:
    """The tuning search: per method and cell, the candidates tried, the chosen one, whether it lies on an
    edge of the candidates (the rows' ``tuning_edge``) and its held-out output VAF (rows
    ``tuning_vaf_output``)."""
    sel = rows[rows["metric"] == "tuning_vaf_output"]
    if sel.empty:
        return pd.DataFrame()
    recs = []
    for (method, cell, backend), g in sel.groupby(["method", "cell", "backend"], sort=False):
        chosen = g[g["chosen"].astype(str).str.lower().isin(["true", "1", "1.0"])] if "chosen" in g else g.iloc[0:0]
        c = chosen.iloc[0] if len(chosen) else g.loc[g["value"].astype(float).idxmax()]
        edge = c.get("tuning_edge", "")
        recs.append({"method": method, "scenario": cell, "backend": backend, "candidates": len(g),
                     "chosen": _settings_text(c.get("candidate", "")), "edge": "" if pd.isna(edge) else edge,
                     "held-out output VAF (%)": float(c["value"]),
                     "worst candidate (%)": float(g["value"].astype(float).min())})
    return pd.DataFrame(recs)


def _design(reason: pd.Series) -> pd.Series:
    """Skips that are the grid's design (its ``only`` rules: reasons led by a reading id, 'M3: ...') or a
    tuned column with nothing to tune: not failures."""
    r = reason.fillna("").astype(str)
    return r.str.match(r"^[A-Z]+\d+:") | r.str.contains("nothing to tune", case=False)


def reasons(rows: pd.DataFrame) -> pd.DataFrame:
    """Skipped and not-fitted combinations: one line per method and reason, with the scenarios. Skips by
    the grid's design are counted separately (:func:`design_skips`)."""
    sel = rows[rows["metric"].isin(FAILURES)]
    if "reason" in sel:
        sel = sel[~_design(sel["reason"])]
    if sel.empty:
        return pd.DataFrame()
    out = []
    for (metric, method, reason), g in sel.groupby(["metric", "method", sel["reason"].fillna("")], sort=False):
        cells = list(dict.fromkeys(g["cell"]))
        out.append({"what": {"skipped": "skipped (not run)", "not_fitted": "run, refused the data",
                             "not_scored": "fitted, nothing to score",
                             "refused": "fitted, refused by the output gate"}[metric],
                    "method": method, "reason": reason, "scenarios": len(cells),
                    "which": "; ".join(cells[:4]) + (f"; ... ({len(cells) - 4} more)" if len(cells) > 4 else "")})
    return pd.DataFrame(out)


def design_skips(rows: pd.DataFrame) -> pd.DataFrame:
    """Combinations the grid leaves out by design: one line per reason with the number of combinations."""
    if "reason" not in rows:
        return pd.DataFrame()
    sel = rows[(rows["metric"] == "skipped") & _design(rows["reason"])]
    if sel.empty:
        return pd.DataFrame()
    n = sel.groupby(sel["reason"].astype(str), sort=False).size()
    return pd.DataFrame({"left out by the grid's design": n.index, "combinations": n.to_numpy()})


# ----------------------------------------------------------------------------- per-scenario tables
def cell_text(r) -> str:
    """'value [lo, hi] #rank' of one row of the full table."""
    s = _num(r["value"])
    if not (np.isnan(r["lo"]) or np.isnan(r["hi"])) and r["lo"] != r["hi"]:      # an end may be infinite
        s += f" [{_num(r['lo'])}, {_num(r['hi'])}]"
    if np.isfinite(r["rank"]):
        s += f" #{int(r['rank'])}"
    return s


def scenario_tables(table: pd.DataFrame, backend: str) -> list[tuple[str, pd.DataFrame, str]]:
    """Per cell of ``backend``: (cell, methods x metrics with 'value [lo, hi] #rank', a note on what could
    not be ranked). The rows are method x tuning, sorted by the rank on VAF of k."""
    out = []
    t = table[table["backend"] == backend]
    for cell, g in t.groupby("cell", sort=False):
        metrics = [m for m in METRICS if m in set(g["metric"])]
        recs = []
        for (method, tuning), h in g.groupby(["method", "tuning"], sort=False):
            rec = {"method": method, "tuning": tuning}
            by = h.set_index("metric")
            for m in metrics:
                rec[METRICS[m][0]] = cell_text(by.loc[m]) if m in by.index else ""
            key = by.loc["vaf_stiffness", "rank"] if "vaf_stiffness" in by.index else np.nan
            rec["_k"] = key if np.isfinite(key) else 1e9
            recs.append(rec)
        df = pd.DataFrame(recs)
        df["_k"] = df.groupby("method")["_k"].transform("min")         # a method's tuning rows side by side
        df = df.sort_values(["_k", "method", "tuning"]).drop(columns="_k")
        notes = []
        for m in metrics:
            h = g[g["metric"] == m]
            if h["note"].str.startswith("cannot rank").all():
                notes.append(f"{METRICS[m][0]}: cannot rank (no finite value)")
            n_flat = int(h["note"].str.contains("constant estimate").sum())
            if n_flat:
                notes.append(f"{METRICS[m][0]}: {n_flat} constant estimates not ranked (no tracking spread)")
            n_inf = int(h["note"].eq("not ranked: not finite").sum())
            if n_inf:
                notes.append(f"{METRICS[m][0]}: {n_inf} not finite, not ranked")
        out.append((cell, df, "; ".join(notes)))
    return out
