"""Tables and figure of van de Ruit et al. (2018), Table II, on simulated subjects.

Drawn from the tidy rows and curves only. The published values shown beside the reproduced ones are
read from the study's published-values file (the checks), never copied here.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from jointbench.benchmarks.figures import PartReport, new_figure, register, save

METHODS = ("kbr", "skirt", "sds", "guarin", "ensemble_irf")
NAMES = {"kbr": "KBR", "skirt": "Skirt", "sds": "SDS", "guarin": "Guarin", "ensemble_irf": "Ensemble IRF"}
COLORS = {"kbr": "tab:red", "skirt": "tab:blue", "sds": "tab:green", "guarin": "tab:purple",
          "ensemble_irf": "tab:orange"}
#: (mode, estimator, metric) of the Table II columns, in the paper's order (the ensemble IRF added)
COLUMNS = [("single", "kbr", "vaf_self"), ("single", "kbr", "vaf_val"), ("single", "skirt", "vaf_self"),
           ("single", "skirt", "vaf_val")] + [("ensemble", m, "vaf_val") for m in METHODS]


def _ok(rows: pd.DataFrame) -> pd.DataFrame:
    out = rows[rows["status"] == "ok"].copy() if "status" in rows.columns else rows.copy()
    out["estimator"] = out["estimator"].fillna("")
    return out


def _num(v: float, digits: int) -> str:
    """Fixed point, or scientific for values a fixed-point cell cannot hold (a diverged fit)."""
    return f"{v:.{digits}f}" if abs(v) < 1e4 else f"{v:.2e}"


def _label(mode: str, est: str, metric: str) -> str:
    what = {"vaf_self": "VAF_self", "vaf_val": "VAF_val", "vaf_val_common": "VAF_val 0.8-22 Hz"}.get(metric, metric)
    return f"{'single' if mode == 'single' else 'ensemble'} {NAMES.get(est, est)} {what}"


def subject_stats(rows: pd.DataFrame, metric_cols: list[tuple[str, str, str]]) -> pd.DataFrame:
    """Mean and SD (over seeds and trials) per subject, and the paper's 'Overall': the mean of the
    subjects' means and of their SDs. Long frame: subject ('Overall' last), mode, estimator, metric,
    mean, sd, n."""
    ok = _ok(rows)
    recs = []
    for mode, est, metric in metric_cols:
        sel = ok[(ok["mode"] == mode) & (ok["estimator"] == est) & (ok["metric"] == metric)] \
            if "mode" in ok.columns else ok.iloc[0:0]
        if sel.empty:
            continue
        per = sel.groupby("subject")["value"].agg(mean="mean", sd=lambda v: float(np.std(v, ddof=1)) if len(v) > 1
                                                  else 0.0, n="count")
        for subj, r in per.iterrows():
            recs.append({"subject": f"P{int(subj)}", "mode": mode, "estimator": est, "metric": metric,
                         "mean": r["mean"], "sd": r["sd"], "n": int(r["n"])})
        recs.append({"subject": "Overall", "mode": mode, "estimator": est, "metric": metric,
                     "mean": float(per["mean"].mean()), "sd": float(per["sd"].mean()), "n": int(per["n"].sum())})
    return pd.DataFrame(recs)


def published_overall(checks) -> dict[tuple[str, str, str], object]:
    """(mode, estimator, metric) -> the value check of an overall Table II cell, from the published file; the
    check of the printed cell (a number) before a text's claim on the same cell (Sec. VI-A's '> 70')."""
    out = {}
    for c in checks:
        sel = dict(c.select)
        if getattr(c, "kind", "value") == "value" and set(sel) == {"metric", "estimator", "mode"}:
            key = (sel["mode"], sel["estimator"], sel["metric"])
            if key not in out or not isinstance(out[key].published, (int, float)):
                out[key] = c
    return out


def table2_frame(rows: pd.DataFrame, checks, digits: int = 1) -> pd.DataFrame:
    """Table II: one row per subject plus 'Overall' and 'Overall (published)', 'mean ± SD' cells."""
    ok = _ok(rows)
    cols = [c for c in COLUMNS if not ok[(ok["metric"] == c[2]) & (ok["estimator"] == c[1])
                                         & (ok.get("mode", pd.Series(dtype=str)) == c[0])].empty]
    st = subject_stats(rows, cols)
    if st.empty:
        return pd.DataFrame()
    pub = published_overall(checks)
    table = {}
    for r in st.itertuples():
        table.setdefault(r.subject, {})[_label(r.mode, r.estimator, r.metric)] = \
            f"{_num(r.mean, digits)} ± {_num(r.sd, digits)}"
    published = {_label(*k): str(c.published) for k, c in pub.items() if k in cols}
    order = sorted((s for s in table if s != "Overall"), key=lambda s: int(s[1:])) + ["Overall"]
    frame = pd.DataFrame([{"subject": s, **table[s]} for s in order])
    if published:
        frame = pd.concat([frame, pd.DataFrame([{"subject": "Overall (published)", **published}])], ignore_index=True)
    return frame.fillna("–")


def stiffness_frame(rows: pd.DataFrame) -> pd.DataFrame:
    """RMSE and bias of the estimated stiffness per method and mode: mean over subjects of the subjects' means,
    and the per-subject RMSE means."""
    ok = _ok(rows)
    if "mode" not in ok.columns:
        return pd.DataFrame()
    recs = []
    names = set(ok["estimator"].unique())
    for mode in ("single", "ensemble"):
        for est in [m for m in METHODS if m in names]:
            sel = ok[(ok["mode"] == mode) & (ok["estimator"] == est)]
            if sel.empty or not sel["metric"].isin(["rmse_k"]).any():
                continue
            per = sel.pivot_table(index="subject", columns="metric", values="value", aggfunc="mean")
            rec = {"mode": mode, "method": NAMES[est]}
            for s, v in per["rmse_k"].items():
                rec[f"RMSE P{int(s)}"] = f"{v:.2f}"
            rec["RMSE_k (N·m/rad)"] = f"{per['rmse_k'].mean():.2f}"
            rec["relative"] = f"{100 * per['rmse_k_rel'].mean():.1f} %" if "rmse_k_rel" in per else ""
            rec["bias_k (N·m/rad)"] = f"{per['bias_k'].mean():+.2f}"
            recs.append(rec)
    return pd.DataFrame(recs)


def skipped_frame(rows: pd.DataFrame) -> pd.DataFrame:
    ok = _ok(rows)
    if "reason" not in ok.columns:
        return pd.DataFrame()
    sel = ok[ok["metric"] == "skipped"]
    return sel[["estimator", "mode", "reason"]].drop_duplicates().reset_index(drop=True)


def design_frame(rows: pd.DataFrame) -> pd.DataFrame:
    """Achieved noise level and true stiffness range per subject (sanity of the simulated design)."""
    ok = _ok(rows)
    ok = ok[ok["estimator"] == ""]
    if ok.empty:
        return pd.DataFrame()
    g = ok.groupby(["subject", "metric"])["value"]
    t = pd.DataFrame({"noise ratio (mean)": g.mean().unstack().get("noise_variance_ratio"),
                      "k min": g.min().unstack().get("k_true_min"), "k max": g.max().unstack().get("k_true_max")})
    t.index = [f"P{int(s)}" for s in t.index]
    return t.round(3).reset_index(names="subject")


def stiffness_figure(curves: pd.DataFrame, folder, name: str, title: str) -> str | None:
    """Every method's k̂(t) against the truth for one subject: ensemble fits, then single-trial fits."""
    if curves.empty or not (curves["curve"] == "stiffness").any():
        return None
    c = curves[curves["curve"] == "stiffness"]
    subject, seed = int(c["subject"].min()), int(c["seed"].min())
    c = c[(c["subject"] == subject) & (c["seed"] == seed)]
    modes = [m for m in ("ensemble", "single") if m in set(c["mode"])]
    fig, axes = new_figure(len(modes), 1, figsize=(8.5, 3.2 * len(modes) + 0.6), sharex=True, squeeze=False)
    for ax, mode in zip(axes[:, 0], modes):
        d = c[c["mode"] == mode]
        truth = d[(d["series"] == "truth")]
        shown = False
        for est, s in truth.groupby("estimator", sort=False):
            if not shown:
                ax.plot(s["x"], s["y"], color="k", lw=1.8, label="true frozen stiffness")
                shown = True
        k = d[d["series"] == "k"]
        if len(k):
            ax.plot(k["x"], k["y"], color="0.6", lw=0.8, ls=":", label="intrinsic k(t)")
        for est in sorted((m for m in METHODS if m in set(d["series"])), key=lambda m: m != "ensemble_irf"):
            s = d[d["series"] == est]
            noisy = est == "ensemble_irf"          # drawn first and faint: it varies sample by sample
            ax.plot(s["x"], s["y"], color=COLORS[est], lw=0.6 if noisy else 1.1, alpha=0.45 if noisy else 1.0,
                    label=NAMES[est], zorder=1 if noisy else 2)
        ax.axvspan(0, 5, color="0.92", zorder=0)
        ax.axvspan(35, 40, color="0.92", zorder=0)
        ax.set_ylabel("stiffness (N·m/rad)")
        ax.set_title("ensemble of trials 1-5 (truth: their mean)" if mode == "ensemble"
                     else "single trial 1 (truth: that trial's)", fontsize=9)
        ax.legend(fontsize=7, ncol=3, loc="upper right", frameon=False)
        if len(truth):
            lo, hi = float(truth["y"].min()), float(truth["y"].max())
            ax.set_ylim(lo - 0.6 * (hi - lo) - 0.5, hi + 0.6 * (hi - lo) + 0.5)
    axes[-1, 0].set_xlabel("time in the analysis window (s); grey: not scored")
    fig.suptitle(f"{title}: subject P{subject}, seed {seed}", fontsize=9)
    fig.tight_layout()
    return save(fig, folder, name)


