"""The report of a comparison grid (protocol ``compare``): every method x scenario x metric with an
interval that contains its value and its rank, the scenarios' identifiability (infeasible ones shown and
left out of the rankings), paired comparisons between methods over the same realizations and their win
counts, the backends' agreement in one line per scenario, the settings of every method in both tuning
columns, the figures (heat map, rise-time / random-error trade-off, k_hat(t) against the truth; PNG, SVG
and PDF), the leaderboard of every ranked metric and tuning column with its exports for a paper (LaTeX
booktabs and wide CSV) and the interactive page ``<part>_comparison.html``, which opens on an overview.
Every heading, count and reading is derived from the tidy rows.

The tables are :mod:`jointbench.benchmarks.compare.tables` and :mod:`jointbench.benchmarks.compare.pairs`, the figures
:mod:`jointbench.benchmarks.compare.plots` (a method's colour and marker: :mod:`jointbench.benchmarks.compare.styles`),
the leaderboard :mod:`jointbench.benchmarks.compare.leaderboard`, the exports
:mod:`jointbench.benchmarks.compare.export`, the page :mod:`jointbench.benchmarks.compare.page`, the statistics
:mod:`jointbench.benchmarks.compare.stats`.

References
----------
van de Ruit, Mugge, Cavallo, Lataire, Ludvig & Schouten, "Quantitative comparison of time-varying system
identification methods to describe human joint impedance" (the metrics).
"""
from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pandas as pd

from jointbench.benchmarks.compare import stats as cs
from jointbench.benchmarks.figures import PartReport, register
from jointbench.benchmarks.compare import export
from jointbench.benchmarks.compare import leaderboard as lb
from jointbench.benchmarks.compare import page as cp
from jointbench.benchmarks.compare import pairs as pairs_
from jointbench.benchmarks.compare import plots
from jointbench.benchmarks.compare import summary as csum
from jointbench.benchmarks.compare import tables as ct
from jointbench.benchmarks.compare.styles import MethodStyle, method_styles
from jointbench.benchmarks.compare.tables import METRICS, labelled  # noqa: F401  (the public names)
from jointbench.benchmarks.compare.tuning import edge_sentence
from jointbench.core.files import write_text

#: paired wins written out in the text per tuning column (the win tables have them all)
WIN_SENTENCES = 5
DEFINITIONS = (
    "Definitions (van de Ruit et al.'s comparison framework): VAF of k = 100 (1 - sum (k_hat - k)^2 / "
    "sum (k - mean k)^2) per realization (a constant at the true mean scores 0 %); RMS error of k per "
    "realization = RMS over t of k_hat - k; bias(t) = mean over realizations of k_hat(t) - k(t), its RMS over t; "
    "random error = RMS over t of the SD over realizations; total error = RMS over t and realizations of "
    "k_hat - k (total^2 = bias^2 + random^2 (R-1)/R); rise time = 10-90 % of the mean estimate at each step of a "
    "square wave, averaged over the steps (infinite when a step is never followed). k is the static gain of "
    "the true frozen impedance, scored between the discarded ends of the record where the estimate is valid "
    "in every realization.")


def _join(items: list[str]) -> str:
    items = [str(i) for i in items]
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1] if items else ""


#: how the text names the values of a cell axis
AXIS_NAMES = {"scenario": "base scenario", "joint": "joint", "variation": "stiffness variation",
              "perturbation": "perturbation", "noise": "noise level", "fs": "rate"}


def _axes_text(rows: pd.DataFrame) -> str:
    """What the scenarios are made of, from the rows: each varying axis and its values."""
    parts = []
    for a in ct.CELL_AXES:
        if a not in rows.columns:
            continue
        vals = [v for v in dict.fromkeys(rows.loc[rows["estimator"] != ct.SCENARIO_ROWS, a].dropna())]
        if a == "scenario" or len(vals) > 1:
            shown = ", ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in vals)
            parts.append(f"{len(vals)} {AXIS_NAMES[a]}{'s' if len(vals) != 1 else ''} ({shown})")
    return " x ".join(parts)


def _r_text(rows: pd.DataFrame) -> str:
    rs = ct.realizations(rows)
    if not rs:
        return "no per-realization rows"
    return "R = " + _join([str(r) for r in rs]) + " realizations per case"


