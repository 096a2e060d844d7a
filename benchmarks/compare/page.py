"""The interactive comparison page: one self-contained HTML file (no network, no library) with the full
table of a comparison grid, sortable by any column and filtered by scenario, metric, tuning, backend and
method, and k_hat(t) against the truth for every scenario, drawn as inline SVG by a few lines of script
from the page's own data (template ``benchmarks/harness/templates/comparison.html.j2``). The rest of the
report (identifiability, paired comparisons, settings) comes as static tables.

The page reads its state from the address's fragment (``#sort=value&dir=desc&metric=vaf_stiffness``), so
a view can be linked; after drawing, ``body`` carries ``data-rows`` (rows shown) and ``data-plots`` (plots
drawn), which the browser test reads (tests/test_comparison_page.py).
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from jointbench.benchmarks.harness.pages import script_json, table, template_env

#: columns of the page's table: (key in the full table, header)
COLUMNS = (("cell", "scenario"), ("backend", "backend"), ("method", "method"), ("tuning", "tuning"),
           ("metric", "metric"), ("value", "value"), ("lo", "interval lo"), ("hi", "interval hi"),
           ("rank", "rank"), ("ranked", "of"), ("n", "n"), ("note", "note"), ("settings", "settings"))
NUMERIC = {"value", "lo", "hi", "rank", "ranked", "n"}
#: methods per plot (the best by median VAF of k), and of those drawn with their band over realizations
PLOT_METHODS, BANDS = 8, 3


def _num(v, digits: int = 4):
    """A number for the page's data: ``digits`` significant digits; infinities as the strings
    'inf'/'-inf'; NaN as null."""
    if v is None:
        return None
    v = float(v)
    if math.isnan(v):
        return None
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return float(f"{v:.{digits}g}")


def _series(y) -> list:
    return [None if not np.isfinite(v) else float(f"{v:.3g}") for v in np.asarray(y, float)]


def _time(t) -> dict:
    """A time axis: start, step and count when uniform (the stored curves are), else the samples."""
    t = np.asarray(t, float)
    if t.size > 2 and np.allclose(np.diff(t), t[1] - t[0], rtol=1e-6, atol=1e-9):
        return {"t0": float(f"{t[0]:.6g}"), "dt": float(f"{t[1] - t[0]:.6g}"), "n": int(t.size)}
    return {"t": [float(f"{x:.6g}") for x in t]}


def page_data(full: pd.DataFrame, curves: dict, order: dict | None = None) -> dict:
    """The page's data: the full table's rows as arrays in :data:`COLUMNS` order (texts as indices into
    ``strings``), and per (cell, backend, tuning) plot the truth and the mean of the :data:`PLOT_METHODS`
    best methods by median VAF of k (the first :data:`BANDS` with their band over realizations, when the
    curves carry it). ``curves``: (cell, backend, tuning) -> a set of :func:`compare_plots.curve_sets`;
    ``order``: the same key -> methods best first."""
    strings: dict[str, int] = {}
    rows = []
    for rec in full.to_dict("records"):
        row = []
        for k, _ in COLUMNS:
            v = rec.get(k)
            if k in NUMERIC:
                row.append(_num(v))
            else:
                row.append(strings.setdefault("" if v is None or (isinstance(v, float) and math.isnan(v))
                                              else str(v), len(strings)))
        rows.append(row)
    plots = []
    for (cell, backend, tuning), d in curves.items():
        best = [m for m in (order or {}).get((cell, backend, tuning), []) if m in d["methods"]] or sorted(d["methods"])
        methods = []
        for m in best[:PLOT_METHODS]:
            s = d["methods"][m]
            e = {"name": m, "time": _time(s["t"]), "mean": _series(s["mean"])}
            if "lo" in s and m in best[:BANDS]:
                e["lo"], e["hi"] = _series(s["lo"]), _series(s["hi"])
            methods.append(e)
        plots.append({"cell": cell, "backend": backend, "tuning": tuning, "time": _time(d["t"]),
                      "truth": _series(d["truth"]), "methods": methods, "of": len(d["methods"])})
    return {"columns": [h for _, h in COLUMNS], "keys": [k for k, _ in COLUMNS],
            "coded": [k not in NUMERIC for k, _ in COLUMNS], "strings": list(strings), "rows": rows, "plots": plots}


def render(title: str, intro: list[str], data: dict, static: list[tuple[str, pd.DataFrame]]) -> str:
    """The page as one HTML string: ``intro`` paragraphs (inline markdown), the interactive table and plots
    of ``data`` (:func:`page_data`) and the ``static`` tables."""
    blob = script_json(data)
    note = (f"Mean estimate over realizations of the {PLOT_METHODS} methods with the highest median VAF of k per "
            f"scenario (the plot's legend; all methods' values are in the table); shaded: the 5th to 95th "
            f"percentile over realizations for the best {BANDS}, where the run stored it.")
    tables = [table(t, df, empty="no rows") for t, df in static if df is not None and not df.empty]
    return template_env().get_template("comparison.html.j2").render(title=title, intro=intro, data=blob,
                                                                    plots_note=note, tables=tables)
