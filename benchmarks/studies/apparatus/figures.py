"""Figures and tables of the apparatus study (servo stiffness, gravity), drawn from the tidy results."""
from __future__ import annotations

import numpy as np
import pandas as pd

from jointbench.benchmarks.figures import PartReport, new_figure, register, save
from jointbench.benchmarks.tables import median_range, over_seeds


def _ok(rows: pd.DataFrame) -> pd.DataFrame:
    return rows[rows["status"] == "ok"] if "status" in rows.columns else rows


def _stat(rows: pd.DataFrame, metric: str, by: list[str], **eq) -> pd.DataFrame:
    """Median, min and max over seeds of ``metric`` per ``by`` (sorted), rows restricted to ``eq``."""
    sel = rows
    for k, v in eq.items():
        sel = sel[sel[k] == v]
    if not by:
        return over_seeds(sel.assign(_all=0), ["_all"], [metric])
    return over_seeds(sel, by, [metric]).sort_values(by, ignore_index=True)


def _servo_errors(a, b, rows: pd.DataFrame, to_ratio: dict, segs: list, k_true: float) -> None:
    """Panels a and b: K-hat - K (% of K) against K_a / K with the measured angle (a) and the command (b) as
    the input, beside the eqs. 3-8 prediction of each segment length."""
    colours = dict(zip(segs, ("k", "tab:blue", "tab:green", "tab:purple")))
    for seg in segs:
        for inp, ax in (("measured", a), ("command", b)):
            m = _stat(rows, "K_err_pct", ["servo_stiffness"], input=inp, segment_s=seg, voluntary="present")
            p = _stat(rows, "K_predicted_err_pct", ["servo_stiffness"], input=inp, segment_s=seg,
                      voluntary="present")
            x = m["servo_stiffness"].map(to_ratio)
            ax.errorbar(x, m["median"], yerr=[m["median"] - m["min"], m["max"] - m["median"]], fmt="o",
                        color=colours[seg], ms=4, capsize=2, label=f"simulated, {seg:g} s segments")
            ax.plot(p["servo_stiffness"].map(to_ratio), p["median"], "-", color=colours[seg], lw=1,
                    label=f"eqs. 3-8 + {seg:g} s Welch window")
    n = _stat(rows, "K_predicted_no_leakage", ["servo_stiffness"], input="measured", segment_s=segs[0],
              voluntary="present")
    a.plot(n["servo_stiffness"].map(to_ratio), 100 * (n["median"] - k_true) / k_true, "r--", lw=1,
           label="eqs. 3-8 alone (voluntary torque only)")
    a.axhspan(-5, 5, color="0.92", zorder=0, label="within 5 % (reading R4)")
    a.set_ylabel("K-hat - K (% of K)")
    a.set_title("Measured angle as the input (the paper's practice)")
    b.set_yscale("symlog", linthresh=10)
    b.set_ylabel("K-hat - K (% of K)")
    b.set_title("Command theta_r as the input (eq. 7: Theta ~ Theta_r)")
    for ax in (a, b):
        ax.set_xscale("log")
        ax.set_xlabel("K_a / K")
        ax.legend(fontsize=7)


def _servo_spectra(c, rows: pd.DataFrame, curves: pd.DataFrame, to_ratio: dict, segs: list) -> None:
    """Panel c: the spectral estimate minus the limb's impedance at three K_a (the stiffest, 2000 and the
    softest), with the servo mode of each, on the first seed."""
    shown = [k for k in sorted(to_ratio) if k in (max(to_ratio), 2000.0, min(to_ratio))]
    c0 = curves[(curves["curve"] == "real_error") & (curves["seed"] == curves["seed"].min())] \
        if len(curves) else curves
    for k, col in zip(shown, ("tab:red", "tab:orange", "k")):
        for series, ls in (("estimate", "-"), ("predicted", "--")):
            s = c0[(c0["servo_stiffness"] == k) & (c0["series"] == series) & (c0["input"] == "measured")
                   & (c0["segment_s"] == segs[0]) & (c0["voluntary"] == "present")]
            c.plot(s["x"], s["y"], ls, color=col, lw=1, label=f"K_a = {k:g}: {series}")
        mode = float(_stat(rows, "servo_mode_hz", ["servo_stiffness"]).set_index("servo_stiffness").loc[k, "median"])
        if mode < c0["x"].max() if len(c0) else False:
            c.axvline(mode, color=col, lw=0.6, ls=":")
    c.axhline(0, color="0.8", lw=0.8)
    c.set_xlabel("frequency (Hz); dotted: the servo mode sqrt((K_a + K)/I) / 2 pi")
    c.set_ylabel("Re(H-hat - Z) (N·m/rad)")
    c.set_title(f"Spectral estimate minus the limb's impedance, measured angle, {segs[0]:g} s segments "
                f"(seed {int(c0['seed'].min()) if len(c0) else 0})")
    c.legend(fontsize=7, ncol=2)


