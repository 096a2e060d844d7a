"""Figures and tables of the lpv study (protocol ``lpv.kmap``; part ``kmap``: figure ``lpv.kmap``, part
``reflex``: figure ``lpv.reflex``), drawn from the tidy rows and curves.

Which method is better in a cell is said only from a paired test (:func:`paired_tests`: the two methods'
errors paired by seed, Wilcoxon signed-rank, Holm over the family; readings L6 and L9), and the report's
sentence is written from its outcome (:func:`_summary`, :func:`_reflex_summary`).
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from jointbench.benchmarks.compare import stats as cs
from jointbench.benchmarks.compare.tables import ALPHA
from jointbench.benchmarks.figures import PartReport, new_figure, register, save
from jointbench.benchmarks.tables import median_range, over_seeds
from jointbench.core.intervals import LEVEL

#: the columns that make one movement (the sweep)
MOVEMENT = ["movement_frequency", "range_scale"]
#: the two methods compared, in the order of the paired difference (first minus second)
METHODS = ("pv_irf", "fsewls")
#: what the methods are compared on (smaller is better)
SCORE = "kmap_rmse_pct"


def _ok(rows: pd.DataFrame) -> pd.DataFrame:
    return rows[rows["status"] == "ok"] if "status" in rows.columns else rows


def paired_tests(rows: pd.DataFrame, metric: str = SCORE, methods: tuple[str, str] = METHODS,
                 by: list[str] = MOVEMENT) -> pd.DataFrame:
    """Per cell (``by``: default the movement), the two ``methods``' ``metric`` (smaller is better) paired by
    seed (both fit the same simulated trial): :func:`benchmarks.compare.stats.paired_comparisons` (two-sided
    Wilcoxon signed-rank, the median paired difference ``methods[0] - methods[1]`` with its 90 % bootstrap
    interval), then Holm's correction over the cells (one family: the count the report states;
    :func:`with_holm`). Columns: the cell's, ``a``, ``b`` (the methods), ``n`` (seeds paired),
    ``median_diff``, ``diff_lo``, ``diff_hi``, ``p``, ``p_holm``, ``favours`` (the method the median
    difference favours, '' on 0) and ``better`` (``favours`` when ``p_holm < ALPHA``, else '').

    References
    ----------
    Wilcoxon (1945); Holm (1979) (:mod:`benchmarks.compare.stats`).
    """
    return with_holm(_pairs(rows, metric, methods, by))


def _pairs(rows: pd.DataFrame, metric: str, methods: tuple[str, str], by: list[str]) -> pd.DataFrame:
    """:func:`paired_tests` before Holm's correction (``p_holm`` and ``better`` not yet set)."""
    a, b = methods
    sel = rows[(rows["metric"] == metric) & rows["estimator"].isin(methods)]
    recs = []
    for key, g in sel.groupby(by, sort=True):
        key = key if isinstance(key, tuple) else (key,)
        values = {m: dict(zip(h["seed"].astype(int), h["value"].astype(float))) for m, h in g.groupby("estimator")}
        pair = cs.paired_comparisons({a: values.get(a, {}), b: values.get(b, {})}, "min", ALPHA)
        if not pair:
            continue
        r = pair[0]
        recs.append({**dict(zip(by, key)), "a": a, "b": b, "n": r["n"], "median_diff": r["median_diff"],
                     "diff_lo": r["diff_lo"], "diff_hi": r["diff_hi"], "p": r["p"],
                     "favours": {"a": a, "b": b}.get(r["favours"], "")})
    return pd.DataFrame(recs)


def with_holm(tests: pd.DataFrame) -> pd.DataFrame:
    """``tests`` (rows of :func:`_pairs`, one family) with ``p_holm`` (Holm's correction over all its rows) and
    ``better``."""
    out = tests.copy()
    if out.empty:
        return out
    out["p_holm"] = cs.holm(out["p"].to_numpy(float))
    out["better"] = np.where(out["p_holm"] < ALPHA, out["favours"], "")
    return out


