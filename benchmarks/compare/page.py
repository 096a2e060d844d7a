"""The interactive comparison page: one self-contained HTML file (no network, no library) that opens on an
overview (:class:`Overview`: the leaderboard of every ranked metric and tuning column, the heat map of each
tuning column and, when the run has it, the summary over scenarios with its critical-difference diagram),
then the full table of a comparison grid, sortable by any column and filtered by scenario, metric, tuning,
backend and method, and k_hat(t) against the truth for every scenario, drawn as inline SVG by a few lines of
script from the page's own data (template ``benchmarks/harness/templates/comparison.html.j2``). The rest of
the report (identifiability, paired comparisons, settings) comes as static tables. A method has the colour
and marker of :func:`jointbench.benchmarks.compare.styles.method_styles` everywhere: in the leaderboards, in
every plot and its legend, as in the static figures.

The page reads its state from the address's fragment (``#sort=value&dir=desc&metric=vaf_stiffness``), so
a view can be linked; after drawing, ``body`` carries ``data-rows`` (rows shown), ``data-plots`` (plots
drawn) and ``data-boards`` (leaderboards shown), which the browser tests read (tests/test_comparison_page.py,
tests/test_comparison_page_overview.py).
"""
from __future__ import annotations

import base64
import dataclasses
import math
import mimetypes
from pathlib import Path

import numpy as np
import pandas as pd

from jointbench.benchmarks.compare.leaderboard import display
from jointbench.benchmarks.compare.styles import TRUTH, MethodStyle, method_styles
from jointbench.benchmarks.compare.tables import METRICS
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


def page_data(full: pd.DataFrame, curves: dict, order: dict | None = None,
              styles: dict[str, MethodStyle] | None = None) -> dict:
    """The page's data: the full table's rows as arrays in :data:`COLUMNS` order (texts as indices into
    ``strings``), per (cell, backend, tuning) plot the truth and the mean of the :data:`PLOT_METHODS`
    best methods by median VAF of k (the first :data:`BANDS` with their band over realizations, when the
    curves carry it), and every method's style (``styles``, default: those of every method of ``full``:
    colour, marker and its SVG path; the plots draw each method in it). ``curves``: (cell, backend, tuning) -> a set of
    :func:`jointbench.benchmarks.compare.plots.curve_sets`; ``order``: the same key -> methods best first."""
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
    styles = styles or method_styles(list(full["method"]) + [m for d in curves.values() for m in d["methods"]])
    unstyled = sorted({m for d in curves.values() for m in d["methods"]} - set(styles))
    if unstyled:
        raise ValueError(f"no style for the plotted methods {unstyled}: give method_styles every method")
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
            "coded": [k not in NUMERIC for k, _ in COLUMNS], "strings": list(strings), "rows": rows, "plots": plots,
            "styles": {m: st.as_dict() for m, st in styles.items()},
            "truth": TRUTH}


# ----------------------------------------------------------------------------------------------- overview
@dataclasses.dataclass
class Overview:
    """What the page opens on: ``boards`` (:func:`board_tables`), ``heatmaps`` (tuning column -> (figure file,
    caption)), ``summary`` (:func:`summary_over_scenarios`: None when the run has no summary over scenarios),
    ``styles`` (method -> style: the leaderboards' swatches), ``note`` (what the overview shows, inline
    markdown) and ``default_metric`` (the metric it opens on)."""

    boards: list[dict]
    heatmaps: dict[str, tuple[Path, str]]
    summary: dict | None
    styles: dict[str, MethodStyle]
    note: str = ""
    default_metric: str = ""


def image_uri(path) -> str:
    """A figure file (PNG or SVG) as a ``data:`` URI (the page loads nothing); empty when the file is missing."""
    path = Path(path)
    if not path.is_file():
        return ""
    mime = mimetypes.guess_type(path.name)[0] or "application/octet-stream"
    return f"data:{mime};base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def board_tables(board: pd.DataFrame) -> list[dict]:
    """The leaderboard (:func:`jointbench.benchmarks.compare.leaderboard.leaderboard`) as one table per metric
    and tuning column, as :func:`jointbench.benchmarks.compare.leaderboard.display` shows it: ``metric``,
    ``tuning``, ``title``, ``columns`` and ``rows`` (each: ``method`` and ``cells``, the texts of its columns
    in order, the method's included)."""
    out = []
    for (metric, tuning), g in board.groupby(["metric", "tuning"], sort=False):
        d = display(g)
        out.append({"metric": metric, "tuning": tuning, "title": f"{METRICS[metric][0]}, {tuning} column",
                    "columns": list(d.columns),
                    "rows": [{"method": r["method"], "cells": list(r.values())} for r in d.to_dict("records")]})
    return out


def summary_over_scenarios(cd_figures: dict[tuple[str, str], Path] | None,
                           summary: pd.DataFrame | None, title: str = "") -> dict | None:
    """The overview's slot for the summary over scenarios (a test over every ranked scenario per metric and
    tuning column, e.g. Friedman with a post-hoc test, and its critical-difference diagram): ``cd_figures``
    maps (metric, tuning column) to the diagram's file (PNG or SVG), ``summary`` is its table (shown as it
    is, titled ``title``). None when the run has neither (the page then shows no such section); a missing
    file is left out."""
    figs = [{"metric": m, "tuning": t, "uri": image_uri(p), "title": f"{METRICS.get(m, (m,))[0]}, {t} column"}
            for (m, t), p in (cd_figures or {}).items()]
    figs = [f for f in figs if f["uri"]]
    tab = table(title or "Summary over scenarios", summary, empty="no rows") if summary is not None else None
    if not figs and tab is None:
        return None
    return {"figures": figs, "table": tab}


def render(title: str, intro: list[str], data: dict, static: list[tuple[str, pd.DataFrame]],
           overview: Overview | None = None, notes: list[str] | None = None) -> str:
    """The page as one HTML string: ``intro`` paragraphs (inline markdown), the ``overview`` (when given), the
    ``notes`` paragraphs (definitions and the like, after the overview), the interactive table and plots of
    ``data`` (:func:`page_data`) and the ``static`` tables."""
    blob = script_json(data)
    note = (f"Mean estimate over realizations of the {PLOT_METHODS} methods with the highest median VAF of k per "
            f"scenario (the plot's legend; all methods' values are in the table); shaded: the 5th to 95th "
            f"percentile over realizations for the best {BANDS}, where the run stored it.")
    tables = [table(t, df, empty="no rows") for t, df in static if df is not None and not df.empty]
    ov = None
    if overview is not None:
        ov = {"boards": overview.boards, "note": overview.note, "summary": overview.summary,
              "heatmaps": [{"tuning": t, "uri": image_uri(p), "caption": c} for t, (p, c) in overview.heatmaps.items()
                           if Path(p).is_file()],
              "default_metric": overview.default_metric,
              "styles": {m: st.as_dict() for m, st in overview.styles.items()},
              "metrics": list(dict.fromkeys(b["metric"] for b in overview.boards)),
              "metric_titles": {b["metric"]: METRICS[b["metric"]][0] for b in overview.boards},
              "tunings": list(dict.fromkeys(b["tuning"] for b in overview.boards))}
    return template_env().get_template("comparison.html.j2").render(title=title, intro=intro, data=blob,
                                                                    plots_note=note, tables=tables, overview=ov,
                                                                    notes=notes or [])
