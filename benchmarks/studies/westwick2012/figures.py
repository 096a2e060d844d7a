"""Figures and tables of the Westwick & Perreault (2012) parts, drawn from the tidy results."""
from __future__ import annotations

import numpy as np
import pandas as pd

from jointbench.benchmarks.figures import PartReport, first_seed, new_figure, register, save, summary_over_seeds


def _curve(curves: pd.DataFrame, name: str, **eq) -> pd.DataFrame:
    sel = curves[curves["curve"] == name]
    for k, v in eq.items():
        sel = sel[sel[k] == v]
    return sel


@register("westwick2012.differentiators")
def differentiators(part, rows, curves, folder, checks) -> PartReport:
    order = int(part.params.get("order", 1))
    fig, (a, b) = new_figure(2, 1, figsize=(6.5, 5.5))
    per = _curve(curves, "periodic", series="closed form")
    ref = _curve(curves, "periodic", series="inverse DFT")
    a.plot(per["x"], per["y"], "k-", lw=1, label="closed form (eq. %d)" % (12 if order == 1 else 13))
    a.plot(ref["x"], ref["y"], "r.", ms=2, label="inverse DFT")
    a.set_xlabel("n (samples)")
    a.set_ylabel("h%d(n) / (ws/N)^%d" % (order, order))
    a.legend(fontsize=8)
    two = _curve(curves, "two_sided")
    b.stem(two["x"], two["y"], basefmt="k-")
    b.set_xlabel("lag (samples)")
    b.set_ylabel("periodic extension")
    a.set_title(("Differentiator" if order == 1 else "Double differentiator") + " IRF, N = %d" %
                int(part.params.get("N", 256)))
    name = save(fig, folder, f"{part.name}.png")
    cap = f"{part.description}: upper, the N-point sequence; lower, its periodic extension around lag 0."
    return PartReport(figures=[(name, cap)],
                      tables=[("Agreement and symmetry", summary_over_seeds(rows, part.name, []))])


@register("westwick2012.sampling_rate")
def sampling_rate(part, rows, curves, folder, checks) -> PartReport:
    fs_list = sorted(curves["fs_hz"].dropna().unique(), reverse=True)
    fig, axes = new_figure(len(fs_list), 1, figsize=(6, 1.7 * len(fs_list)), sharex=True)
    axes = np.atleast_1d(axes)
    for ax, fs in zip(axes, fs_list):
        c = _curve(curves, "irf_over_fs2", fs_hz=fs)
        ax.stem(c["x"], c["y"], basefmt="k-")
        ax.set_ylabel(f"{fs:g} Hz")
    joint = part.params.get("joint") or {}
    axes[0].set_title("Ankle impedance IRF / fs^2 (" + ", ".join(f"{k} = {joint[k]}" for k in ("I", "B", "K")
                                                                 if k in joint) + ")")
    axes[-1].set_xlabel("lag (samples)")
    name = save(fig, folder, f"{part.name}.png")
    t = summary_over_seeds(rows, part.name, ["fs_hz"])
    return PartReport(figures=[(name, part.description)], tables=[("Shape against sampling rate", t)])


@register("westwick2012.input_bandlimit")
def input_bandlimit(part, rows, curves, folder, checks) -> PartReport:
    fig, ax = new_figure(figsize=(6.5, 4))
    for series, c in curves[curves["curve"] == "irf"].groupby("series", sort=False):
        ax.plot(c["x"] * 1e3, c["y"], label=series, lw=1.5 if series == "no noise" else 1)
    ax.set_xlim(-100, 100)
    ax.set_xlabel("lag (ms)")
    ax.set_ylabel("impedance IRF (N·m/rad per sample)")
    snr = [float(v) for v in np.atleast_1d(part.params.get("snr_db", []))]
    ax.set_title(f"Elbow impedance IRF at {part.params.get('fs', '?')}, {part.params.get('cutoff', '?')} input, "
                 f"angle SNR {min(snr, default=np.nan):g}-{max(snr, default=np.nan):g} dB (eq. 17)")
    ax.legend(fontsize=8)
    name = save(fig, folder, f"{part.name}.png")
    return PartReport(figures=[(name, part.description)],
                      tables=[("Distortion and spread against angle SNR",
                               summary_over_seeds(rows, part.name, ["snr_db"]))])


