"""Figures and tables of van de Ruit et al. (2018), simulation study (Table I, Figs. 3-4, 7(b)/8(a)).

Drawn from the tidy rows and curves only. The published Table I values shown beside the reproduced
ones are read from the study's published-values file (the checks), never copied here.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from jointbench.benchmarks.checks import verdict
from jointbench.benchmarks.figures import PartReport, new_figure, register, save
from jointbench.benchmarks.studies.vanderuit2018_table1.protocol import (TABLE1_METRICS, inferred_noise_ratio,
                                                           prefilter_noise_ratio)
from jointbench.benchmarks.tables import median_range, over_seeds

LABELS = {"vaf_self": "VAF_self (%)", "vaf_optim": "VAF_optim (%)", "vaf_val": "VAF_val (%)",
          "rmse_k": "RMSE_k (N·m/rad)"}
COLORS = {"kbr": "tab:red", "skirt": "tab:blue"}
VARIATION_NAMES = {"sine20": "sine 20 s", "square10": "square 10 s", "square20": "square 20 s",
                   "square30": "square 30 s"}


def _snr_text(v: float) -> str:
    return "Inf" if not math.isfinite(float(v)) else f"{float(v):g}"


def _snr_order(values: pd.Series) -> list[float]:
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
    """Per Table I column: how many published cells this part meets, each judged by its check
    (:func:`benchmarks.checks.verdict`: the check's own aggregate over this part's rows)."""
    st = _stats(rows)
    part = _part_of(rows)
    recs = []
    for m in TABLE1_METRICS:
        for ev in ("reproduction", "conditional", "calibrated"):
            n = hit = 0
            for (metric, est, var, snr), c in published.items():
                key = (var, est, snr, metric)
                if metric != m or key not in st.index or getattr(c, "evidence", "reproduction") != ev:
                    continue
                n += 1
                hit += int(verdict(c, rows, part)[5] == "pass")
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


def _part_of(rows: pd.DataFrame) -> str | None:
    """The part whose rows these are (a figure maker gets one part's rows)."""
    return str(rows["part"].iloc[0]) if len(rows) and "part" in rows.columns else None


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
    present, names = set(rows["variation"]), set(rows["estimator"])
    variations = [v for v in VARIATION_NAMES if v in present]
    variations += sorted(present - set(variations))
    ests = [e for e in ("kbr", "skirt") if e in names]
    ests += sorted(names - set(ests) - {"", "truth", "bound"} - {np.nan})
    snrs = _snr_order(rows["snr_db"].dropna())
    recs = []
    for var in variations:
        for est in ests:
            for snr in snrs:
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
    present = set(c["variation"].unique())
    rows = [v for v in variations if v in present]
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
    present = set(c["series"].unique())
    series = ["truth"] + [s for s in ("kbr", "skirt") if s in present]
    series += sorted(present - set(series))
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


BOUND_ADOPTED = {"interval": "paper", "truth": "frozen", "fit": "window"}
BOUND_NAMES = {"paper": "[0, 30] s (R2)", "first30": "first 30 s of the window", "window": "whole 40 s window",
               "frozen": "frozen |G(jω₁, t)| (R5)", "intrinsic": "intrinsic k(t)",
               "scored": "fitted on the scored samples (exact bound)", "window_fit": "fitted over the window"}


def _bounds(rows: pd.DataFrame) -> pd.DataFrame:
    """Median over seeds of ``rmse_k_bound`` per (variation, interval, truth, fit, n_p)."""
    b = rows[(rows["metric"] == "rmse_k_bound") & (rows["status"] == "ok")]
    if b.empty:
        return b
    keys = ["variation", "interval", "truth", "fit", "n_p"]
    out = b.groupby(keys)["value"].median().reset_index()
    out["n_p"] = out["n_p"].astype(int)
    return out


def _published_noise_free(published: dict, var: str) -> float | None:
    c = published.get(("rmse_k", "skirt", var, math.inf))
    return float(c.published) if c is not None else None


def bound_frame(rows: pd.DataFrame, published: dict) -> pd.DataFrame:
    """Skirt bound: per alternative (scored interval, truth, fit) and square wave, the bound at N_p = 7 (the
    text's order), the published noise-free skirt RMSE_k, and the smallest tried N_p whose bound reaches it
    (from the rows; none when no tried order does)."""
    b = _bounds(rows)
    if b.empty:
        return pd.DataFrame()
    recs = []
    for (iv, tr, fit), g in b.groupby(["interval", "truth", "fit"], sort=False):
        rec = {"scored interval": BOUND_NAMES.get(iv, iv), "truth": BOUND_NAMES.get(tr, tr),
               "projection": BOUND_NAMES["window_fit" if fit == "window" else fit],
               "adopted": "yes" if (iv, tr, fit) == tuple(BOUND_ADOPTED.values()) else ""}
        need = []
        for var in ("square10", "square20", "square30"):
            gv = g[g["variation"] == var].sort_values("n_p")
            pub = _published_noise_free(published, var)
            if gv.empty or pub is None:
                continue
            at7 = gv.loc[gv["n_p"] == 7, "value"]
            rec[f"{VARIATION_NAMES[var]}: N_p = 7 bound"] = f"{float(at7.iloc[0]):.3f}" if len(at7) else ""
            rec[f"{VARIATION_NAMES[var]}: published"] = f"{pub:g}"
            ok = gv.loc[gv["value"] <= pub + 0.005, "n_p"]          # the printed rounding
            rec[f"{VARIATION_NAMES[var]}: smallest N_p reaching it"] = str(int(ok.iloc[0])) if len(ok) else "none"
            need.append(int(ok.iloc[0]) if len(ok) else None)
        rec["smallest N_p reaching all three"] = ("none tried" if not need or None in need else str(max(need)))
        recs.append(rec)
    return pd.DataFrame(recs)


def bound_orders_frame(rows: pd.DataFrame, published: dict) -> pd.DataFrame:
    """The adopted alternative's bound against N_p, one column per variation."""
    b = _bounds(rows)
    if b.empty:
        return pd.DataFrame()
    sel = b[(b["interval"] == BOUND_ADOPTED["interval"]) & (b["truth"] == BOUND_ADOPTED["truth"])
            & (b["fit"] == BOUND_ADOPTED["fit"])]
    t = sel.pivot_table(index="n_p", columns="variation", values="value").round(3)
    t = t[[v for v in VARIATION_NAMES if v in t.columns]].rename(columns=VARIATION_NAMES)
    pub = {VARIATION_NAMES[v]: _published_noise_free(published, v) for v in VARIATION_NAMES}
    t.loc["published (skirt, SNR Inf)"] = [pub.get(c) for c in t.columns]
    return t.reset_index().rename(columns={"n_p": "N_p"})


def bound_figure(rows: pd.DataFrame, published: dict, skirt_np, folder: Path, name: str) -> str | None:
    """Bound against N_p per square wave (the adopted alternative solid, the others thin), the published
    noise-free skirt RMSE_k (dashed) and this part's skirt (a dot at its N_p)."""
    b = _bounds(rows)
    if b.empty:
        return None
    squares = [v for v in ("square10", "square20", "square30") if v in set(b["variation"])]
    fig, axes = new_figure(1, len(squares), figsize=(3.6 * len(squares), 3.2), squeeze=False)
    own = rows[(rows["metric"] == "rmse_k") & (rows["estimator"] == "skirt") & (rows["status"] == "ok")]
    own = own[~np.isfinite(own["snr_db"].astype(float))]
    for ax, var in zip(axes[0], squares):
        gv = b[b["variation"] == var]
        for (iv, tr, fit), g in gv.groupby(["interval", "truth", "fit"]):
            g = g.sort_values("n_p")
            adopted = (iv, tr, fit) == tuple(BOUND_ADOPTED.values())
            ax.plot(g["n_p"], g["value"], color="k" if adopted else "0.7", lw=1.8 if adopted else 0.7,
                    marker="o" if adopted else None, ms=3, zorder=3 if adopted else 1,
                    label="bound (adopted: [0, 30] s, frozen, over window)" if adopted else None)
        pub = _published_noise_free(published, var)
        if pub is not None:
            ax.axhline(pub, color="tab:green", ls="--", lw=1.2, label=f"published skirt {pub:g}")
        mine = own[own["variation"] == var]["value"]
        if len(mine) and skirt_np is not None:
            ax.plot([skirt_np], [float(mine.median())], "s", color="tab:blue", ms=6,
                    label=f"this part's skirt (N_p = {skirt_np})")
        ax.axvline(7, color="tab:red", lw=0.6, ls=":")
        ax.set_title(VARIATION_NAMES[var], fontsize=9)
        ax.set_xlabel("N_p (eq. 14)")
        ax.set_ylim(bottom=0)
    axes[0][0].set_ylabel("best possible RMSE_k (N·m/rad)")
    axes[0][0].legend(fontsize=6, loc="upper right")
    fig.suptitle("Skirt bound: least-squares projection of the true stiffness onto the eq. 14 basis "
                 "(grey: other intervals, truths, fits; dotted: the text's N_p = 7)", fontsize=8)
    return save(fig, folder, name)


def noise_derivation_frame(published: dict, ratios: dict, cutoff_hz: float = 15.0, order: int = 2,
                           white_hz: float = 50.0, scored_hz: float = 22.0) -> pd.DataFrame:
    """Reading R1 tried as a derivation: per nominal SNR, the ratio each published row implies (KBR and skirt
    ranges, :func:`inferred_noise_ratio`), the configured (calibrated) ratio, and what white noise to
    ``white_hz`` scaled to the SNR before the 15 Hz filter gives on the scored record (0 ... ``scored_hz``,
    the 44 Hz decimation of R9) and on the whole filtered noise (0 ... ``white_hz``)."""
    recs = []
    for snr in (5.0, 10.0):
        rec = {"SNR (dB)": f"{snr:g}"}
        for est in ("kbr", "skirt"):
            rs = []
            for var in VARIATION_NAMES:
                val, opt = published.get(("vaf_val", est, var, snr)), published.get(("vaf_optim", est, var, snr))
                if val is not None and opt is not None:
                    rs.append(inferred_noise_ratio(float(val.published), float(opt.published)))
            rec[f"inferred from the published {est} rows"] = f"{min(rs):.3f}-{max(rs):.3f}" if rs else ""
        conf = next((v for k, v in ratios.items() if math.isclose(float(k), snr)), None)
        rec["configured (calibrated, R1)"] = f"{float(conf):.3f}" if conf is not None else ""
        on = prefilter_noise_ratio(snr, cutoff_hz, order, white_hz, scored_hz)
        full = prefilter_noise_ratio(snr, cutoff_hz, order, white_hz, white_hz)
        rec[f"derived, scored 0-{scored_hz:g} Hz (our 44 Hz record)"] = f"{on:.3f}"
        rec[f"derived, all the filtered noise (0-{white_hz:g} Hz)"] = f"{full:.3f}"
        recs.append(rec)
    return pd.DataFrame(recs)


def gaps_frame(rows: pd.DataFrame, checks) -> pd.DataFrame:
    """KBR - skirt of this part's medians for every method-difference check of Table I (published gap, its
    size band when there is one), whatever part the check belongs to: the gaps under this part's variant, each
    judged by its check (:func:`benchmarks.checks.verdict` on this part's rows)."""
    st = _stats(rows)
    part = _part_of(rows)
    recs = {}
    for c in checks:
        if getattr(c, "count", "") != "method_difference" or not c.versus:
            continue
        sel, ver = dict(c.select), dict(c.versus)
        m, var, snr = sel["metric"], str(sel["variation"]), float(sel["snr_db"])
        ka, kb = (var, str(sel["estimator"]), snr, m), (var, str(ver["estimator"]), snr, m)
        if ka not in st.index or kb not in st.index:
            continue
        key = (var, snr, m)
        gap, _, _, _, _, status = verdict(c, rows, part)
        rec = recs.setdefault(key, {"variation": VARIATION_NAMES.get(var, var), "SNR (dB)": _snr_text(snr),
                                    "column": LABELS[m], "published KBR - skirt": str(c.published).split(" (")[0]
                                    .replace("KBR - skirt = ", ""), "reproduced": f"{gap:+.3g}",
                                    "sign": "", "size band": "", "size": ""})
        kind = c.id.rsplit("-", 1)[-1]
        inside = status == "pass"
        if kind == "sign":
            rec["sign"] = "pass" if inside else "**MISS**"
        else:
            rec["size band"] = f"[{c.low:.3g}, {c.high:.3g}]"
            rec["size"] = "pass" if inside else "**MISS**"
    return pd.DataFrame(list(recs.values()))


@register("vanderuit2018.table1")
def table1(part, rows, curves, folder, checks) -> PartReport:
    rows = rows.copy()
    rows["estimator"] = rows["estimator"].fillna("")
    published = published_cells(checks)
    figs = []
    if len(curves):
        curves = curves.copy()
        curves["snr_db"] = curves["snr_db"].astype(float)
        present = set(curves["variation"].unique())
        squares = [v for v in ("square10", "square20", "square30") if v in present]
        others = [v for v in sorted(present) if v not in squares]
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
    metrics = set(rows["metric"].unique())
    more = [m for m in ("vaf_self_window", "vaf_optim_window", "vaf_val_window", "rmse_k_intrinsic")
            if m in metrics]
    if more:
        tables.append(("Whole-window VAFs (reading R3) and RMSE against the intrinsic k(t) (reading R5)",
                       extra_frame(rows[rows["estimator"].fillna("") != ""], more)))
    steps = [m for m in ("step_ramp_time_s", "step_captured") if m in metrics]
    if steps:
        tables.append(("Square-wave steps (reading R10): equivalent ramp time (s) and fraction of the step "
                       "captured within 1 s", extra_frame(rows, steps)))
    noise = [m for m in ("noise_variance_ratio", "snr_db_actual", "noise_variance_ratio_window",
                         "snr_db_actual_window") if m in metrics]
    if noise:
        t = extra_frame(rows[rows["estimator"].fillna("") == ""], noise)
        tables.append(("Noise actually added to the estimation trial (reading R1): var(noise)/var(torque) and "
                       "the standard SNR, scored interval and whole window", t.drop(columns=["estimator"])))
    if part.name == "table1" and (part.params.get("variance_ratio") or {}):
        tables.append(("Reading R1 tried as a derivation (issue 19): white noise to 50 Hz scaled to the nominal SNR "
                       "before the 15 Hz filter, against the ratio the published rows imply", noise_derivation_frame(
                           published, part.params["variance_ratio"])))
    gaps = gaps_frame(rows, checks)
    if len(gaps) and part.name != "table1":
        tables.append(("Table I's gaps KBR - skirt under this part's settings (medians; the bands of the "
                       "method-difference checks of part table1, applied here for comparison, not scored)", gaps))
    bt = bound_frame(rows, published)
    if len(bt):
        tables.append(("Skirt bound (reading R12): the best RMSE_k the eq. 14 basis can reach without noise, at "
                       "the text's N_p = 7, for each alternative of the scored interval (R2), the truth (R5) and "
                       "the projection; and the smallest N_p whose bound reaches the published skirt value", bt))
        tables.append(("Skirt bound against N_p (adopted alternative: [0, 30] s, frozen |G(jω₁, t)|, projected "
                       "over the window; N·m/rad)", bound_orders_frame(rows, published)))
        np_ = (part.estimators.get("skirt") or {}).get("n_p")
        fb = bound_figure(rows, published, np_ if isinstance(np_, int) else None, folder,
                          f"{part.name}_skirt_bound.png")
        if fb:
            figs.append((fb, "Skirt bound against the basis order N_p for the square waves without noise (reading "
                             "R12): a published RMSE_k below the curve cannot come from that basis."))
    text = ("Medians over seeds; the checks above compare the median with the published value. "
            "Noise levels are nominal (reading R1 says what they mean in each part).")
    note = outliers(rows)
    if note:
        text += "\n\n" + note
    return PartReport(figures=figs, tables=tables, text=text)