def _paired_text(pairs: pd.DataFrame, rows: pd.DataFrame) -> str:
    text = ("Paired comparisons: for every feasible scenario (primary backend), tuning column and metric scored per "
            "realization, every pair of methods is compared over the realizations both were scored on (the same "
            "data: realization r is the same simulation for every method) by the two-sided Wilcoxon signed-rank "
            f"test (exact distribution), with Holm's correction over the pairs of that scenario, column and metric "
            f"(family-wise error {ct.ALPHA:g}); the median paired difference carries its paired percentile bootstrap "
            "90 % interval. 'A beats B' counts the scenarios where the adjusted p-value is below "
            f"{ct.ALPHA:g} and the median difference favours A.")
    if pairs.empty:
        return text + " No pair could be compared in this run."
    text += pairs_.attainability_text(pairs, ct.ALPHA)
    sig = int((pairs["verdict"] != "").sum())
    text += f" Significant after correction: {sig} of {len(pairs)} pairs."
    return text


def _readings(table: pd.DataFrame, primary: str) -> pd.DataFrame:
    """Derived readings: who ranks first how often on each ranked metric (primary backend, each tuning)."""
    out = []
    t = table[(table["backend"] == primary) & (table["rank"] == 1)]
    for tuning, g in t.groupby("tuning", sort=False):
        for metric in [m for m in METRICS if m in set(g["metric"])]:
            h = g[g["metric"] == metric]
            n_cells = table[(table["backend"] == primary) & (table["tuning"] == tuning) & (table["metric"] == metric)
                            & (table["ranked"] > 0)]["cell"].nunique()
            counts = h.groupby("method")["cell"].nunique().sort_values(ascending=False, kind="stable")
            out.append({"metric": METRICS[metric][0], "tuning": tuning, "ranked scenarios": n_cells,
                        "first (scenarios)": "; ".join(f"{m} {n}" for m, n in counts.items())})
    return pd.DataFrame(out)


@dataclasses.dataclass
class _Grid:
    """A comparison grid part's results as its report reads them, each derived once from the tidy rows."""

    name: str                        # the part's name
    rows: pd.DataFrame               # the tidy rows, labelled (ct.labelled)
    curves: pd.DataFrame
    table: pd.DataFrame              # every method x scenario x metric (ct.full_table)
    pairs: pd.DataFrame              # the paired comparisons (pairs_.paired)
    primary: str                     # the backend the rankings are on
    feas: dict                       # (scenario, backend) -> best median VAF of k (ct.feasibility)
    methods: list[str]               # methods with a score (skipped ones: reasons)
    cells: list[str]                 # the scenarios
    tunings: list[str]
    backends: list[str]
    ranked: list[str]                # the scenarios some method beats a constant in
    infeasible: list[str]
    styles: dict[str, MethodStyle]   # every method's colour and marker, in every figure and on the page
    board: pd.DataFrame              # the leaderboard (lb.leaderboard)
    exports: list[str]               # the summary's files for a paper (export.write_summary)

    @property
    def page_name(self) -> str:
        return f"{self.name}_comparison.html"


def _grid(part, rows: pd.DataFrame, curves: pd.DataFrame, folder) -> _Grid:
    """The grid's results from its rows; the full table, the paired comparisons and the summary's exports
    written beside the report (``<part>_scores.csv``, ``<part>_pairs.csv``, :func:`export.write_summary`)."""
    rows = labelled(rows)
    table = ct.full_table(rows, curves)
    table.to_csv(folder / f"{part.name}_scores.csv", index=False)
    primary = ct.primary_backend(rows)
    feas = ct.feasibility(table)
    cells = list(dict.fromkeys(table["cell"])) or list(dict.fromkeys(rows["cell"]))
    ranked = [c for c in cells if feas.get((c, primary), np.nan) > 0]
    pairs = pairs_.paired(rows, table)
    if not pairs.empty:
        pairs.to_csv(folder / f"{part.name}_pairs.csv", index=False)
    drawn = labelled(curves.assign(metric="curve"))["method"] if curves is not None and len(curves) else []
    board = lb.leaderboard(table, primary)
    return _Grid(part.name, rows, curves, table, pairs, primary, feas, methods=sorted(dict.fromkeys(table["method"])),
                 cells=cells, tunings=[t for t in dict.fromkeys(table["tuning"]) if t],
                 backends=[b for b in dict.fromkeys(rows.loc[rows["metric"] != "skipped", "backend"]) if b],
                 ranked=ranked, infeasible=[c for c in cells if c not in ranked and (c, primary) in feas],
                 styles=method_styles(list(table["method"]) + list(drawn)), board=board,
                 exports=export.write_summary(board, table, primary, folder, part.name))


