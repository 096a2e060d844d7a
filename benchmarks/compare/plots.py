"""The figures of a comparison grid, drawn from its full table (:mod:`jointbench.benchmarks.compare.tables`)
and stored curves: the methods x scenarios heat map of the VAF of k on a diverging scale centred at 0,
the rise-time / random-error trade-off with the methods whose rise time is infinite at the axis edge,
and k_hat(t) against the truth per scenario. Each figure is written as PNG (the report) and as SVG and PDF
(vector, for print). A method has one colour and marker in every figure and panel
(:func:`jointbench.benchmarks.compare.styles.method_styles` over all the comparison's methods); legends sit
outside the axes.
"""
from __future__ import annotations

import textwrap

import numpy as np
import pandas as pd

from jointbench.benchmarks.figures import new_figure, save
from jointbench.benchmarks.compare.styles import TRUTH, MethodStyle, method_styles
from jointbench.benchmarks.compare.tables import labelled

#: the colour scale of the heat map ends here (% VAF); lower values are drawn in the end colour
VAF_FLOOR = -100.0
#: methods drawn per panel of the k_hat(t) figure (the best by median VAF of k)
CURVES_PER_PANEL = 5
#: of those, drawn with their band over realizations (legibility)
BANDS = 3
#: PNG rate of the k_hat(t) figure (many noisy lines: the report inlines it; the SVG and PDF have every detail)
KHAT_DPI = 100
#: markers drawn along each k_hat(t) line (its second cue beside the colour)
MARKS_PER_LINE = 8
#: vector formats written beside each PNG
VECTOR_FORMATS = ("svg", "pdf")
#: series names of the spread of the estimate over realizations in the curves file
SPREAD = ("p05 over realizations", "p95 over realizations")


def save_formats(fig, folder, name: str, dpi: int | None = None) -> str:
    """The figure as ``name`` (PNG; at ``dpi``, else the report's rate) and beside it in every
    :data:`VECTOR_FORMATS` (for print); returns the PNG's name. The SVG carries no date (reproducible)."""
    folder.mkdir(parents=True, exist_ok=True)
    stem = name.rsplit(".", 1)[0]
    for fmt in VECTOR_FORMATS:
        meta = {"Date": None} if fmt == "svg" else {"CreationDate": None}
        fig.savefig(folder / f"{stem}.{fmt}", bbox_inches="tight", metadata=meta)
    return save(fig, folder, name) if dpi is None else save(fig, folder, name, dpi)


def _styles(styles: dict[str, MethodStyle] | None, table: pd.DataFrame) -> dict[str, MethodStyle]:
    """The styles given, else those of every method of ``table`` (the full table: all tuning columns)."""
    return styles if styles is not None else method_styles(table["method"])


def _vaf_text(v: float) -> str:
    if not np.isfinite(v):
        return ""
    if abs(v) >= 1000:
        return f"{v / 1000:.0f}k"
    return f"{v:.0f}" if abs(v) >= 10 else f"{v:.1f}"


def heat_map(table: pd.DataFrame, rows: pd.DataFrame, backend: str, tuning: str, feasible: dict,
             folder, name: str) -> str | None:
    """Methods x scenarios coloured by the median VAF of k on a diverging scale centred at 0 % (blue above:
    better than a constant at the true mean; red below), clipped at :data:`VAF_FLOOR` (the colour bar
    says so; each cell prints its value). Skipped combinations grey ('skip'), refused 'n/f'; infeasible
    scenarios are marked '(infeasible)' on their label."""
    v = table[(table["metric"] == "vaf_stiffness") & (table["backend"] == backend) & (table["tuning"] == tuning)]
    ran = rows[(rows["backend"] == backend) & (rows["tuning"] == tuning) & rows["method"].ne("")
               & ~rows["metric"].isin(["skipped", "tuning_vaf_output"]) & rows["estimator"].ne("(scenario)")]
    methods = sorted(set(ran["method"]) | set(v["method"]))    # with the tuned copies of untunable fits
    scens = list(dict.fromkeys(v["cell"])) or list(dict.fromkeys(ran["cell"]))
    if not methods or not scens:
        return None
    grid = np.full((len(methods), len(scens)), np.nan)
    for r in v.itertuples():
        if r.method in methods:
            grid[methods.index(r.method), scens.index(r.cell)] = r.value
    state = {}
    sub = rows[(rows["backend"] == backend) & (rows["tuning"] == tuning)]
    for metric, tag in (("skipped", "skip"), ("not_fitted", "n/f"), ("not_scored", "n/s")):
        for r in sub[sub["metric"] == metric].itertuples():
            state[(r.method, r.cell)] = tag
    import matplotlib.pyplot as plt
    from matplotlib.colors import TwoSlopeNorm

    fig, ax = new_figure(figsize=(max(6.0, 0.62 * len(scens) + 3.0), max(3.0, 0.36 * len(methods) + 2.2)))
    cmap = plt.get_cmap("RdBu").with_extremes(bad="0.88", under=plt.get_cmap("RdBu")(0.0))
    norm = TwoSlopeNorm(vmin=VAF_FLOOR, vcenter=0.0, vmax=100.0)
    im = ax.imshow(np.where(np.isfinite(grid), np.maximum(grid, VAF_FLOOR - 1), np.nan), cmap=cmap, norm=norm,
                   aspect="auto")
    for i, m in enumerate(methods):
        for j, s in enumerate(scens):
            value = grid[i, j]
            text = _vaf_text(value) if np.isfinite(value) else state.get((m, s), "")
            dark = np.isfinite(value) and abs(norm(max(value, VAF_FLOOR)) - 0.5) > 0.3
            ax.text(j, i, text, ha="center", va="center", fontsize=7, color="white" if dark else "black")
    labels = [s + ("" if feasible.get((s, backend), np.nan) > 0 else " (infeasible)") for s in scens]
    ax.set_xticks(range(len(scens)), labels, rotation=60, ha="right", fontsize=7)
    ax.set_yticks(range(len(methods)), methods, fontsize=8)
    bar = fig.colorbar(im, ax=ax, extend="min", fraction=0.04, pad=0.02)
    bar.set_label(f"VAF of k (%), median over realizations\n(colour clipped at {VAF_FLOOR:.0f} %; cells: values)",
                  fontsize=8)
    bar.ax.tick_params(labelsize=7)
    return save_formats(fig, folder, name)