def _servo_table(rows: pd.DataFrame, to_ratio: dict, segs: list) -> pd.DataFrame:
    """K-hat (median and range over seeds) and its prediction per K_a, input and segment length."""
    table = []
    for k in sorted(to_ratio, reverse=True):
        row = {"K_a (N·m/rad)": k, "K_a / K": to_ratio[k],
               "servo mode (Hz)": float(_stat(rows, "servo_mode_hz", ["servo_stiffness"])
                                        .set_index("servo_stiffness").loc[k, "median"])}
        for seg in segs:
            for inp in ("measured", "command"):
                m = _stat(rows, "K", ["servo_stiffness"], input=inp, segment_s=seg, voluntary="present") \
                    .set_index("servo_stiffness")
                p = _stat(rows, "K_predicted", ["servo_stiffness"], input=inp, segment_s=seg, voluntary="present") \
                    .set_index("servo_stiffness")
                if k not in m.index:          # every fit of this cell refused by the output gate (report.md)
                    row[f"K-hat {inp}, {seg:g} s"] = row[f"predicted {inp}, {seg:g} s"] = "refused"
                    continue
                m, p = m.loc[k], p.loc[k]
                row[f"K-hat {inp}, {seg:g} s"] = median_range(m["median"], m["min"], m["max"], m["n"])
                row[f"predicted {inp}, {seg:g} s"] = round(float(p["median"]), 3)
        table.append(row)
    return pd.DataFrame(table)


def _voluntary_table(rows: pd.DataFrame, to_ratio: dict, segs: list, k_true: float) -> list[dict]:
    """What the voluntary torque does to K-hat (measured angle, the longest segments) per K_a, beside the
    bias eqs. 3-8 predict from it; no rows unless the sweep runs with and without it."""
    tv = []
    both = set(rows["voluntary"].dropna()) >= {"present", "absent"}
    for k in sorted(to_ratio, reverse=True) if both else []:
        on = _stat(rows, "K", ["servo_stiffness"], input="measured", segment_s=segs[-1], voluntary="present") \
            .set_index("servo_stiffness").loc[k, "median"]
        off = _stat(rows, "K", ["servo_stiffness"], input="measured", segment_s=segs[-1], voluntary="absent") \
            .set_index("servo_stiffness").loc[k, "median"]
        pr = _stat(rows, "K_predicted_no_leakage", ["servo_stiffness"], input="measured", segment_s=segs[-1],
                   voluntary="present").set_index("servo_stiffness").loc[k, "median"]
        tv.append({"K_a (N·m/rad)": k, "K-hat with T_v": on, "K-hat without T_v": off,
                   "difference": on - off, "eqs. 3-8 bias from T_v": pr - k_true})
    return tv


def _servo_text(rows: pd.DataFrame, tv: list[dict]) -> str:
    """The largest median error per segment length, and the bias the voluntary torque alone would cause."""
    err = _stat(rows, "K_err_pct", ["servo_stiffness", "segment_s"], input="measured", voluntary="present")
    worst = err.loc[err.groupby("segment_s")["median"].apply(lambda v: v.abs().idxmax())]
    text = ("Largest median |K-hat - K| over the sweep with the measured angle as the input: "
            + "; ".join(f"{r.segment_s:g} s segments {r.median:+.2f} % at K_a = {r.servo_stiffness:g} N·m/rad"
                        for r in worst.itertuples()) + ".")
    if tv:
        text += (" The voluntary torque alone (eqs. 3-6, no window) would bias K by "
                 f"{min(r['eqs. 3-8 bias from T_v'] for r in tv):+.3f} N·m/rad at most.")
    return text


@register("apparatus.servo")
def servo(part, rows, curves, folder, checks) -> PartReport:
    """The servo stiffness part: K-hat against K_a / K with its prediction, the spectral estimate, the
    tables of K-hat and of what the voluntary torque does."""
    rows = _ok(rows)
    ratio = _stat(rows, "servo_over_joint_stiffness", ["servo_stiffness"])
    to_ratio = dict(zip(ratio["servo_stiffness"], ratio["median"]))
    segs = sorted(rows["segment_s"].dropna().unique())
    k_true = float(_stat(rows, "K_true", [], input="measured")["median"].iloc[0]) if len(rows) else np.nan
    fig, (a, b, c) = new_figure(3, 1, figsize=(6.8, 10))
    _servo_errors(a, b, rows, to_ratio, segs, k_true)
    _servo_spectra(c, rows, curves, to_ratio, segs)
    fig.tight_layout()
    name = save(fig, folder, "apparatus_servo.png")
    tv = _voluntary_table(rows, to_ratio, segs, k_true)
    return PartReport(figures=[(name, "Servo stiffness: K-hat against K_a / K with its eqs. 3-8 prediction, "
                                      "measured angle (top) and command (middle) as the input; the spectral "
                                      "estimate at three K_a (bottom).")],
                      tables=[("K-hat (N·m/rad; median and range over seeds, voluntary torque present) and its "
                               "prediction", _servo_table(rows, to_ratio, segs))]
                      + ([(f"What the voluntary torque does (measured angle, {segs[-1]:g} s segments, "
                           "medians over the same seeds, i.e. the same commands)", pd.DataFrame(tv))] if tv else []),
                      text=_servo_text(rows, tv))