@register("westwick2012.sampling_rate_experiment")
def sampling_rate_experiment(part, rows, curves, folder, checks) -> PartReport:
    c0 = first_seed(curves)
    fs_list = sorted(c0["fs_hz"].dropna().unique(), reverse=True)
    fig, axes = new_figure(len(fs_list), 1, figsize=(6, 1.8 * len(fs_list)))
    axes = np.atleast_1d(axes)
    for ax, fs in zip(axes, fs_list):
        for series, style in (("nonparametric", "k-"), ("parametric", "r--")):
            c = _curve(c0, "irf_over_fs2", fs_hz=fs, series=series)
            ax.plot(c["x"] / fs * 1e3, c["y"], style, label=series)
        ax.set_ylabel(f"{fs:g} Hz")
    axes[0].legend(fontsize=8)
    axes[0].set_title(f"Band-limited ({part.params.get('bandlimit', '?')}) impedance IRFs / fs^2 (Fig. 7)")
    axes[-1].set_xlabel("lag (ms)")
    name = save(fig, folder, "fig7.png")
    sel = rows[(rows["metric"] == "vaf_parametric_irf") & (rows["status"] == "ok")]
    table = (sel.groupby("fs_hz")["value"].agg(["median", "mean", "std", "min", "max", "count"])
             .reset_index().sort_values("fs_hz"))
    params = summary_over_seeds(rows[rows["metric"].isin(["I", "B", "K"])], part.name, [])
    shape = summary_over_seeds(rows[rows["metric"] == "shape_diff_pct"], part.name, ["fs_hz"])
    invariance = summary_over_seeds(rows[rows["metric"].isin(["vaf_parametric_irf_range", "residual_ratio_lowest_rate",
                                                              "lowest_rate_over_nyquist"])], part.name, [])
    return PartReport(figures=[(name, "Fig. 7: nonparametric (solid) and parametric (dashed) IRFs, seed "
                                f"{int(c0['seed'].min())}")],
                      tables=[("Table I: parametric IRF fit (%VAF) by sampling rate, over seeds (published values: "
                               "checks W5 above)", table),
                              (f"I, B, K fitted at {max(float(f) for f in part.params['fs']):g} Hz"
                               if part.params.get("fs") else "I, B, K", params),
                              ("Shape difference (%) of each rate's nonparametric IRF against the 500 Hz one "
                               "(reading R16; checks W7-shape)", shape),
                              ("Change of the parametric IRF fit (%VAF) with the sampling rate, per trial: its range "
                               "over the rates, the unexplained variance at the lowest rate over that at the highest, "
                               "and the lowest rate over the band's Nyquist rate (reading R19; check "
                               "W5-rate-invariance)", invariance)])


@register("westwick2012.input_noise")
def input_noise(part, rows, curves, folder, checks) -> PartReport:
    c0 = first_seed(curves)
    fig, (a, b) = new_figure(2, 1, figsize=(6.5, 6.5), sharex=True)
    for series, s in _curve(c0, "coherence2").groupby("series"):
        a.semilogx(s["x"], s["y"], {"before": "0.6", "after": "k"}[series], label=series)
    a.set_ylabel("coherence²")
    a.legend(fontsize=8)
    styles = {"original": ("0.6", "-"), "with noise": ("k", "-"), "eq. 17 prediction": ("r", "--"),
              "eq. 17 with true impedance": ("b", ":"), "true impedance": ("g", "-.")}
    for series, s in _curve(c0, "magnitude").groupby("series"):
        col, ls = styles[series]
        b.loglog(s["x"], s["y"], color=col, ls=ls, label=series)
    fall = rows[(rows["metric"] == "fall_away_hz") & (rows["seed"] == rows["seed"].min())]["value"]
    if len(fall):
        b.axvline(float(fall.iloc[0]), color="0.8", lw=0.8)
    b.set_ylabel("|impedance| (N·m/rad)")
    b.set_xlabel("frequency (Hz)")
    b.legend(fontsize=7)
    cutoff = ((part.experiment or {}).get("perturbation") or {}).get("cutoff", "?")
    a.set_title(f"{part.params.get('snr_db', '?')} dB angle noise, {cutoff} input (Fig. 8)")
    name = save(fig, folder, f"{part.name}.png")
    return PartReport(figures=[(name, part.description)],
                      tables=[("Fall-away frequency and prediction error", summary_over_seeds(rows, part.name, []))])
