"""Figures and tables of the Xu & Hollerbach (1998) parts, drawn from the tidy results (nothing is
recomputed except the analytic EWLS bound of Fig. 2)."""
from __future__ import annotations

import numpy as np
import pandas as pd

from jointbench.benchmarks.figures import PartReport, first_seed, new_figure, register, save
from jointbench.benchmarks.tables import median_range, over_seeds

VAF_FLOOR = -60.0   # VAF axes are cut here (values below are drawn on the axis, marked 'v')


def _stats(rows: pd.DataFrame, by: list[str], metrics: list[str]) -> pd.DataFrame:
    """Median, min and max over seeds of each metric, per combination of ``by`` (a long frame)."""
    return over_seeds(rows, by + ["metric"], metrics)


def _wide(rows: pd.DataFrame, by: list[str], metrics: list[str], order: dict | None = None) -> pd.DataFrame:
    """One row per ``by`` combination, one column per metric: 'median (min to max)' over seeds."""
    s = _stats(rows, by, metrics)
    if s.empty:
        return pd.DataFrame()
    by = [b for b in by if b in s.columns]
    s["cell"] = [median_range(m, lo, hi, n) for m, lo, hi, n in zip(s["median"], s["min"], s["max"], s["n"])]
    key = by or ["_all"]
    if not by:
        s["_all"] = ""
    cells = {}
    for combo, g in s.groupby(key, sort=False, dropna=False):
        combo = combo if isinstance(combo, tuple) else (combo,)
        rec = dict(zip(key, combo))
        rec["seeds"] = int(g["n"].max())
        rec.update(dict(zip(g["metric"], g["cell"])))
        cells[combo] = rec
    t = pd.DataFrame(list(cells.values()))
    t = t[key + ["seeds"] + [m for m in metrics if m in t.columns]]
    if not by:
        t = t.drop(columns=["_all"])
    sort = []
    for col in by:
        ranks = (order or {}).get(col)
        if ranks is not None:
            t["_o_" + col] = t[col].map(lambda v: ranks.index(v) if v in ranks else len(ranks))
            sort.append("_o_" + col)
        elif pd.api.types.is_numeric_dtype(t[col]):
            t["_o_" + col] = t[col]
            sort.append("_o_" + col)
    if sort:
        t = t.sort_values(sort, kind="stable").drop(columns=sort)
    return t.reset_index(drop=True)


def _median_curve(rows: pd.DataFrame, metric: str, x: str, **eq) -> pd.DataFrame:
    sel = rows[rows["metric"] == metric]
    for k, v in eq.items():
        sel = sel[sel[k] == v]
    return over_seeds(sel, [x]).set_index(x)[["median", "min", "max"]].sort_index()


def _errorbar(ax, s: pd.DataFrame, floor: float | None = VAF_FLOOR, **kw):
    if s.empty:
        return
    x = s.index.to_numpy(float)
    m, lo, hi = (s[c].to_numpy(float) for c in ("median", "min", "max"))
    if floor is not None:
        m, lo, hi = (np.maximum(v, floor) for v in (m, lo, hi))
    ax.errorbar(x, m, yerr=[m - lo, hi - m], capsize=2, **kw)
    if floor is not None:
        cut = s["median"].to_numpy(float) < floor
        if cut.any():
            ax.plot(x[cut], np.full(cut.sum(), floor), "v", color=kw.get("color", "k"), ms=7)


def _joint(part) -> dict:
    return dict((part.experiment or {}).get("joint") or {})


def _k_text(part) -> str:
    """The configured K(t) as 'mean ± amplitude N·m/rad' (read from the joint model, never typed)."""
    k = _joint(part).get("K")
    if isinstance(k, dict) and "mean" in k and "amplitude" in k:
        return f"{k['mean']:g} ± {k['amplitude']:g} N·m/rad"
    return f"{k} N·m/rad"


def _joint_text(part) -> str:
    """'I = ..., K = ..., B a -> b -> c' from the joint model (profiles by their values)."""
    out = []
    for name, v in _joint(part).items():
        if name == "model":
            continue
        if isinstance(v, dict) and "values" in v:
            out.append(f"{name} " + " -> ".join(f"{x:g}" for x in v["values"]))
        else:
            out.append(f"{name} = {v}")
    return ", ".join(out)


def _forgetting(part) -> float:
    """lambda (1/s) of the part's FSEWLS settings."""
    from jointbench import estimators

    name = next(iter(part.estimators))
    return float(estimators.make(name, part.estimators[name]).settings.forgetting)