def _bar(value: float, lo: float, hi: float, edge: float | None = None):
    """Error bar of an interval; an infinite upper end runs to ``edge`` (the axis edge) when given."""
    if np.isposinf(hi) and edge is not None:
        hi = max(edge, value)
    if not (np.isfinite(lo) and np.isfinite(hi) and np.isfinite(value)):
        return None
    return [[max(0.0, value - lo)], [max(0.0, hi - value)]]


def _figure_legend(fig, handles: dict) -> None:
    """One legend for the whole figure, below its panels (never over the data): ``handles`` label -> artist."""
    ncol = min(6, max(1, len(handles)))
    fig.legend(list(handles.values()), list(handles.keys()), loc="upper center", bbox_to_anchor=(0.5, 0.0),
               ncol=ncol, fontsize=7, frameon=False, handlelength=2.4)


def _handle(style: MethodStyle, line: bool):
    """A legend entry in a method's style: its colour and marker (with a line for line plots)."""
    from matplotlib.lines import Line2D

    return Line2D([], [], color=style.color, marker=style.marker, ms=5, ls="-" if line else "", lw=1.2)


def trade_off(table: pd.DataFrame, backend: str, tuning: str, folder, name: str,
              styles: dict[str, MethodStyle] | None = None) -> tuple[str | None, list[str]]:
    """Random error against rise time per square-wave scenario, one point per method with its interval, in
    the method's colour and marker (``styles``; default: those of every method of ``table``). A method whose
    rise time is infinite (a step never followed) is drawn hollow at the right edge of the axis (dotted) and
    listed in the panel. Returns the file and one line per panel naming them."""
    styles = _styles(styles, table)
    t = table[(table["backend"] == backend) & (table["tuning"] == tuning)]
    rise = t[t["metric"] == "rise_time_s"]
    if rise.empty:
        return None, []
    scens = list(dict.fromkeys(rise["cell"]))
    ncol = min(3, len(scens))
    nrow = -(-len(scens) // ncol)
    fig, axes = new_figure(nrow, ncol, figsize=(4.4 * ncol, 4.3 * nrow), squeeze=False)
    lines, drawn = [], set()
    for ax, scen in zip(axes.ravel(), scens):
        r = rise[rise["cell"] == scen].set_index("method")
        e = t[(t["cell"] == scen) & (t["metric"] == "random_error")].set_index("method")
        both = [m for m in r.index if m in e.index]
        fin = [m for m in both if np.isfinite(r.loc[m, "value"])]
        inf = [m for m in both if not np.isfinite(r.loc[m, "value"])]
        xmax = max([r.loc[m, "hi"] if np.isfinite(r.loc[m, "hi"]) else r.loc[m, "value"] for m in fin] or [1.0])
        xmax = xmax if np.isfinite(xmax) and xmax > 0 else 1.0
        edge = 1.1 * xmax
        for m in fin:
            x, y, st = r.loc[m], e.loc[m], styles[m]
            ax.errorbar(x["value"], y["value"], xerr=_bar(x["value"], x["lo"], x["hi"], edge),
                        yerr=_bar(y["value"], y["lo"], y["hi"]), fmt=st.marker, color=st.color, ms=5, capsize=2)
        for m in inf:
            y, st = e.loc[m], styles[m]
            ax.errorbar(edge, y["value"], yerr=_bar(y["value"], y["lo"], y["hi"]), fmt=st.marker, color=st.color,
                        mfc="white", ms=6, capsize=2)
        drawn.update(fin + inf)
        if inf:
            ax.axvline(edge, color="0.6", lw=0.8, ls=":")
            listed = textwrap.fill("rise time ∞, drawn hollow at the dotted edge: " + ", ".join(inf), 70)
            ax.text(0.0, -0.2, listed, transform=ax.transAxes, ha="left", va="top", fontsize=6, color="0.25")
            lines.append(f"{scen}: rise time infinite for {', '.join(inf)}")
        ax.set_xlim(0, 1.15 * xmax)
        ax.set_title(scen, fontsize=8)
        ax.set_xlabel("rise time 10-90 % (s)", fontsize=8)
        ax.set_ylabel("random error (N·m/rad)", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    for ax in axes.ravel()[len(scens):]:
        ax.axis("off")
    fig.tight_layout(h_pad=3.0)
    _figure_legend(fig, {m: _handle(styles[m], line=False) for m in sorted(drawn)})
    return save_formats(fig, folder, name), lines


def curve_sets(curves: pd.DataFrame | None, backend: str, tuning: str) -> dict[str, dict]:
    """Per cell: ``t`` and ``truth`` and per method ``mean`` (and ``lo``/``hi``, the 5th and 95th
    percentiles over realizations, when the curves carry them)."""
    if curves is None or curves.empty or "series" not in curves.columns:
        return {}
    c = labelled(curves.assign(metric="curve"))
    c = c[(c["backend"] == backend) & (c["tuning"] == tuning)] if backend else c[c["tuning"] == tuning]
    out: dict[str, dict] = {}
    for cell, g in c.groupby("cell", sort=False):
        d = {"methods": {}}
        for method, h in g.groupby("method", sort=True):
            s = {k: v.sort_values("x") for k, v in h.groupby("series")}
            if "mean estimate" not in s:
                continue
            m = {"t": s["mean estimate"]["x"].to_numpy(float), "mean": s["mean estimate"]["y"].to_numpy(float)}
            if all(k in s for k in SPREAD):
                m["lo"], m["hi"] = (s[k]["y"].to_numpy(float) for k in SPREAD)
            d["methods"][method] = m
            if "truth" in s and len(s["truth"]) > len(d.get("t", ())):      # the widest span of the truth
                d["t"], d["truth"] = s["truth"]["x"].to_numpy(float), s["truth"]["y"].to_numpy(float)
        if d["methods"] and "truth" in d:
            out[cell] = d
    return out


def best_methods(table: pd.DataFrame, cell: str, backend: str, tuning: str, n: int) -> list[str]:
    """The ``n`` methods with the highest median VAF of k in the cell (finite values)."""
    v = table[(table["cell"] == cell) & (table["backend"] == backend) & (table["tuning"] == tuning)
              & (table["metric"] == "vaf_stiffness")]
    v = v[np.isfinite(v["value"].astype(float))].sort_values("value", ascending=False)
    return list(v["method"][:n])


def khat_figure(sets: dict, table: pd.DataFrame, backend: str, tuning: str, folder, name: str,
                styles: dict[str, MethodStyle] | None = None) -> str | None:
    """k_hat(t) against the truth, one panel per scenario: the mean estimate over realizations of the
    :data:`CURVES_PER_PANEL` methods with the highest median VAF of k, each in its colour with its marker every
    so often (``styles``; default: those of every method of ``table``), the first :data:`BANDS` with the band
    of the 5th to 95th percentile over realizations where the curves carry it, and the truth over them all
    (black). One legend for the figure, below the panels, lists every method drawn."""
    if not sets:
        return None
    styles = _styles(styles, table)
    cells = list(sets)
    ncol = min(4, len(cells))
    nrow = -(-len(cells) // ncol)
    fig, axes = new_figure(nrow, ncol, figsize=(4.2 * ncol, 2.9 * nrow), squeeze=False)
    drawn = set()
    for ax, cell in zip(axes.ravel(), cells):
        d = sets[cell]
        shown = [m for m in best_methods(table, cell, backend, tuning, CURVES_PER_PANEL) if m in d["methods"]]
        for i, m in enumerate(shown):
            s, st = d["methods"][m], styles[m]
            every = max(1, len(s["t"]) // MARKS_PER_LINE)
            ax.plot(s["t"], s["mean"], color=st.color, lw=1.0, marker=st.marker, ms=3.5, markevery=(i * every
                    // max(1, len(shown)), every), label=m, zorder=2)
            if "lo" in s and i < BANDS:
                ax.fill_between(s["t"], s["lo"], s["hi"], color=st.color, alpha=0.12, lw=0, zorder=1)
        drawn.update(shown)
        ax.plot(d["t"], d["truth"], color=TRUTH, lw=1.4, label="truth", zorder=3)
        lo, hi = np.min(d["truth"]), np.max(d["truth"])
        pad = max(0.6 * (hi - lo), 0.2 * abs(hi))
        ax.set_ylim(lo - pad, hi + pad)
        ax.set_title(cell, fontsize=8)
        ax.set_xlabel("t (s)", fontsize=7)
        ax.set_ylabel("k (N·m/rad)", fontsize=7)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    for ax in axes.ravel()[len(cells):]:
        ax.axis("off")
    fig.tight_layout()
    from matplotlib.lines import Line2D

    handles = {"truth": Line2D([], [], color=TRUTH, lw=1.4)}
    handles.update({m: _handle(styles[m], line=True) for m in sorted(drawn)})
    _figure_legend(fig, handles)
    return save_formats(fig, folder, name, dpi=KHAT_DPI)