def _overview(g: _Grid) -> list[str]:
    """The report's first two paragraphs: what was compared and where every number is; which scenarios are
    ranked."""
    several = len(g.backends) > 1
    return [f"{len(g.methods)} methods on {len(g.cells)} scenarios ({_axes_text(g.rows)}), {_r_text(g.rows)}; "
            f"backend{'s' if several else ''} {_join(g.backends) or 'unnamed'}"
            + (f" (rankings on {g.primary}; the others in one agreement line per scenario)" if several else "")
            + f"; tuning column{'s' if len(g.tunings) > 1 else ''} {_join(g.tunings)}. Every number is from the tidy "
            f"rows (`cases.csv`); the full table is `{g.name}_scores.csv`, the paired comparisons "
            f"`{g.name}_pairs.csv`"
            + (f"; for a paper, {_exports_text(g.exports)}" if g.exports else "")
            + f"; [the interactive comparison page]({g.page_name}) opens on the leaderboards and heat maps, then has "
            "the full table sortable and filtered by scenario and metric, and k_hat(t) of the best methods of "
            "every scenario.",
            f"**{len(g.ranked)} of {len(g.cells)} scenarios are ranked**"
            + (f"; {len(g.infeasible)} are infeasible (no method's median VAF of k is above 0 %, i.e. none beats a "
               f"constant at the true mean) and left out of every ranking and count: {_join(g.infeasible)}."
               if g.infeasible else "; in every scenario some method beats a constant at the true mean.")
            + (" " + ct.unranked_hint(g.rows, g.table, g.primary)).rstrip()]


def _exports_text(files: list[str]) -> str:
    """Each export of :func:`export.write_summary` written, named with what it holds."""
    what = {"_summary.tex": "the leaderboards as LaTeX booktabs tables, one per tuning column",
            "_summary_wide.csv": "the leaderboards, one row per method",
            "_values_wide.csv": "every value, one row per tuning column and method"}
    return "; ".join(f"`{f}` ({w})" for f in files for end, w in what.items() if f.endswith(end))


def _board_text(g: _Grid) -> str:
    """What the leaderboards show and over what (the backend; whether some method is ranked in fewer scenarios
    than its leaderboard counts, from the leaderboard's rows)."""
    few = not lb.partial(g.board).empty
    return (f"Leaderboards, per ranked metric and tuning column on the {g.primary} backend over the ranked "
            "scenarios: a method's mean share of the other methods ranked in a scenario that it is strictly "
            "ahead of (100 %: first alone in every scenario), the scenarios it ranks first in (ties included) and "
            "its median distance to each scenario's best (times the best for an error or a time, points behind "
            "for a VAF). A description, not a test"
            + ("; a method ranked in fewer scenarios than its leaderboard counts says 'n of N' in the scenarios "
               "column: its share is over those n only." if few else "."))


def _intervals_text(primary: str) -> str:
    return ("Intervals (90 %), each containing its value: per-realization metrics (VAF of k, RMS error, output VAF, "
            "fit time) show the median over realizations with the percentile bootstrap interval of that median "
            f"({cs.DRAWS} resamplings of the realizations, seed {cs.SEED}); the others show the study's bootstrap "
            "interval over realizations when it contains its value (else none is shown, and the table says so). "
            "Ranks (#) are competition ranks among finite values, per scenario and tuning column, on the "
            f"{primary} backend; an infinite rise time is not ranked, nor the random error of a constant estimate "
            "(its spread measures no tracking); a metric without a finite value says 'cannot rank'.")


def _text(g: _Grid) -> list[str]:
    """The report's paragraphs: the overview, the definitions, the intervals, the paired comparisons, the
    leaderboards, the most frequent wins and the backends' agreement (the first five make the page's
    introduction and notes)."""
    text = [*_overview(g), DEFINITIONS, _intervals_text(g.primary), _paired_text(g.pairs, g.rows)]
    if not g.board.empty:
        text.append(_board_text(g))
    n_bad = int(g.table["interval"].str.contains("excludes").sum())
    if n_bad:
        text.append(f"{n_bad} study intervals exclude their own value (rows from before the study re-centred its "
                    "bootstrap): not shown.")
    main = _main_metric(g.table)
    for tuning in g.tunings:
        s = pairs_.beats_sentences(g.pairs, main, tuning, top=WIN_SENTENCES)
        if s:
            text.append(f"The most frequent significant paired wins ({tuning} column; all in the win tables): "
                        + "; ".join(s) + ".")
    edges = edge_sentence(g.rows)
    if edges:
        text.append(edges)
    agree = ct.backend_agreement(g.table, g.primary)
    if agree:
        text.append("Backend agreement, one line per scenario:\n\n" + "\n\n".join(agree))
    return text


