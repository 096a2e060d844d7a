"""Figures and tables of van de Ruit et al. (2018), simulation study (Table I, Figs. 3-4, 7(b)/8(a)).

Drawn from the tidy rows and curves only. The published Table I values shown beside the reproduced
ones are read from the study's published-values file (the checks), never copied here.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from jointbench.benchmarks.figures import PartReport, new_figure, register, save
from jointbench.benchmarks.protocols.vanderuit2018 import TABLE1_METRICS
from jointbench.benchmarks.tables import median_range, over_seeds

LABELS = {"vaf_self": "VAF_self (%)", "vaf_optim": "VAF_optim (%)", "vaf_val": "VAF_val (%)",
          "rmse_k": "RMSE_k (N·m/rad)"}
COLORS = {"kbr": "tab:red", "skirt": "tab:blue"}
VARIATION_NAMES = {"sine20": "sine 20 s", "square10": "square 10 s", "square20": "square 20 s",
                   "square30": "square 30 s"}


def _snr_text(v: float) -> str:
    return "Inf" if not math.isfinite(float(v)) else f"{float(v):g}"


def _snr_order(values) -> list[float]:
    """Noise levels as in Table I: 5, 10, Inf."""
    return sorted({float(v) for v in values})


def published_cells(checks) -> dict[tuple, object]:
    """(metric, estimator, variation, snr_db) -> the value check of that Table I cell (published
    value and tolerance), from the study's published-values file. Checks of any part count, so a
    sensitivity part shows the same published values.
    """
    out = {}
    for c in checks:
        if getattr(c, "kind", "value") != "value":
            continue
        sel = dict(c.select)
        if set(sel) != {"metric", "estimator", "variation", "snr_db"}:
            continue
        out[(sel["metric"], str(sel["estimator"]), str(sel["variation"]), float(sel["snr_db"]))] = c
    return out


def within_tolerance(rows: pd.DataFrame, published: dict) -> pd.DataFrame:
    """Per Table I column: how many published cells this part's medians meet (the checks' bounds)."""
    st = _stats(rows)
    recs = []
    for m in TABLE1_METRICS:
        for ev in ("reproduction", "calibrated"):
            n = hit = 0
            for (metric, est, var, snr), c in published.items():
                key = (var, est, snr, metric)
                if metric != m or key not in st.index or getattr(c, "evidence", "reproduction") != ev:
                    continue
                n += 1
                hit += int(c.low <= float(st.loc[key, "median"]) <= c.high)
            if n:
                recs.append({"column": LABELS[m], "evidence": ev, "cells within tolerance": f"{hit} of {n}"})
    return pd.DataFrame(recs)


def outliers(rows: pd.DataFrame, floor: float = 50.0) -> str:
    """A sentence naming the cases whose VAF fell below ``floor`` percent (medians hide them)."""
    sel = rows[(rows["status"] == "ok") & rows["metric"].isin(["vaf_self", "vaf_optim", "vaf_val"])
               & (rows["value"] < floor)]
    if sel.empty:
        return ""
    items = [f"`{case}` ({est}: {', '.join(g['metric'])} down to {g['value'].min():.4g} %)"
             for (case, est), g in sel.groupby(["case_id", "estimator"], sort=True)]
    return (f"Outliers (VAF below {floor:g} %, kept in the medians and ranges): " + "; ".join(items) + ".")


def _fmt(med: float, lo: float, hi: float, n: int, digits: int) -> str:
    return median_range(med, lo, hi, n, digits)


def _stats(rows: pd.DataFrame) -> pd.DataFrame:
    ok = rows.copy()
    ok["snr_db"] = ok["snr_db"].astype(float)
    ok["estimator"] = ok["estimator"].fillna("")
    keys = ["variation", "estimator", "snr_db", "metric"]
    return over_seeds(ok, keys).set_index(keys)


def table1_frame(rows: pd.DataFrame, published: dict) -> pd.DataFrame:
    """Table I: per variation, method and noise level, each metric's published value beside the
    reproduced median (min-max over seeds)."""
    st = _stats(rows)
    variations = [v for v in VARIATION_NAMES if v in set(rows["variation"])]
    variations += sorted(set(rows["variation"]) - set(variations))
    ests = [e for e in ("kbr", "skirt") if e in set(rows["estimator"])]
    ests += sorted(set(rows["estimator"]) - set(ests) - {"", "truth"} - {np.nan})
    recs = []
    for var in variations:
        for est in ests:
            for snr in _snr_order(rows["snr_db"].dropna()):
                rec = {"variation": VARIATION_NAMES.get(var, var), "method": est, "SNR (dB)": _snr_text(snr)}
                for m in TABLE1_METRICS:
                    c = published.get((m, est, var, snr))
                    pub = c.published if c is not None else "–"
                    key = (var, est, snr, m)
                    if key in st.index:
                        r = st.loc[key]
                        rep = _fmt(r["median"], r["min"], r["max"], int(r["n"]), 2 if m == "rmse_k" else 1)
                    else:
                        rep = ""
                    rec[f"{LABELS[m]} published"] = pub
                    rec[f"{LABELS[m]} reproduced"] = rep
                recs.append(rec)
    return pd.DataFrame(recs)


def extra_frame(rows: pd.DataFrame, metrics: list[str]) -> pd.DataFrame:
    """Median (min-max over seeds) of further metrics, one column each."""
    st = _stats(rows)
    recs = []
    keys = sorted({k[:3] for k in st.index if k[3] in metrics},
                  key=lambda k: (list(VARIATION_NAMES).index(k[0]) if k[0] in VARIATION_NAMES else 99,
                                 str(k[1]), k[2]))
    for var, est, snr in keys:
        rec = {"variation": VARIATION_NAMES.get(var, var), "estimator": est or "(data)", "SNR (dB)": _snr_text(snr)}
        for m in metrics:
            key = (var, est, snr, m)
            if key in st.index:
                r = st.loc[key]
                digits = 3 if ("ratio" in m or "rmse" in m or "step" in m) else 1
                rec[m] = _fmt(r["median"], r["min"], r["max"], int(r["n"]), digits)
            else:
                rec[m] = ""
        recs.append(rec)
    return pd.DataFrame(recs)


def _stiffness_panel(ax, curves: pd.DataFrame, var: str, snr: float, seed: int, band: bool) -> None:
    c = curves[(curves["variation"] == var) & (curves["snr_db"].astype(float) == snr)]
    full = c[(c["curve"] == "stiffness") & (c["seed"] == seed)]
    for series, s in full.groupby("series", sort=False):
        if series == "truth":
            ax.plot(s["x"], s["y"], color="k", lw=1.6, label="true |G(jω₁,t)|")
        elif series == "k":
            ax.plot(s["x"], s["y"], color="0.6", lw=0.8, ls=":", label="k(t)")
        else:
            ax.plot(s["x"], s["y"], color=COLORS.get(series, None), lw=1.0, label=series)
    if band:
        g = c[c["curve"] == "stiffness_grid"]
        for series, s in g.groupby("series", sort=False):
            if series == "truth":
                continue
            q = s.groupby("x")["y"].agg(["min", "max"])
            ax.fill_between(q.index, q["min"], q["max"], color=COLORS.get(series, "0.5"), alpha=0.15, lw=0)
    ax.axvspan(-5, 0, color="0.92", zorder=0)
    ax.axvspan(30, 35, color="0.92", zorder=0)
    ax.set_xlim(-5, 35)


def stiffness_figure(curves: pd.DataFrame, variations: list[str], folder: Path, name: str, title: str) -> str | None:
    """Figs. 3/4: true and estimated stiffness over time, one row per variation, one column per SNR."""
    if curves.empty or not (curves["curve"] == "stiffness").any():
        return None
    c = curves[curves["variation"].isin(variations)]
    if c.empty:
        return None
    seed = int(c.loc[c["curve"] == "stiffness", "seed"].min())
    snrs = sorted({float(v) for v in c["snr_db"]}, key=lambda v: -v)   # Inf, 10, 5 as in Fig. 3
    rows = [v for v in variations if v in set(c["variation"])]
    fig, axes = new_figure(len(rows), len(snrs), figsize=(3.4 * len(snrs), 2.4 * len(rows) + 1.0),
                           sharex=True, sharey=True, squeeze=False)
    for i, var in enumerate(rows):
        for j, snr in enumerate(snrs):
            ax = axes[i][j]
            _stiffness_panel(ax, c, var, snr, seed, band=True)
            if i == 0:
                ax.set_title(f"SNR {_snr_text(snr)} dB")
            if j == 0:
                ax.set_ylabel(f"{VARIATION_NAMES.get(var, var)}\nstiffness (N·m/rad)")
            if i == len(rows) - 1:
                ax.set_xlabel("time (s)")
    truth = c[(c["curve"] == "stiffness") & (c["series"] == "truth")]["y"]
    if len(truth):                       # keep the transient excursions of the bands from squashing the plot
        axes[0][0].set_ylim(float(truth.min()) - 2.5, float(truth.max()) + 2.5)
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.suptitle(f"{title} (lines: seed {seed}; bands: min-max over seeds; grey: transient, not scored)",
                 fontsize=9)
    h = fig.get_figheight()
    fig.tight_layout(rect=(0, 0.35 / h, 1, 1 - 0.3 / h))
    fig.legend(handles, labels, loc="lower center", bbox_to_anchor=(0.5, 0.0), ncol=len(labels), fontsize=8,
               frameon=False)
    return save(fig, folder, name)


def tf_figure(curves: pd.DataFrame, folder: Path, name: str) -> str | None:
    """Figs. 7(b)/8(a) style: |G(jω, t)| at the excited lines against time, true and estimated."""
    c = curves[curves["curve"] == "tf_mag"] if len(curves) else curves
    if c.empty:
        return None
    seed = int(c["seed"].min())
    c = c[c["seed"] == seed]
    cases = sorted({(v, float(s)) for v, s in zip(c["variation"], c["snr_db"])}, key=lambda k: (k[0], -k[1]))
    series = ["truth"] + [s for s in ("kbr", "skirt") if s in set(c["series"])]
    series += sorted(set(c["series"]) - set(series))
    fig, axes = new_figure(len(series), len(cases), figsize=(3.6 * len(cases), 2.5 * len(series) + 0.5),
                           sharex=True, sharey=True, squeeze=False)
    vmin, vmax = np.log10(c["y"].clip(lower=1e-3).quantile(0.01)), np.log10(c["y"].clip(lower=1e-3).quantile(0.99))
    im = None
    for j, (var, snr) in enumerate(cases):
        for i, s in enumerate(series):
            ax = axes[i][j]
            d = c[(c["variation"] == var) & (c["snr_db"].astype(float) == snr) & (c["series"] == s)]
            if d.empty:
                ax.set_axis_off()
                continue
            img = d.pivot_table(index="freq_hz", columns="x", values="y")
            im = ax.pcolormesh(img.columns, img.index, np.log10(img.clip(lower=1e-3).to_numpy()),
                               shading="nearest", vmin=vmin, vmax=vmax, cmap="viridis")
            ax.axvline(0, color="w", lw=0.6, ls="--")
            ax.axvline(30, color="w", lw=0.6, ls="--")
            if i == 0:
                ax.set_title(f"{VARIATION_NAMES.get(var, var)}, SNR {_snr_text(snr)} dB", fontsize=9)
            if j == 0:
                ax.set_ylabel(f"{'true' if s == 'truth' else s}\nfrequency (Hz)")
            if i == len(series) - 1:
                ax.set_xlabel("time (s)")
    if im is not None:
        cb = fig.colorbar(im, ax=[a for row in axes for a in row], shrink=0.8)
        cb.set_label("log10 |G(jω, t)| (N·m/rad)")
    fig.suptitle(f"|G(jω, t)| at the excited lines (seed {seed})", fontsize=9)
    return save(fig, folder, name)


@register("vanderuit2018.table1")
def table1(part, rows, curves, folder, checks) -> PartReport:
    rows = rows.copy()
    rows["estimator"] = rows["estimator"].fillna("")
    published = published_cells(checks)
    figs = []
    if len(curves):
        curves = curves.copy()
        curves["snr_db"] = curves["snr_db"].astype(float)
        squares = [v for v in ("square10", "square20", "square30") if v in set(curves["variation"])]
        others = [v for v in sorted(set(curves["variation"])) if v not in squares]
        f3 = stiffness_figure(curves, squares, folder, f"{part.name}_fig3_square.png",
                              "Fig. 3: square-wave stiffness")
        if f3:
            f_min = ((part.experiment or {}).get("perturbation") or {}).get("f_min", "the lowest line")
            figs.append((f3, f"Fig. 3 style: true frozen |G(jω₁, t)| at {f_min} (black) and the KBR (red) and skirt "
                             "(blue) estimates for the square waves, per noise level; grey spans: transients "
                             "outside the scored [0, 30] s."))
        f4 = stiffness_figure(curves, others, folder, f"{part.name}_fig4_sine.png", "Fig. 4: sinusoidal stiffness")
        if f4:
            periods = ", ".join(str((part.params.get("variations") or {}).get(v, {}).get("period", "?"))
                                for v in others)
            figs.append((f4, f"Fig. 4 style: the same for the sinusoidal stiffness (period {periods})."))
        f7 = tf_figure(curves, folder, f"{part.name}_tf_image.png")
        if f7:
            figs.append((f7, "Figs. 7(b)/8(a) style: |G(jω, t)| (log scale) at the 25 excited lines over the "
                             "window, true (top), KBR frozen FRF and skirt system function; dashed: the scored "
                             "[0, 30] s."))
    tables = [("Table I: published beside the reproduced median (min-max over seeds)", table1_frame(rows, published))]
    tol = within_tolerance(rows, published)
    if len(tol):
        tables.append(("Published cells met by this part's medians (tolerances of the T1 checks)", tol))
    more = [m for m in ("vaf_self_window", "vaf_optim_window", "vaf_val_window", "rmse_k_intrinsic")
            if m in set(rows["metric"])]
    if more:
        tables.append(("Whole-window VAFs (reading R3) and RMSE against the intrinsic k(t) (reading R5)",
                       extra_frame(rows[rows["estimator"].fillna("") != ""], more)))
    steps = [m for m in ("step_ramp_time_s", "step_captured") if m in set(rows["metric"])]
    if steps:
        tables.append(("Square-wave steps (reading R10): equivalent ramp time (s) and fraction of the step "
                       "captured within 1 s", extra_frame(rows, steps)))
    noise = [m for m in ("noise_variance_ratio", "snr_db_actual", "noise_variance_ratio_window",
                         "snr_db_actual_window") if m in set(rows["metric"])]
    if noise:
        t = extra_frame(rows[rows["estimator"].fillna("") == ""], noise)
        tables.append(("Noise actually added to the estimation trial (reading R1): var(noise)/var(torque) and "
                       "the standard SNR, scored interval and whole window", t.drop(columns=["estimator"])))
    text = ("Medians over seeds; the checks above compare the median with the published value. "
            "Noise levels are nominal (reading R1 says what they mean in each part).")
    note = outliers(rows)
    if note:
        text += "\n\n" + note
    return PartReport(figures=figs, tables=tables, text=text)