def error_table(rows: pd.DataFrame) -> pd.DataFrame:
    """K(theta) errors per movement (frequency x range) and method: median (min to max) over seeds; the
    paired test of the two methods' errors (:func:`paired_tests`)."""
    st = over_seeds(rows, ["movement_frequency", "range_scale", "estimator", "metric"],
                    ["kmap_rmse_pct", "band_coverage", "band_halfwidth"])
    span = over_seeds(rows[rows["estimator"].fillna("") == ""], ["movement_frequency", "range_scale"], ["range_rad"])
    tests = paired_tests(rows)
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
        t = tests[(tests["movement_frequency"] == f) & (tests["range_scale"] == r)] if len(tests) else tests
        if len(t):
            t = t.iloc[0]
            row["pv_irf - FSEWLS (points; median paired, 90 % interval)"] = (
                f"{t['median_diff']:+.3f} ({t['diff_lo']:+.3f} to {t['diff_hi']:+.3f})")
            row["p (signed-rank, Holm)"] = f"{t['p_holm']:.2g}"
            row["significantly smaller error"] = t["better"] or "neither"
        out.append(row)
    return pd.DataFrame(out)


def _movements(t: pd.DataFrame) -> str:
    return ", ".join(f"{f:g} Hz x {r:g}" for f, r in zip(t["movement_frequency"], t["range_scale"]))


def _summary(rows: pd.DataFrame) -> str:
    """The comparison written from the paired tests' outcome (:func:`paired_tests`), and each method's range
    of errors (medians over seeds)."""
    st = over_seeds(rows, ["movement_frequency", "range_scale", "estimator"], [SCORE])
    tests = paired_tests(rows)
    if st.empty or tests.empty:
        return ""
    piv = st.pivot_table(index=["movement_frequency", "range_scale"], columns="estimator", values="median")
    if not set(METHODS) <= set(piv.columns):
        return ""
    m = len(tests)
    n = f"{tests['n'].min()}" if tests["n"].min() == tests["n"].max() else f"{tests['n'].min()} to {tests['n'].max()}"
    a, b = (tests[tests["better"] == e] for e in METHODS)
    text = (f"Paired by seed (both methods fit the same trial; two-sided Wilcoxon signed-rank over {n} seeds, Holm "
            f"over the {m} movements, alpha {ALPHA:g}; reading L6), pv_irf's K(theta) has the significantly smaller "
            f"RMS error in {len(a)} of the {m} movements" + (f" ({_movements(a)})" if len(a) else "") +
            f", FSEWLS mapped through theta in {len(b)}" + (f" ({_movements(b)})" if len(b) else "") +
            f"; no significant difference in {m - len(a) - len(b)}.")
    pv, fs = piv["pv_irf"], piv["fsewls"]
    return (text + f" Medians over seeds: pv_irf's error ranges from {pv.min():.2g} % to {pv.max():.2g} % of the "
            f"mean K, FSEWLS mapped through theta's from {fs.min():.2g} % to {fs.max():.2g} %.")


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


# --------------------------------------------------------------------------------------- part reflex (L7-L9)
#: the cells of the reflex part (its sweep)
REFLEX_CELL = ["reflex_gain", "fs"]
#: the method with the reflex pathway, compared with each other method
PVPC = "pv_parallel_cascade"
#: the methods of the reflex part, in the tables' order
REFLEX_METHODS = (PVPC, "pv_irf", "fsewls")
#: how the tables name them
LABELS = {PVPC: "pv_parallel_cascade", "pv_irf": "pv_irf", "fsewls": "FSEWLS mapped"}


def reflex_tests(rows: pd.DataFrame) -> pd.DataFrame:
    """pv_parallel_cascade against each other method of the rows, per cell (reflex gain x rate): the paired
    tests of :func:`paired_tests`, Holm over every cell and comparison together (one family, reading L9)."""
    others = [m for m in REFLEX_METHODS[1:] if m in set(rows["estimator"].dropna())]
    return with_holm(pd.concat([_pairs(rows, SCORE, (PVPC, m), REFLEX_CELL) for m in others], ignore_index=True))


def _cell(g: pd.DataFrame, est: str, metric: str, digits: int = 2) -> str:
    x = g[(g["estimator"] == est) & (g["metric"] == metric)]
    if not len(x):
        return ""
    r = x.iloc[0]
    return median_range(float(r["median"]), float(r["min"]), float(r["max"]), int(r["n"]), digits)


