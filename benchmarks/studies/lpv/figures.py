"""Figure and tables of the lpv study (protocol ``lpv.kmap``), drawn from the tidy rows and curves."""
from __future__ import annotations

import pandas as pd

from jointbench.benchmarks.figures import PartReport, new_figure, register, save
from jointbench.benchmarks.tables import median_range, over_seeds
from jointbench.core.intervals import LEVEL


def _ok(rows: pd.DataFrame) -> pd.DataFrame:
    return rows[rows["status"] == "ok"] if "status" in rows.columns else rows


def error_table(rows: pd.DataFrame) -> pd.DataFrame:
    """K(theta) errors per movement (frequency x range) and method: median (min to max) over seeds."""
    st = over_seeds(rows, ["movement_frequency", "range_scale", "estimator", "metric"],
                    ["kmap_rmse_pct", "band_coverage", "band_halfwidth"])
    span = over_seeds(rows[rows["estimator"].fillna("") == ""], ["movement_frequency", "range_scale"], ["range_rad"])
    out = []
    for (f, r), g in st.groupby(["movement_frequency", "range_scale"]):
        row = {"movement (Hz)": f, "range scale": r}
        sp = span[(span["movement_frequency"] == f) & (span["range_scale"] == r)]
        row["range (rad)"] = f"{float(sp['median'].iloc[0]):.3g}" if len(sp) else ""
        for est, metric, label in (("pv_irf", "kmap_rmse_pct", "pv_irf RMS error (%)"),
                                   ("fsewls", "kmap_rmse_pct", "FSEWLS mapped RMS error (%)"),
                                   ("pv_irf", "band_coverage", "pv_irf band coverage"),
                                   ("pv_irf", "band_halfwidth", "pv_irf band half-width (N·m/rad)")):
            x = g[(g["estimator"] == est) & (g["metric"] == metric)]
            row[label] = median_range(float(x["median"].iloc[0]), float(x["min"].iloc[0]), float(x["max"].iloc[0]),
                                      int(x["n"].iloc[0]), 3) if len(x) else "not fitted"
        out.append(row)
    return pd.DataFrame(out)


def _summary(rows: pd.DataFrame) -> str:
    st = over_seeds(rows, ["movement_frequency", "range_scale", "estimator"], ["kmap_rmse_pct"])
    if st.empty:
        return ""
    piv = st.pivot_table(index=["movement_frequency", "range_scale"], columns="estimator", values="median")
    if not {"pv_irf", "fsewls"} <= set(piv.columns):
        return ""
    better = int((piv["pv_irf"] < piv["fsewls"]).sum())
    return (f"pv_irf's K(theta) has the smaller RMS error in {better} of the {len(piv)} movements (medians over "
            f"seeds); its error ranges from {piv['pv_irf'].min():.2g} % to {piv['pv_irf'].max():.2g} % of the mean K, "
            f"FSEWLS mapped through theta from {piv['fsewls'].min():.2g} % to {piv['fsewls'].max():.2g} %.")


@register("lpv.kmap")
def lpv_kmap(part, rows, curves, folder, checks) -> PartReport:
    rows = _ok(rows)
    fig, axes = new_figure(2, 2, figsize=(11, 8.5))
    (a, b), (c, d) = axes
    c0 = curves[curves["seed"] == curves["seed"].min()] if len(curves) else curves
    slow, wide = (min(rows["movement_frequency"].dropna()), max(rows["range_scale"].dropna())) if len(rows) else (0, 1)
    fast = max(rows["movement_frequency"].dropna()) if len(rows) else 0
    for ax, freq in ((a, slow), (b, fast)):
        s = c0[(c0["movement_frequency"] == freq) & (c0["range_scale"] == wide)] if len(c0) else c0
        for (curve, series, est), g in s.groupby(["curve", "series", s["estimator"].fillna("")]) if len(s) else []:
            if curve == "k_theta":
                if series == "truth":
                    ax.plot(g["x"], g["y"], "k-", lw=2, label="true K(theta)")
                elif series == "estimate":
                    ax.plot(g["x"], g["y"], "-", color="tab:blue" if est == "pv_irf" else "tab:orange", lw=1.3,
                            label=f"{est}" + (" mapped through theta" if est == "fsewls" else ""))
            elif curve == "k_of_t":
                ax.plot(g["x"], g["y"], ".", color="tab:orange", ms=2, alpha=0.4, label="FSEWLS K-hat(t) vs slow angle")
        lo = s[(s["series"] == "band low")] if len(s) else s
        hi = s[(s["series"] == "band high")] if len(s) else s
        if len(lo) and len(hi):
            ax.fill_between(lo["x"], lo["y"], hi["y"].to_numpy(), color="tab:blue", alpha=0.2, label="pv_irf 95 % band")
        ax.set_xlabel("slow angle (rad)")
        ax.set_ylabel("K (N·m/rad)")
        ax.set_title(f"K(theta), movement {freq:g} Hz, full range (seed {int(c0['seed'].min()) if len(c0) else 0})")
        ax.legend(fontsize=7)
    st = over_seeds(rows, ["movement_frequency", "range_scale", "estimator"], ["kmap_rmse_pct"])
    for est, ls in (("pv_irf", "-o"), ("fsewls", "--s")):
        for rs, col in zip(sorted(st["range_scale"].dropna().unique()), ("tab:green", "tab:purple", "k", "tab:red")):
            g = st[(st["estimator"] == est) & (st["range_scale"] == rs)].sort_values("movement_frequency")
            c.errorbar(g["movement_frequency"], g["median"], yerr=[g["median"] - g["min"], g["max"] - g["median"]],
                       fmt=ls, color=col, ms=4, capsize=2, lw=1, label=f"{est}, range x {rs:g}")
    c.set_xscale("log")
    c.set_yscale("log")
    c.set_xlabel("movement frequency (Hz)")
    c.set_ylabel("RMS error of K(theta) (% of mean K)")
    c.set_title("How the answer degrades with speed and range")
    c.legend(fontsize=6, ncol=2)
    cov = over_seeds(rows, ["movement_frequency", "range_scale"], ["band_coverage"])
    for rs, col in zip(sorted(cov["range_scale"].dropna().unique()), ("tab:green", "tab:purple", "k", "tab:red")):
        g = cov[cov["range_scale"] == rs].sort_values("movement_frequency")
        d.plot(g["movement_frequency"], g["median"], "-o", color=col, ms=4, label=f"range x {rs:g}")
    d.axhline(LEVEL, color="0.6", ls=":", lw=1, label=f"nominal {100 * LEVEL:g} %")
    d.set_xscale("log")
    d.set_ylim(0, 1.05)
    d.set_xlabel("movement frequency (Hz)")
    d.set_ylabel("fraction of the K(theta) grid in the band")
    d.set_title("pv_irf: coverage of its pointwise band")
    d.legend(fontsize=7)
    fig.tight_layout()
    name = save(fig, folder, "lpv_kmap.png")
    return PartReport(figures=[(name, "K(theta) of the slowest and fastest movement over the full range (top); the "
                                      "RMS error of K(theta) by movement speed and range (bottom left, medians and "
                                      "ranges over seeds); pv_irf's band coverage (bottom right).")],
                      tables=[("K(theta) errors by movement (medians, min to max over seeds)", error_table(rows))],
                      text=_summary(rows))