def _trace_axes(ax, c: pd.DataFrame, name: str, t0: float, t1: float, ylabel: str):
    for series, style in (("truth", dict(color="0.4", lw=1.2)), ("estimate", dict(color="C3", lw=1))):
        s = c[(c["curve"] == name) & (c["series"] == series)]
        s = s[(s["x"] >= t0) & (s["x"] <= t1)]
        ax.plot(s["x"], s["y"], label=series, **style)
    ax.set_ylabel(ylabel)


# --------------------------------------------------------------------------------------------- Fig. 2
@register("xu1998.fig2")
def fig2(part, rows, curves, folder, checks) -> PartReport:
    lam = _forgetting(part)
    conds = [c for c in ("posture", "movement") if (rows.get("condition") == c).any()]
    fig, axes = new_figure(1, len(conds), figsize=(5.2 * len(conds), 4.2), sharey=True)
    axes = np.atleast_1d(axes)
    f = np.geomspace(0.04, 2.5, 100)
    for ax, cond, letter in zip(axes, conds, "ab"):
        _errorbar(ax, _median_curve(rows, "vaf_output", "f_v", condition=cond), color="k", marker="^",
                  mfc="w", ls="-", lw=0.8, label="output VAF")
        _errorbar(ax, _median_curve(rows, "vafm_K", "f_v", condition=cond), color="C0", marker="s",
                  ls="-", lw=0.8, label="VAFM of K")
        _errorbar(ax, _median_curve(rows, "vafv_K", "f_v", condition=cond), color="C3", marker="o",
                  ls="-", lw=0.8, label="VAFV of K")
        w = 2 * np.pi * f
        ax.plot(f, 100 * lam ** 2 / (lam ** 2 + w ** 2), color="0.5", ls="--", lw=0.8,
                label=f"first-order lag 1/λ bound (λ = {lam:g} 1/s)")
        ax.axhline(80, color="0.7", ls=":", lw=0.8)
        ax.set_xscale("log")
        ax.set_xlabel("frequency of the parameter variation f_v (Hz)")
        ax.set_title(f"({letter}) {cond}")
        ax.set_ylim(VAF_FLOOR - 5, 105)
    axes[0].set_ylabel("VAF (%)")
    axes[0].legend(fontsize=7, loc="lower left")
    figs = [(save(fig, folder, f"{part.name}.png"),
             "Fig. 2: output VAF (open triangles), VAFM (squares) and VAFV (circles) of K against f_v; median "
             f"and min-max over seeds; dotted: 80 %; dashed: the bound of a first-order lag 1/λ; values below "
             f"{VAF_FLOOR:g} % are drawn on the axis (v).")]
    c0 = first_seed(curves)
    c0 = c0[c0["curve"] == "K"] if len(c0) else c0
    if len(c0):
        fvs = sorted(c0["f_v"].dropna().unique())
        show = [v for v in (0.2, 0.5, 0.75, 1.5) if v in fvs] or fvs[:3]
        fig, axes = new_figure(len(show), len(conds), figsize=(5.2 * len(conds), 2.0 * len(show)), squeeze=False)
        for i, fv in enumerate(show):
            for j, cond in enumerate(conds):
                c = c0[(c0["f_v"] == fv) & (c0["condition"] == cond)]
                if c.empty:
                    continue
                t0 = float(c["x"].min())
                _trace_axes(axes[i, j], c, "K", t0, t0 + max(3.0 / fv, 4.0), f"K, {fv:g} Hz")
                if i == 0:
                    axes[i, j].set_title(cond)
        axes[-1, 0].set_xlabel("time (s)")
        axes[0, 0].legend(fontsize=7)
        figs.append((save(fig, folder, f"{part.name}_traces.png"),
                     f"Estimated K(t) (red) over the true K(t) (grey), seed {int(c0['seed'].min())}, for a few f_v "
                     "(N·m/rad; 3 periods or 4 s from the start of the scored window)."))
    order = {"condition": ["posture", "movement"]}
    t = _wide(rows, ["condition", "f_v"], ["vafv_K", "vafm_K", "vaf_output", "mean_err_K", "rmse_K",
                                           "vafv_B", "vafm_I"], order)
    outs = _wide(rows, ["condition", "f_v"], ["vaf_output_filtered_torque", "vaf_output_torque",
                                              "vaf_output_angle"], order)
    exp = part.experiment or {}
    acq = exp.get("acquisition") or {}
    text = (f"Each case: {exp.get('duration', '?')} simulated, acquired at {acq.get('fs', '?')} "
            f"({acq.get('trim', '0 s')} trimmed at each end), {part.params.get('discard', '?')} discarded at each end, "
            "VAFs and errors "
            "on the rest (readings R8, R13). Noise free. Posture is analysed without the high-pass H, "
            "movement with it (R5). `mean_err_K` = mean(K_hat) - mean(K) (check X4; at the slowest f_v it is zero "
            "within the seed spread). The output VAF of the "
            "checks is that of the filtered torque (R4); the second table gives the other candidate signals "
            "(an empty cell: the estimated model was unstable).")
    return PartReport(figures=figs, text=text,
                      tables=[("Fig. 2 values: median (min to max) over seeds", t),
                              ("Output VAF by candidate signal (reading R4): filtered torque L H tau (eq. 5), "
                               "high-passed torque H tau, high-passed angle H theta", outs)])