def reflex_table(rows: pd.DataFrame) -> pd.DataFrame:
    """Per cell (reflex gain x rate): the reflex's share of the torque; each method's RMS and signed mean error
    of K(theta) (% of the mean K); the bands' coverage; pv_parallel_cascade's reflex gain error and how often it
    kept its reflex pathway (medians, min to max over seeds); and the paired tests (:func:`reflex_tests`)."""
    metrics = ["kmap_rmse_pct", "kmap_mean_error_pct", "band_coverage", "reflex_gain_rmse_pct", "reflex_kept"]
    st = over_seeds(rows, [*REFLEX_CELL, "estimator", "metric"], metrics)
    share = over_seeds(rows[rows["estimator"].fillna("") == ""], REFLEX_CELL, ["reflex_share_pct"])
    tests = reflex_tests(rows)
    out = []
    for (g0, fs), g in st.groupby(REFLEX_CELL):
        row = {"reflex gain (N·m·s/rad)": g0, "rate (Hz)": fs}
        sh = share[(share["reflex_gain"] == g0) & (share["fs"] == fs)]
        row["reflex share (%)"] = (median_range(float(sh["median"].iloc[0]), float(sh["min"].iloc[0]),
                                                float(sh["max"].iloc[0]), int(sh["n"].iloc[0]), 1) if len(sh) else "0")
        for est in REFLEX_METHODS:
            row[f"{LABELS[est]} RMS error (%)"] = _cell(g, est, "kmap_rmse_pct") or "not fitted"
            row[f"{LABELS[est]} mean error (%)"] = _cell(g, est, "kmap_mean_error_pct")
        for est in (PVPC, "pv_irf"):
            row[f"{LABELS[est]} band coverage"] = _cell(g, est, "band_coverage")
        row["pv_parallel_cascade reflex gain error (%)"] = _cell(g, PVPC, "reflex_gain_rmse_pct", 1)
        kept = g[(g["estimator"] == PVPC) & (g["metric"] == "reflex_kept")]
        row["reflex kept (seeds)"] = f"{rows_kept(rows, g0, fs)} of {int(kept['n'].iloc[0])}" if len(kept) else ""
        t = tests[(tests["reflex_gain"] == g0) & (tests["fs"] == fs)] if len(tests) else tests
        for _, r in t.iterrows():
            row[f"vs {LABELS[r['b']]}: median paired difference (p Holm)"] = (
                f"{r['median_diff']:+.2f} ({r['p_holm']:.2g}): {r['better'] or 'neither'} smaller")
        out.append(row)
    return pd.DataFrame(out)


def rows_kept(rows: pd.DataFrame, g0: float, fs: float) -> int:
    """The seeds of a cell in which pv_parallel_cascade kept its reflex pathway."""
    sel = _ok(rows)
    sel = sel[(sel["metric"] == "reflex_kept") & (sel["estimator"] == PVPC) & (sel["reflex_gain"] == g0)
              & (sel["fs"] == fs)]
    return int(np.sum(sel["value"].to_numpy(float) > 0.5))


def _reflex_summary(rows: pd.DataFrame) -> str:
    """The comparison written from the paired tests' outcome (:func:`reflex_tests`) and each method's range of
    errors with a reflex (medians over seeds)."""
    tests = reflex_tests(rows)
    if tests.empty:
        return ""
    st = over_seeds(rows[rows["reflex_gain"] > 0], [*REFLEX_CELL, "estimator"], [SCORE])
    n = f"{tests['n'].min()}" if tests["n"].min() == tests["n"].max() else f"{tests['n'].min()} to {tests['n'].max()}"
    parts = []
    for other in tests["b"].unique():
        t = tests[tests["b"] == other]
        wins, losses = (t[t["better"] == e] for e in (PVPC, other))
        parts.append(f"against {LABELS[other]}, pv_parallel_cascade's K(theta) has the significantly smaller RMS error "
                     f"in {len(wins)} of the {len(t)} cells" + (f" ({_cells(wins)})" if len(wins) else "") +
                     f", the other in {len(losses)}" + (f" ({_cells(losses)})" if len(losses) else ""))
    text = (f"Paired by seed (two-sided Wilcoxon signed-rank over {n} seeds, Holm over the {len(tests)} tests, alpha "
            f"{ALPHA:g}; reading L9): " + "; ".join(parts) + ".")
    if len(st):
        ranges = "; ".join(f"{LABELS[e]} {g['median'].min():.2g} % to {g['median'].max():.2g} %"
                           for e, g in st.groupby("estimator") if e in LABELS)
        text += f" With a reflex (gain > 0), medians over seeds of the RMS error of K(theta): {ranges}."
    return text