def _title(g: _Grid) -> str:
    return (f"{len(g.methods)} methods on {len(g.cells)} scenarios ({len(g.ranked)} ranked), {_r_text(g.rows)}, "
            f"tuning {' and '.join(g.tunings)}, backend{'s' if len(g.backends) > 1 else ''} {', '.join(g.backends)}")


def _method_tables(g: _Grid, ident: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    """The tables over every scenario: identifiability, who ranks first, the settings, the tuning, its
    effect and the paired wins."""
    out = []
    if not ident.empty:
        has = any(h in ident.columns for h in ct.IDENTIFIABILITY.values())
        out.append(("Identifiability of every scenario" + ("" if has else
                    " (the rows carry no identifiability figures: only the best VAF of k)"), ident))
    readings = _readings(g.table, g.primary)
    if not readings.empty:
        out.append(("Who ranks first, counted over the ranked scenarios", readings))
    main = _main_metric(g.table)
    for (metric, tuning), board in g.board.groupby(["metric", "tuning"], sort=False):
        if metric == main:
            out.append((f"Leaderboard on {METRICS[metric][0]} ({tuning} column; every metric on the interactive "
                        "page and in the exports)", lb.display(board)))
    st = ct.settings_table(g.rows)
    out.append(("Settings of every method" if not st.empty else
                "Settings of every method: the rows carry no settings column (a run before settings "
                "were recorded)", st))
    tt = ct.tuning_table(g.rows)
    if not tt.empty:
        out.append(("Tuning: candidates tried on the tuning realizations (never scored), chosen by held-out "
                    "output VAF", tt))
    te = pairs_.tuning_effect(g.rows, g.table)
    if not te.empty:
        out.append(("Tuned against paper settings, per method: paired over the same realizations of each ranked "
                    "scenario (signed-rank, Holm over the methods of a scenario)", te))
    for tuning in g.tunings:
        for metric in ("vaf_stiffness", "error_rms"):
            w = pairs_.wins(g.pairs, metric, tuning)
            if not w.empty:
                out.append((f"Paired wins on {METRICS[metric][0]} ({tuning}): row against column, 'w/a/n' = "
                            "significantly better in w, median paired difference ahead in a, of n ranked "
                            "scenarios", w))
    return out


def _scenario_tables(g: _Grid, ident: pd.DataFrame) -> list[tuple[str, pd.DataFrame]]:
    """One table per scenario (an infeasible one says so, with its identifiability figures), then the
    combinations skipped or not fitted and those the grid's design leaves out."""
    out = []
    figures = ident.set_index(["scenario", "backend"]) if not ident.empty else None
    for cell, df, note in ct.scenario_tables(g.table, g.primary):
        status = "ranked"
        if cell not in g.ranked:
            status = "infeasible: not ranked"
            if figures is not None and (cell, g.primary) in figures.index:
                f = figures.loc[(cell, g.primary)]
                shown = [f"{h} {f[h]:.3g}" for h in ct.IDENTIFIABILITY.values() if h in f and pd.notna(f[h])]
                status += ("; " + ", ".join(shown)) if shown else ""
        n_m = df["method"].nunique()
        title = f"{cell} ({g.primary}; {status}; {n_m} methods): value [90 % interval] #rank"
        out.append((title + (f". {note}" if note else ""), df))
    why = ct.reasons(g.rows)
    if not why.empty:
        out.append(("Combinations skipped or not fitted, and why", why))
    design = ct.design_skips(g.rows)
    if not design.empty:
        out.append(("Combinations left out by the grid's design (not failures)", design))
    return out


def _figures(g: _Grid, folder) -> tuple[list[tuple[str, str]], dict, dict, dict]:
    """The figures of each tuning column (heat map, trade-off, k_hat(t)) with their captions, the curves
    of the interactive page: ``{(scenario, backend, tuning): curves}`` and the methods in their order, and
    the heat maps by tuning column ``{tuning: (file, caption)}`` (the page's overview)."""
    out, sets, order, heat = [], {}, {}, {}
    vector = " and ".join(f.upper() for f in plots.VECTOR_FORMATS)
    for tuning in g.tunings:
        sfx = _suffix(tuning, g.tunings)
        f = plots.heat_map(g.table, g.rows, g.primary, tuning, g.feas, folder, f"{g.name}_heatmap{sfx}.png")
        if f:
            cap = (f"Methods x scenarios ({tuning} column, {g.primary}): median VAF of k (%), diverging at 0 % (blue: "
                   f"better than a constant at the true mean), colour clipped at {plots.VAF_FLOOR:.0f} %, every cell "
                   "printed")
            out.append((f, f"{cap}; also as {vector}"))
            heat[tuning] = (folder / f, cap)
        f, lines = plots.trade_off(g.table, g.primary, tuning, folder, f"{g.name}_tradeoff{sfx}.png", g.styles)
        if f:
            out.append((f, f"Rise time against random error, square-wave scenarios ({tuning} column): bars "
                           "are the 90 % intervals, each method in its colour and marker (as in every figure); "
                           "methods with an infinite rise time hollow at the dotted right edge"
                           + (": " + "; ".join(lines) if lines else "") + f"; also as {vector}"))
        s = plots.curve_sets(g.curves, g.primary, tuning)
        f = plots.khat_figure(s, g.table, g.primary, tuning, folder, f"{g.name}_khat{sfx}.png", g.styles)
        if f:
            out.append((f, f"k_hat(t) against the truth ({tuning} column, {g.primary}): mean over realizations "
                           f"of the {plots.CURVES_PER_PANEL} methods with the highest median VAF of k per "
                           f"scenario, each in its colour and marker (as in every figure and on the page; one legend "
                           f"below), the truth in black over them (band: 5th-95th percentile over realizations of "
                           f"the best {plots.BANDS}, where stored; the axis spans the truth's range with a margin); "
                           f"more methods on the interactive page; also as {vector}"))
        for cell, d in s.items():
            sets[(cell, g.primary, tuning)] = d
            order[(cell, g.primary, tuning)] = plots.best_methods(g.table, cell, g.primary, tuning,
                                                                  len(d["methods"]))
    return out, sets, order, heat


def _write_page(g: _Grid, text: list[str], tables: list, sets: dict, order: dict, heat: dict, folder,
                cd_figures: dict | None = None, summary: pd.DataFrame | None = None) -> None:
    """The interactive page ``<part>_comparison.html``: the introduction (links as plain text), the overview
    (leaderboards, heat maps and, given ``cd_figures`` ((metric, tuning) -> file) or ``summary``, the summary
    over scenarios: :func:`page.summary_over_scenarios`), the curves, the tables but the per-scenario ones (the
    page filters the full table by scenario)."""
    rows = g.rows
    study = str(rows["study"].dropna().iloc[0]) if "study" in rows and rows["study"].notna().any() else ""
    title = f"Method comparison: {study + ', part ' if study else 'part '}{g.name}"
    intro = [re.sub(r"\[([^\]]+)\]\([^)]+\)", r"\1", p) for p in text[:2]]
    static = [(t, df) for t, df in tables if not t.startswith((*g.cells, "Leaderboard on"))]   # in the overview
    main = _main_metric(g.table)
    overview = cp.Overview(boards=cp.board_tables(g.board), heatmaps=heat, styles=g.styles,
                           summary=cp.summary_over_scenarios(cd_figures, summary), note=_board_text(g),
                           default_metric=main)
    write_text(folder / g.page_name, cp.render(title, intro, cp.page_data(g.table, sets, order, g.styles), static,
                                               overview, notes=[DEFINITIONS, text[3], text[4]]))


def _main_metric(table: pd.DataFrame) -> str:
    """The metric the text's wins and the page's overview lead with: the RMS error of k when the rows have it."""
    return "error_rms" if (table["metric"] == "error_rms").any() else "vaf_stiffness"


@register("compare")
def compare_figures(part, rows, curves, folder, checks) -> PartReport:
    """Tables, figures and the page of a comparison grid part (module docstring)."""
    g = _grid(part, rows, curves, folder)
    text = _text(g)
    ident = ct.identifiability(g.rows, g.table)
    colours = {m: st.color for m, st in g.styles.items()}
    summary = csum.report_parts(g.name, g.table, g.rows, g.pairs, g.primary, folder, colours=colours)
    rep = PartReport(text="\n\n".join(text + summary.text), title=_title(g))
    rep.tables = _method_tables(g, ident) + summary.tables + _scenario_tables(g, ident)
    rep.figures, sets, order, heat = _figures(g, folder)
    rep.figures += summary.figures
    cd = {(m, t): Path(folder) / f"{g.name}_cd_{m}_{t}.png"
          for m, t in zip(summary.tests.get("metric", []), summary.tests.get("tuning", []))}
    _write_page(g, text, rep.tables, sets, order, heat, folder, cd_figures={k: f for k, f in cd.items() if f.exists()},
                summary=summary.tables[0][1] if summary.tables else None)
    return rep


def _suffix(tuning: str, tunings: list[str]) -> str:
    """File-name suffix of a tuning column's figures (none for the first: the file names of old runs)."""
    return "" if tuning == tunings[0] else f"_{tuning}"
