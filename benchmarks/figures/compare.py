"""Tables and figures of a comparison grid (protocol ``compare``): the best method of every scenario on
each metric with its spread, a heat map of methods x scenarios, the rise-time / random-error trade-off,
and the combinations skipped or not fitted with their reasons. Drawn from the tidy rows only.

A *method* is an estimator with the data it was given (``kbr`` on single trials, ``kbr (ensemble)``); a
*scenario* is a combination of the grid's other axes (scenario, time variation, noise, rate, backend ...).
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from jointbench.benchmarks.figures import PartReport, new_figure, register, save

#: grid axes that make a scenario, in the order of its label
SCENARIO_AXES = ("scenario", "joint", "variation", "perturbation", "noise", "fs", "backend")
#: metric -> (heading, better: 'max' or 'min', per realization?)
METRICS = {
    "vaf_stiffness": ("VAF of k (%)", "max", True),
    "total_error": ("total error (N·m/rad)", "min", False),
    "bias_rms": ("bias, RMS (N·m/rad)", "min", False),
    "random_error": ("random error (N·m/rad)", "min", False),
    "rise_time_s": ("rise time (s)", "min", False),
    "vaf_output": ("output VAF (%)", "max", True),
    "fit_time_s": ("fit time (s)", "min", True),
}


def _axes(rows: pd.DataFrame) -> list[str]:
    """The scenario axes that vary in these rows (the scenario name always)."""
    out = []
    for a in SCENARIO_AXES:
        if a in rows.columns and (a == "scenario" or rows[a].dropna().astype(str).nunique() > 1):
            out.append(a)
    return out


def labelled(rows: pd.DataFrame) -> pd.DataFrame:
    """The rows with ``method`` and ``scenario_label`` columns."""
    out = rows.copy()
    out["estimator"] = out["estimator"].fillna("").astype(str)
    data = out["data"].fillna("trial").astype(str) if "data" in out.columns else "trial"
    out["method"] = np.where(data == "ensemble", out["estimator"] + " (ensemble)", out["estimator"])
    axes = _axes(out)

    def label(r) -> str:
        parts = []
        for a in axes:
            v = r[a]
            if a in ("noise", "fs") and not (isinstance(v, str)):
                v = f"{a} {v:g}"
            parts.append(str(v))
        return " / ".join(parts)

    out["scenario_label"] = out.apply(label, axis=1) if len(out) else ""
    return out


def scores(rows: pd.DataFrame) -> pd.DataFrame:
    """One row per method, scenario and metric: ``value`` (median over realizations and seeds), ``lo`` and
    ``hi`` (min and max over the realizations for per-realization metrics; the basic bootstrap 90 %
    interval over realizations for the others), ``n`` (values combined)."""
    ok = rows[(rows["status"] == "ok") & rows["metric"].isin(list(METRICS))]
    recs = []
    for (method, scen, metric), g in ok.groupby(["method", "scenario_label", "metric"], sort=False):
        v = g["value"].astype(float)
        if METRICS[metric][2]:
            lo, hi = float(v.min()), float(v.max())
        else:
            lo = float(g["p05"].min()) if "p05" in g and g["p05"].notna().any() else float(v.min())
            hi = float(g["p95"].max()) if "p95" in g and g["p95"].notna().any() else float(v.max())
        recs.append({"method": method, "scenario": scen, "metric": metric, "value": float(v.median()),
                     "lo": lo, "hi": hi, "n": int(len(v))})
    return pd.DataFrame(recs, columns=["method", "scenario", "metric", "value", "lo", "hi", "n"])


def _fmt(v: float) -> str:
    if not np.isfinite(v):
        return "∞" if v > 0 else ("-∞" if v < 0 else "")
    return f"{v:.3g}" if abs(v) < 1e4 else f"{v:.2e}"


def best_table(sc: pd.DataFrame) -> pd.DataFrame:
    """Per scenario, the best method on each metric: 'method value (lo to hi)'."""
    out = []
    for scen in dict.fromkeys(sc["scenario"]):
        row = {"scenario": scen}
        for metric, (head, better, _) in METRICS.items():
            s = sc[(sc["scenario"] == scen) & (sc["metric"] == metric)]
            s = s[np.isfinite(s["value"])] if metric != "rise_time_s" else s[s["value"].notna()]
            if s.empty:
                row[head] = ""
                continue
            r = s.loc[s["value"].idxmax() if better == "max" else s["value"].idxmin()]
            row[head] = f"{r['method']} {_fmt(r['value'])} ({_fmt(r['lo'])} to {_fmt(r['hi'])})"
        out.append(row)
    return pd.DataFrame(out)


def heat_map(sc: pd.DataFrame, rows: pd.DataFrame, folder, name: str) -> str | None:
    """Methods x scenarios, coloured by the median VAF of the stiffness (clipped to 0-100 %); skipped
    combinations grey ('skip'), estimates that could not be fitted 'n/f'."""
    v = sc[sc["metric"] == "vaf_stiffness"]
    ran = rows[(rows["estimator"] != "") & (rows["metric"] != "skipped")]
    methods = list(dict.fromkeys(ran["method"]))          # a method skipped everywhere: in the reasons table
    scens = list(dict.fromkeys(rows["scenario_label"]))
    if not methods or not scens:
        return None
    grid = np.full((len(methods), len(scens)), np.nan)
    for r in v.itertuples():
        grid[methods.index(r.method), scens.index(r.scenario)] = r.value
    state = {}
    for metric, tag in (("skipped", "skip"), ("not_fitted", "n/f"), ("not_scored", "n/s")):
        for r in rows[rows["metric"] == metric].itertuples():
            state[(r.method, r.scenario_label)] = tag
    fig, ax = new_figure(figsize=(max(6.0, 0.75 * len(scens) + 2.5), max(3.0, 0.42 * len(methods) + 1.5)))
    import matplotlib.pyplot as plt

    cmap = plt.get_cmap("viridis").with_extremes(bad="0.85")
    im = ax.imshow(np.clip(grid, 0, 100), cmap=cmap, vmin=0, vmax=100, aspect="auto")
    for i, m in enumerate(methods):
        for j, s in enumerate(scens):
            value = grid[i, j]
            text = (state.get((m, s), "") if not np.isfinite(value) else
                    "<-99" if value < -99 else f"{value:.0f}" if abs(value) >= 10 else f"{value:.1f}")
            dark = np.isfinite(grid[i, j]) and grid[i, j] < 60
            ax.text(j, i, text, ha="center", va="center", fontsize=7, color="white" if dark else "black")
    ax.set_xticks(range(len(scens)), scens, rotation=60, ha="right", fontsize=7)
    ax.set_yticks(range(len(methods)), methods, fontsize=8)
    fig.colorbar(im, ax=ax, label="VAF of the stiffness (%), median over realizations")
    ax.set_title("Methods x scenarios: VAF of the estimated stiffness, % (grey: skipped; n/f: not fitted; "
                 "exact values in the scores file)", fontsize=9)
    return save(fig, folder, name)


def _bar(r) -> list | None:
    """Error bar from the spread (clipped at the estimate, should an interval not contain it)."""
    if not (np.isfinite(r["lo"]) and np.isfinite(r["hi"])):
        return None
    return [[max(0.0, r["value"] - r["lo"])], [max(0.0, r["hi"] - r["value"])]]


def trade_off(sc: pd.DataFrame, folder, name: str) -> str | None:
    """Random error against rise time (square-wave scenarios), one panel per scenario, one point per
    method with its bootstrap spread: the trade-off of the framework (fast methods are noisy)."""
    rise = sc[(sc["metric"] == "rise_time_s") & np.isfinite(sc["value"])]
    if rise.empty:
        return None
    scens = list(dict.fromkeys(rise["scenario"]))
    ncol = min(3, len(scens))
    nrow = -(-len(scens) // ncol)
    fig, axes = new_figure(nrow, ncol, figsize=(4.2 * ncol, 3.4 * nrow), squeeze=False)
    methods = list(dict.fromkeys(sc["method"]))
    import matplotlib.pyplot as plt

    colors = {m: plt.get_cmap("tab20")(i % 20) for i, m in enumerate(methods)}
    for ax, scen in zip(axes.ravel(), scens):
        r = rise[rise["scenario"] == scen].set_index("method")
        e = sc[(sc["scenario"] == scen) & (sc["metric"] == "random_error")].set_index("method")
        for m in r.index.intersection(e.index):
            x, y = r.loc[m], e.loc[m]
            ax.errorbar(x["value"], y["value"], xerr=_bar(x), yerr=_bar(y), fmt="o", color=colors[m], label=m,
                        ms=5, capsize=2)
        ax.set_title(scen, fontsize=8)
        ax.set_xlabel("rise time 10-90 % (s)")
        ax.set_ylabel("random error (N·m/rad)")
        ax.grid(alpha=0.3)
    for ax in axes.ravel()[len(scens):]:
        ax.axis("off")
    handles, labels = axes.ravel()[0].get_legend_handles_labels()
    seen = dict(zip(labels, handles))
    for ax in axes.ravel()[1:len(scens)]:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            seen.setdefault(lab, h)
    fig.legend(list(seen.values()), list(seen.keys()), loc="lower center", ncol=min(6, len(seen)), fontsize=7,
               bbox_to_anchor=(0.5, -0.02 - 0.02 * (len(seen) // 6)))
    fig.suptitle("Rise time against random error (square-wave stiffness; bars: basic bootstrap 90 % intervals over "
                 "realizations)",
                 fontsize=9)
    fig.tight_layout(rect=(0, 0.06, 1, 0.96))
    return save(fig, folder, name)


def reasons(rows: pd.DataFrame) -> pd.DataFrame:
    """Skipped and not-fitted combinations: one line per method and reason, with the scenarios."""
    sel = rows[rows["metric"].isin(["skipped", "not_fitted", "not_scored"])]
    if sel.empty:
        return pd.DataFrame()
    out = []
    for (metric, method, reason), g in sel.groupby(["metric", "method", "reason"], sort=False):
        scens = list(dict.fromkeys(g["scenario_label"]))
        out.append({"what": {"skipped": "skipped (not run)", "not_fitted": "run, refused the data",
                             "not_scored": "fitted, nothing to score"}[metric],
                    "method": method, "reason": reason, "scenarios": len(scens),
                    "which": "; ".join(scens[:4]) + (f"; ... ({len(scens) - 4} more)" if len(scens) > 4 else "")})
    return pd.DataFrame(out)


@register("compare")
def compare_figures(part, rows, curves, folder, checks) -> PartReport:
    """Tables and figures of a comparison grid part (module docstring)."""
    rep = PartReport()
    rows = labelled(rows)
    sc = scores(rows)
    sc.to_csv(folder / f"{part.name}_scores.csv", index=False)
    n_methods, n_scen = rows["method"].replace("", np.nan).dropna().nunique(), rows["scenario_label"].nunique()
    R = rows["realization"].dropna().nunique() if "realization" in rows.columns else 0
    rep.text = (f"{n_methods} methods on {n_scen} scenarios, {R} realizations each. Every number is from the tidy "
                f"rows (`cases.csv`); all scores per method and scenario are in `{part.name}_scores.csv`. "
                "Definitions (studies.md D): VAF of k = 100 (1 - sum (k_hat - k)^2 / sum (k - mean k)^2) per "
                "realization; bias(t) = mean over realizations of k_hat(t) - k(t), its RMS over t; random error = "
                "RMS over t of the SD over realizations; total error = RMS over t and realizations of k_hat - k "
                "(total^2 = bias^2 + random^2 (R-1)/R); rise time = 10-90 % of the mean estimate at each step of "
                "a square wave, averaged over the steps. k is the static gain of the true frozen impedance; "
                "scored between the part's discarded ends, where the estimate is valid in every realization. "
                "Spread: min to max over realizations (per-realization metrics) or the basic bootstrap 90 % "
                "interval over realizations (the others). The RMS bias of a resampled set of realizations "
                "carries more of their noise than that of all R, so its bootstrap values sit above the "
                "estimate; the basic interval reflects them about it and can therefore lie below the value "
                "itself: read it as how much of the bias is noise.")
    if not sc.empty:
        rep.tables.append(("Best method per scenario (value, spread)", best_table(sc)))
        f = heat_map(sc, rows, folder, f"{part.name}_heatmap.png")
        if f:
            rep.figures.append((f, "Methods x scenarios: median VAF of the estimated stiffness (%)"))
        f = trade_off(sc, folder, f"{part.name}_tradeoff.png")
        if f:
            rep.figures.append((f, "Rise time against random error on the square-wave scenarios"))
    why = reasons(rows)
    if not why.empty:
        rep.tables.append(("Combinations skipped or not fitted, and why", why))
    return rep