def _cells(t: pd.DataFrame) -> str:
    return ", ".join(f"gain {g:g} at {f:g} Hz" for g, f in zip(t["reflex_gain"], t["fs"]))


@register("lpv.reflex")
def lpv_reflex(part, rows, curves, folder, checks) -> PartReport:
    rows = _ok(rows)
    fig, axes = new_figure(2, 2, figsize=(11, 8.5))
    (a, b), (c, d) = axes
    c0 = curves[curves["seed"] == curves["seed"].min()] if len(curves) else curves
    strongest = max(rows["reflex_gain"].dropna()) if len(rows) else 0
    colours = {PVPC: "tab:green", "pv_irf": "tab:blue", "fsewls": "tab:orange"}
    for ax, fs in zip((a, b), sorted(rows["fs"].dropna().unique())[:2] if len(rows) else ()):
        s = c0[(c0["reflex_gain"] == strongest) & (c0["fs"] == fs) & (c0["curve"] == "k_theta")] if len(c0) else c0
        for (series, est), g in s.groupby(["series", s["estimator"].fillna("")]) if len(s) else []:
            if series == "truth":
                ax.plot(g["x"], g["y"], "k-", lw=2, label="true K(theta)")
            elif series == "estimate":
                ax.plot(g["x"], g["y"], "-", color=colours.get(est, "0.4"), lw=1.3, label=LABELS.get(est, est))
        for est in (PVPC, "pv_irf"):
            lo = s[(s["series"] == "band low") & (s["estimator"] == est)] if len(s) else s
            hi = s[(s["series"] == "band high") & (s["estimator"] == est)] if len(s) else s
            if len(lo) and len(hi):
                ax.fill_between(lo["x"], lo["y"], hi["y"].to_numpy(), color=colours[est], alpha=0.2,
                                label=f"{LABELS[est]} {100 * LEVEL:g} % band")
        ax.set_xlabel("slow angle (rad)")
        ax.set_ylabel("K (N·m/rad)")
        seed = int(c0["seed"].min()) if len(c0) else 0
        ax.set_title(f"K(theta), reflex gain {strongest:g} N·m·s/rad, {fs:g} Hz (seed {seed})")
        ax.legend(fontsize=7)
    st = over_seeds(rows, [*REFLEX_CELL, "estimator"], ["kmap_mean_error_pct"])
    for (est, fs), g in st.groupby(["estimator", "fs"]):
        g = g.sort_values("reflex_gain")
        c.errorbar(g["reflex_gain"], g["median"], yerr=[g["median"] - g["min"], g["max"] - g["median"]],
                   fmt="-o" if fs == min(st["fs"]) else "--s", color=colours.get(est, "0.4"), ms=4, capsize=2, lw=1,
                   label=f"{LABELS.get(est, est)}, {fs:g} Hz")
    c.axhline(0, color="0.6", lw=0.8)
    c.set_xlabel("reflex gain at the mean angle (N·m·s/rad)")
    c.set_ylabel("mean error of K(theta) (% of mean K)")
    c.set_title("The reflex torque each method reads as stiffness")
    c.legend(fontsize=6)
    g = c0[(c0["curve"] == "reflex_gain") & (c0["reflex_gain"] == strongest)] if len(c0) else c0
    for (series, fs), h in g.groupby(["series", "fs"]) if len(g) else []:
        if series == "truth":
            if fs == min(g["fs"]):
                d.plot(h["x"], h["y"], "k-", lw=2, label="true G(theta)")
        else:
            d.plot(h["x"], h["y"], "-" if fs == min(g["fs"]) else "--", color=colours[PVPC], lw=1.3,
                   label=f"pv_parallel_cascade, {fs:g} Hz")
    d.set_xlabel("slow angle (rad)")
    d.set_ylabel("reflex gain (N·m·s/rad)")
    d.set_title(f"The reflex's static gain along the movement (gain {strongest:g})")
    d.legend(fontsize=7)
    fig.tight_layout()
    name = save(fig, folder, "lpv_reflex.png")
    return PartReport(figures=[(name, "K(theta) with the strongest reflex at each rate, seed 0 (top); the signed mean "
                                      "error of K(theta) by reflex gain (bottom left, medians and ranges over seeds); "
                                      "the reflex's static gain along the movement (bottom right).")],
                      tables=[("K(theta) with a reflex, by reflex gain and rate (medians, min to max over seeds)",
                               reflex_table(rows))],
                      text=_reflex_summary(rows))