def gaps_frame(rows: pd.DataFrame, checks) -> pd.DataFrame:
    """Ensemble VAF_val overall per method over each method's own band and over the common 0.8-22 Hz band, and
    the gaps KBR - SDS and KBR - Guarin beside the published ones (the G1, G2 checks): Table II's gaps under
    this part's noise (reading S14)."""
    st = subject_stats(rows, [("ensemble", m, metric) for m in METHODS for metric in ("vaf_val", "vaf_val_common")])
    if st.empty:
        return pd.DataFrame()
    ov = st[st["subject"] == "Overall"].set_index(["estimator", "metric"])["mean"]
    pub = {str((c.versus or {}).get("estimator")): c.published for c in checks
           if c.id.startswith(("G1-", "G2-")) and c.versus}
    recs = []
    for metric, band in (("vaf_val", "each method's own band (44 Hz: 0.8-22 Hz; 100 Hz: 0.8-50 Hz)"),
                         ("vaf_val_common", "common band 0.8-22 Hz")):
        rec = {"VAF_val scored on": band}
        for m in METHODS:
            if (m, metric) in ov.index:
                rec[NAMES[m]] = f"{ov[(m, metric)]:.1f}"
        for other in ("sds", "guarin"):
            if ("kbr", metric) in ov.index and (other, metric) in ov.index:
                rec[f"KBR - {NAMES[other]}"] = f"{ov[('kbr', metric)] - ov[(other, metric)]:+.1f}"
        recs.append(rec)
    recs.append({"VAF_val scored on": "published (Table II, overall)",
                 **{f"KBR - {NAMES[o]}": f"+{pub[o]}" for o in ("sds", "guarin") if o in pub}})
    return pd.DataFrame(recs).fillna("")