# --------------------------------------------------------------------------------------------- Fig. 3
@register("xu1998.fig3")
def fig3(part, rows, curves, folder, checks) -> PartReport:
    fig, (a, b, c) = new_figure(1, 3, figsize=(13, 4))
    _errorbar(a, _median_curve(rows, "vaf_output", "nsr"), color="k", marker="^", mfc="w", label="output")
    for name, col, mk in (("I", "C2", "D"), ("B", "C0", "s"), ("K", "C3", "o")):
        _errorbar(b, _median_curve(rows, f"vafm_{name}", "nsr"), color=col, marker=mk, label=name)
        _errorbar(c, _median_curve(rows, f"vafv_{name}", "nsr"), color=col, marker=mk, label=name)
    for ax, title in ((a, "(a) VAF of the output prediction"), (b, "(b) VAFM"), (c, "(c) VAFV")):
        ax.set_title(title)
        ax.set_xlabel("NSR")
        ax.axhline(80, color="0.7", ls=":", lw=0.8)
        ax.set_ylim(VAF_FLOOR - 5, 105)
        ax.legend(fontsize=8, loc="lower left")
    a.set_ylabel("VAF (%)")
    channel = str(part.params.get("noise_on", "torque"))
    figs = [(save(fig, folder, f"{part.name}.png"),
             f"{part.description}. Noise on the {channel}; median and min-max over seeds; values below "
             f"{VAF_FLOOR:g} % are drawn on the axis (v).")]
    c0 = first_seed(curves)
    c0 = c0[c0["curve"] == "K"] if len(c0) else c0
    if len(c0):
        levels = sorted(c0["nsr"].dropna().unique())
        show = [v for v in (0.0, 0.1, 0.2, 0.3) if v in levels] or levels[:3]
        fig, axes = new_figure(len(show), 1, figsize=(8, 1.8 * len(show)), sharex=True, squeeze=False)
        for ax, v in zip(axes[:, 0], show):
            cc = c0[c0["nsr"] == v]
            t0 = float(cc["x"].min())
            _trace_axes(ax, cc, "K", t0, t0 + 12.0, f"K, NSR {v:g}")
        axes[-1, 0].set_xlabel("time (s)")
        axes[0, 0].legend(fontsize=7)
        figs.append((save(fig, folder, f"{part.name}_traces.png"),
                     f"Estimated K(t) (red) over the true K(t) (grey) at several NSR, seed {int(c0['seed'].min())}, "
                     f"movement at {part.params.get('f_v', '?')} (first 12 s of the scored window)."))
    t = _wide(rows, ["nsr"], ["vafv_K", "vafm_K", "vafv_B", "vafm_B", "vafv_I", "vafm_I", "vaf_output",
                              "mean_err_K", "mean_I"])
    drops = _wide(rows, ["nsr"], ["drop_vafv_K", "drop_vafm_K", "drop_vafv_B", "drop_vaf_output"])
    text = (f"Movement at f_v = {part.params.get('f_v', '?')} with white noise on the measured {channel} "
            "(reading R11), NSR = var(noise)/var(noise-free signal) over the acquired record. VAFM and VAFV of I "
            "stay near 100 % "
            "whatever I_hat does: with the floor of 1 of eq. 8 they measure absolute errors in kg·m² (R13); "
            "`mean_I` shows I_hat itself. Each case also fits the same record without noise; the second table "
            "gives the falls against it.")
    return PartReport(figures=figs, text=text, tables=[(f"VAFs against NSR (noise on the {channel}): median "
                                             "(min to max) over seeds", t),
                                            ("Fall of each VAF against the same record without noise (points; "
                                             "check X5-K-faster)", drops)])