@register("apparatus.gravity")
def gravity(part, rows, curves, folder, checks) -> PartReport:
    rows = _ok(rows)
    off = _stat(rows, "gravity_offset", ["posture_deg"])
    kg = _stat(rows, "gravity_stiffness", ["posture_deg"])
    mgl = float(_stat(rows, "gravity_moment", [])["median"].iloc[0])
    fig, (a, b) = new_figure(2, 1, figsize=(6.8, 7.5))
    a.errorbar(off["posture_deg"], off["median"], yerr=[off["median"] - off["min"], off["max"] - off["median"]],
               fmt="ko", ms=5, capsize=2, label="FSEWLS: K-hat with gravity - without (same trial)")
    phi = np.linspace(0, 180, 181)
    a.plot(phi, mgl * np.cos(np.radians(phi)), "r-", lw=1, label="m g l cos(posture) (eq. 2)")
    a.plot(kg["posture_deg"], kg["median"], "r.", ms=8, label="K_g along the trajectory")
    a.axhline(0, color="0.8", lw=0.8)
    a.set_xlabel("posture: angle of theta = 0 from hanging down (deg)")
    a.set_ylabel("stiffness offset (N·m/rad)")
    a.legend(fontsize=7)
    a.set_title(f"Gravity on the forearm (m g l = {mgl:.3g} N·m/rad) and FSEWLS")
    c0 = curves[curves["seed"] == curves["seed"].min()] if len(curves) else curves
    styles = {"estimate, gravity": "-", "estimate, no gravity": "-", "joint K(t)": ":", "joint K(t) + K_g": "--"}
    for posture, col in ((0.0, "tab:blue"), (180.0, "tab:red")):
        s = c0[c0["posture_deg"] == posture]
        for series, ls in styles.items():
            d = s[s["series"] == series]
            if series in ("estimate, no gravity", "joint K(t)") and posture != 0.0:
                continue
            colour = "0.4" if "no gravity" in series or series == "joint K(t)" else col
            b.plot(d["x"], d["y"], ls, color=colour, lw=1,
                   label=f"{series}"
                   + ("" if "no gravity" in series or series == "joint K(t)" else f", {posture:g} deg"))
    if len(c0):
        t0 = float(c0["x"].min())
        b.set_xlim(t0, t0 + 6)
    b.set_xlabel("time (s)")
    b.set_ylabel("K (N·m/rad)")
    b.legend(fontsize=7, ncol=3, loc="upper center", bbox_to_anchor=(0.5, -0.15))
    b.set_title("K-hat(t) hanging down (0 deg) and pointing up (180 deg)")
    fig.tight_layout()
    name = save(fig, folder, "apparatus_gravity.png")
    table = []
    for r in off.itertuples():
        k = kg.set_index("posture_deg").loc[r.posture_deg]
        kh = _stat(rows, "K_hat_mean", ["posture_deg"]).set_index("posture_deg").loc[r.posture_deg]
        k0 = _stat(rows, "K_hat_mean_no_gravity", ["posture_deg"]).set_index("posture_deg").loc[r.posture_deg]
        table.append({"posture (deg)": r.posture_deg, "mean K-hat, gravity": kh["median"],
                      "mean K-hat, none": k0["median"], "offset": median_range(r.median, r.min, r.max, r.n),
                      "K_g (trajectory)": k["median"], "m g l cos(posture)": mgl * np.cos(np.radians(r.posture_deg))})
    dev = (off.set_index("posture_deg")["median"] - kg.set_index("posture_deg")["median"]).abs()
    text = (f"The offset FSEWLS reports follows K_g = m g l cos(posture + theta) within {dev.max():.3f} N·m/rad "
            f"({100 * dev.max() / mgl:.2g} % of m g l) at every posture.")
    return PartReport(figures=[(name, "Gravity: the stiffness offset FSEWLS reports against the linearized gravity "
                                      "stiffness (top); K-hat(t) with and without gravity (bottom).")],
                      tables=[("Mean stiffness over the scored 40 s (N·m/rad; medians over seeds)",
                               pd.DataFrame(table))],
                      text=text)