@register("vanderuit2018.table2")
def table2(part, rows, curves, folder, checks) -> PartReport:
    tables = []
    t2 = table2_frame(rows, checks)
    if len(t2):
        tables.append(("Table II layout: VAF (%) mean ± SD per simulated subject (over seeds and trials) and "
                       "overall (mean of the subjects' means and SDs; reading S6)", t2))
    st = subject_stats(rows, [("ensemble", m, "vaf_val_common") for m in METHODS])
    if len(st):
        ov = st[st["subject"] == "Overall"]
        tables.append(("Ensemble VAF_val in the band both rates hold, 0.8-22 Hz (reading S5), overall",
                       pd.DataFrame([{NAMES[r.estimator]: f"{r.mean:.1f} ± {r.sd:.1f}" for r in ov.itertuples()}])))
    gp = gaps_frame(rows, checks)
    finding = ""
    if len(gp) > 1 and {"KBR - SDS", "KBR - Guarin"} <= set(gp.columns) and gp.iloc[0]["KBR - SDS"]:
        own, common, pub = gp.iloc[0], gp.iloc[1], gp.iloc[-1]
        finding = (f"\n\nGaps of this part (from its rows): KBR - SDS {own['KBR - SDS']} and KBR - Guarin "
                   f"{own['KBR - Guarin']} points when each method is scored over its own band, "
                   f"{common['KBR - SDS']} and {common['KBR - Guarin']} over the common 0.8-22 Hz band "
                   f"(published {pub['KBR - SDS']} and {pub['KBR - Guarin']}).")
    if len(gp) > 1:
        tables.append(("Ensemble VAF_val (%) overall and the gaps KBR - SDS, KBR - Guarin, over each method's band "
                       "and over the band both rates hold (readings S5, S14)", gp))
    sf = stiffness_frame(rows)
    if len(sf):
        tables.append(("Stiffness tracking (reading S11): RMSE per subject and overall, relative RMSE, bias "
                       "(estimated minus true)", sf))
    sk = skipped_frame(rows)
    if len(sk):
        tables.append(("Estimators skipped, with the reason", sk))
    dz = design_frame(rows)
    if len(dz):
        tables.append(("Simulated design: achieved var(noise)/var(torque) (reading S2) and the range of the true "
                       "intrinsic k(t)", dz))
    figs = []
    f = stiffness_figure(curves, folder, f"{part.name}_stiffness.png", part.name)
    if f:
        figs.append((f, "Every method's estimated stiffness against the truth for one subject (k̂ = Σh for the IRF "
                        "methods, |Ĥ(jω₁, t)| at 0.1 Hz for KBR and skirt); top: fitted on trials 1-5 (truth: their "
                        "mean), bottom: single-trial fits of trial 1."))
    seeds = sorted(set(_ok(rows)["seed"])) if "seed" in rows.columns else []
    text = (f"{len(seeds)} seed(s) x {rows['subject'].nunique() if 'subject' in rows.columns else 0} simulated "
            "subjects; every VAF after removing the frequencies below 0.8 Hz, over the scored 5-35 s of the window."
            + finding)
    return PartReport(figures=figs, tables=tables, text=text)