# ------------------------------------------------------------------------------------------- examples
@register("xu1998.traces")
def traces(part, rows, curves, folder, checks) -> PartReport:
    figs = []
    c0 = first_seed(curves)
    names = [n for n in ("K", "B", "I", "zeta") if len(c0) and (c0["curve"] == n).any()]
    units = {"K": "K (N·m/rad)", "B": "B (N·m·s/rad)", "I": "I (kg·m²)", "zeta": "ζ"}
    shapes = [s for s in ("sine", "square") if "shape" in c0.columns and (c0["shape"] == s).any()]
    conds = [c for c in ("posture", "movement") if len(c0) and (c0["condition"] == c).any()]
    for shape in shapes:
        fig, axes = new_figure(len(names), len(conds), figsize=(5.2 * len(conds), 1.8 * len(names)),
                               sharex=True, squeeze=False)
        for j, cond in enumerate(conds):
            c = c0[(c0["shape"] == shape) & (c0["condition"] == cond)]
            t0 = float(c["x"].min())
            for i, name in enumerate(names):
                _trace_axes(axes[i, j], c, name, t0, t0 + 8.0, units[name])
            axes[0, j].set_title(f"{shape} K, {cond}")
            axes[-1, j].set_xlabel("time (s)")
        axes[0, 0].legend(fontsize=7)
        figs.append((save(fig, folder, f"{part.name}_{shape}.png"),
                     f"{shape.capitalize()} K(t) = {_k_text(part)} at {part.params.get('f_v', '')}: estimates (red) "
                     f"over the truth (grey), seed {int(c0['seed'].min())}, first 8 s of the scored window."))
    t = _wide(rows, ["shape", "condition"], ["vafv_K", "vafm_K", "vafv_B", "vafm_B", "vafv_I", "vaf_output",
                                             "mean_err_K", "mean_zeta", "true_mean_zeta"],
              {"shape": ["sine", "square"], "condition": ["posture", "movement"]})
    text = (f"K(t) = {_k_text(part)} as a sine or a square wave at the same frequency (the square wave is not in "
            "the paper, reading R14), damping ratio constant. The information on K comes mostly from the "
            "low-frequency angle, whose amplitude scales as 1/K: the estimates follow a fall of K faster than a "
            "rise (square-wave figure).")
    return PartReport(figures=figs, text=text, tables=[("Scores: median (min to max) over seeds", t)])


# ---------------------------------------------------------------------------------------- calibration
@register("xu1998.calibration")
def calibration(part, rows, curves, folder, checks) -> PartReport:
    figs = []
    c0 = first_seed(curves)
    names = [n for n in ("I", "B", "K", "zeta") if len(c0) and (c0["curve"] == n).any()]
    if names:
        units = {"K": "K (N·m/rad)", "B": "B (N·m·s/rad)", "I": "I (kg·m²)", "zeta": "ζ"}
        fig, axes = new_figure(len(names), 1, figsize=(8, 1.9 * len(names)), sharex=True, squeeze=False)
        t0, t1 = float(c0["x"].min()), float(c0["x"].max())
        for ax, name in zip(axes[:, 0], names):
            _trace_axes(ax, c0, name, t0, t1, units[name])
        axes[0, 0].legend(fontsize=7)
        axes[0, 0].set_title("Calibration arm: damping switched during the trial (Fig. 5)")
        axes[-1, 0].set_xlabel("time (s)")
        figs.append((save(fig, folder, f"{part.name}.png"),
                     f"Calibration arm ({_joint_text(part)}): estimates (red) over the "
                     f"truth (grey), seed {int(c0['seed'].min())}, scored window."))
    t = _wide(rows, [], ["err_pct_I", "err_pct_K", "err_pct_B", "vaf_output", "vaf_output_torque",
                         "vaf_output_angle", "vafv_B", "rmse_B", "mean_zeta"])
    return PartReport(figures=figs, tables=[("Errors (%) of the window means and output VAF: median (min to max) "
                                             "over seeds", t)])


# ------------------------------------------------------------------------------------------ readings
def exact_control_sentence(rows: pd.DataFrame, variants: dict) -> str:
    """What the exact-derivative controls give in posture at the highest f_v run, beside the chosen
    configuration (derived from the rows: medians over seeds), or '' without those variants."""
    sel = rows[(rows["status"] == "ok") & (rows["metric"] == "vafv_K") & (rows["condition"] == "posture")]
    exact = [v for v in variants if (variants[v] or {}).get("regressors") == "exact" and (sel["variant"] == v).any()]
    if not exact or not (sel["variant"] == "chosen").any():
        return ""
    fv = float(sel["f_v"].max())
    at = sel[sel["f_v"] == fv].groupby("variant")["value"].median()

    def lam(v):
        f = ((variants[v] or {}).get("estimator_settings") or {}).get("forgetting")
        return f"lambda = {f}" if f else "the same lambda"

    parts = [f"`{v}` ({lam(v)}) {at[v]:.1f} %" for v in exact]
    return (f" Exact-derivative control (reading R21): fed the simulation's exact derivatives instead of its "
            f"filters, the EWLS gives a posture VAFV of K at {fv:g} Hz of " + ", ".join(parts)
            + f", against {at['chosen']:.1f} % with the filters (`chosen`): what the filters cost is the "
            "difference; the rest of the gap to the paper's boundary is the EWLS itself.")


@register("xu1998.readings")
def readings(part, rows, curves, folder, checks) -> PartReport:
    variants = dict(part.params.get("variants") or {})
    order = list(part.sweep.get("variant", variants))
    metrics = ["vafv_K", "vafm_K", "vaf_output", "mean_err_K", "vafv_B"]
    t = _wide(rows, ["variant", "condition", "f_v"], metrics,
              {"variant": order, "condition": ["posture", "movement"]})
    def changes(over: dict) -> str:
        flat = {}
        for k, v in (over or {}).items():
            flat.update({f"{k}.{kk}": vv for kk, vv in v.items()} if isinstance(v, dict) else {k: v})
        return ", ".join(f"{k} = {v}" for k, v in flat.items()) or "(the chosen readings)"

    what = pd.DataFrame({"variant": order, "changes": [changes(variants.get(v)) for v in order]})
    fig, axes = new_figure(1, 2, figsize=(12, 4), sharey=True)
    s = _stats(rows, ["variant", "condition", "f_v"], ["vafv_K"])
    for ax, cond in zip(axes, ("posture", "movement")):
        sub = s[s["condition"] == cond]
        fvs = sorted(sub["f_v"].unique())
        width = 0.8 / max(1, len(fvs))
        for k, fv in enumerate(fvs):
            m = [float(sub[(sub["variant"] == v) & (sub["f_v"] == fv)]["median"].squeeze() if
                       ((sub["variant"] == v) & (sub["f_v"] == fv)).any() else np.nan) for v in order]
            ax.bar(np.arange(len(order)) + (k - (len(fvs) - 1) / 2) * width, np.maximum(m, VAF_FLOOR),
                   width, label=f"f_v = {fv:g} Hz")
        ax.axhline(80, color="0.5", ls=":", lw=0.8)
        ax.set_xticks(np.arange(len(order)))
        ax.set_xticklabels(order, rotation=35, ha="right", fontsize=8)
        ax.set_title(cond)
        ax.set_ylim(VAF_FLOOR - 5, 105)
    axes[0].set_ylabel("VAFV of K (%), median over seeds")
    for ax in axes:
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
            break
    name = save(fig, folder, f"{part.name}.png")
    fvs = ", ".join(f"{float(v):g}" for v in part.sweep.get("f_v", ()))
    text = (f"What each candidate reading gives, on the Fig. 2 conditions at f_v = {fvs} Hz (the paper's movement "
            "boundary is 0.5 Hz, its posture boundary 1.5 Hz), noise free, same seeds as Fig. 2. The paper's "
            "statements to match: VAFV and VAFM of K about 80 % at 1.5 Hz in posture and at 0.5 Hz in movement, "
            "movement worse than posture, output VAF close to 100 %. `chosen` is the configuration of every "
            f"other part. Bars below the axis are cut at {VAF_FLOOR:g} %.")
    text += exact_control_sentence(rows, variants)
    return PartReport(figures=[(name, "VAFV of K by reading (median over seeds)")], text=text,
                      tables=[("Candidate readings", what),
                              ("What each reading gives: median (min to max) over seeds", t)])


@register("xu1998.filter_ratio")
def filter_ratio(part, rows, curves, folder, checks) -> PartReport:
    table = rows[rows["status"] == "ok"][["estimator", "metric", "value"]].reset_index(drop=True)
    return PartReport(tables=[("The ratio of L's cutoff and the stated limit of the parameter variation, both ways "
                               "round (reading R22; check X9-ratio-6.4)", table)])
