"""A method's style in the comparison's figures, the leaderboard and the exports for a paper: one colour and
marker per method, the same in every panel and figure; legends off the data, the truth over the estimates,
vector formats beside the PNG; the leaderboard on a hand-computed case; the booktabs LaTeX and the wide CSV
carry the leaderboard's numbers."""
from __future__ import annotations

import io
import types
import xml.etree.ElementTree as ET

import numpy as np
import pandas as pd
import pytest

from jointbench.benchmarks.compare import export, leaderboard as lb, plots, styles
from jointbench.benchmarks.compare import figures as compare
from tests.test_comparison_report import synthetic_rows


# ------------------------------------------------------------------------------------------ the palette
def _lab(color: str) -> np.ndarray:
    """CIELAB (D65) of an sRGB colour (the CIE formulas), for the distances below."""
    from matplotlib.colors import to_rgb

    c = np.array(to_rgb(color))
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    xyz = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]]) @ lin
    xyz /= [0.95047, 1.0, 1.08883]
    f = np.where(xyz > (6 / 29) ** 3, np.cbrt(xyz), xyz / (3 * (6 / 29) ** 2) + 4 / 29)
    return np.array([116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])])


def test_twenty_methods_get_distinct_legible_styles():
    names = [f"method {k:02d}" for k in range(20)]
    st = styles.method_styles(reversed(names))            # keyed on the name: the order given does not matter
    assert list(st) == names and st == styles.method_styles(names)
    colors = [s.color for s in st.values()]
    assert len(set(colors)) == 20                       # 20 colours, no repeat
    lab = [_lab(c) for c in colors]
    gaps = {n: min(np.linalg.norm(a - b) for i, a in enumerate(lab[:n]) for b in lab[:i]) for n in (16, 20)}
    assert gaps[16] > 20 and gaps[20] > 18            # CIE76 distances: far from "near-identical" (a few units)
    for c in colors:                                    # legible on white, not the truth's black
        assert styles.MIN_CONTRAST <= styles.contrast_with_white(c) <= styles.MAX_CONTRAST
        assert np.linalg.norm(_lab(c) - _lab(styles.TRUTH)) > 15
    assert len({(s.color, s.marker) for s in st.values()}) == 20
    assert len({s.marker for s in list(st.values())[:len(styles.MARKERS)]}) == len(styles.MARKERS)


def test_contrast_with_white_by_hand():
    assert styles.contrast_with_white("#000000") == pytest.approx(21.0)
    assert styles.contrast_with_white("#ffffff") == pytest.approx(1.0)
    assert styles.contrast_with_white("#777777") == pytest.approx(4.48, abs=0.01)   # WCAG's known mid grey


def test_svg_marker_is_matplotlibs_shape():
    assert styles.svg_marker("s") == "M-0.5 0.5L0.5 0.5L0.5 -0.5L-0.5 -0.5Z"      # the square, y down
    assert styles.svg_marker("o").startswith("M0 ") and "C" in styles.svg_marker("o")


# ------------------------------------------------------------------------------------------ the figures
@pytest.fixture(scope="module")
def drawn(tmp_path_factory):
    """The report of the synthetic grid with every matplotlib figure kept open (``save_formats`` wrapped)."""
    figs = {}
    real = plots.save_formats

    def keep(fig, folder, name, dpi=None):
        figs[name] = fig
        fig.canvas.draw()
        return real(fig, folder, name, dpi)

    rows, curves = synthetic_rows(R=6)
    folder = tmp_path_factory.mktemp("matrix")
    mp = pytest.MonkeyPatch()
    mp.setattr(plots, "save_formats", keep)
    try:
        rep = compare.compare_figures(types.SimpleNamespace(name="matrix"), rows, curves, folder, None)
    finally:
        mp.undo()
    return rep, folder, figs, pd.read_csv(folder / "matrix_scores.csv")


def _method_artists(fig):
    """(axes, label, colour, marker, zorder) of every labelled line of every panel."""
    from matplotlib.colors import to_hex

    for ax in fig.axes:
        for line in ax.get_lines():
            if not line.get_label().startswith("_"):
                yield ax, line.get_label(), to_hex(line.get_color()), line.get_marker(), line.get_zorder()


def test_a_method_is_drawn_alike_in_every_panel_and_figure(drawn):
    rep, folder, figs, table = drawn
    st = styles.method_styles(table["method"])
    seen = {}
    khat = [n for n in figs if "_khat" in n]
    assert len(khat) == 2                                    # paper and tuned columns
    for name in khat:
        for ax, label, color, marker, _ in _method_artists(figs[name]):
            if label == "truth":
                assert color == styles.TRUTH
                continue
            assert (color, marker) == (st[label].color, st[label].marker), (name, label)
            seen.setdefault(label, set()).add((name, ax.get_title()))
    assert len(seen) >= 2 and max(len(v) for v in seen.values()) >= 4     # a method in several panels, both columns
    from matplotlib.colors import to_hex

    for name in [n for n in figs if "_tradeoff" in n]:       # the trade-off's points: the same styles
        for ax in figs[name].axes:
            for line in ax.get_lines():
                if line.get_marker() not in ("None", None, "", "|", "_"):       # not the error bars' caps
                    c = to_hex(line.get_color())
                    assert (c, line.get_marker()) in {(s.color, s.marker) for s in st.values()}


def test_legends_are_off_the_data_and_the_truth_is_on_top(drawn):
    rep, folder, figs, table = drawn
    for name in [n for n in figs if "_khat" in n or "_tradeoff" in n]:
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        fig = figs[name]
        canvas = FigureCanvasAgg(fig)
        canvas.draw()
        renderer = canvas.get_renderer()
        assert all(ax.get_legend() is None for ax in fig.axes), name          # no legend inside a panel
        assert len(fig.legends) == 1
        box = fig.legends[0].get_window_extent(renderer)
        panels = [ax.get_window_extent(renderer) for ax in fig.axes if ax.axison]
        assert all(not box.overlaps(p) for p in panels), name
        if "_khat" in name:
            labels = {label for ax, label, *_ in _method_artists(fig)}
            legend = {t.get_text() for t in fig.legends[0].get_texts()}
            assert legend == labels                                            # every line drawn, once
            for ax in fig.axes:
                lines = [(label, z) for a, label, _, _, z in _method_artists(fig) if a is ax]
                if lines:
                    truth = [z for label, z in lines if label == "truth"]
                    assert truth and truth[0] > max(z for label, z in lines if label != "truth")


def test_every_figure_also_as_svg_and_pdf(drawn):
    rep, folder, figs, table = drawn
    for f, caption in rep.figures:
        stem = folder / f.rsplit(".", 1)[0]
        svg = stem.with_suffix(".svg").read_bytes()
        assert ET.parse(io.BytesIO(svg)).getroot().tag.endswith("svg") and b"<dc:date>" not in svg
        assert stem.with_suffix(".pdf").read_bytes().startswith(b"%PDF")
        assert "also as SVG and PDF" in caption
    png = folder / "matrix_khat.png"
    import matplotlib.image as mpimg

    h, w = mpimg.imread(png).shape[:2]
    assert h > 250 and w > 600                          # the synthetic grid's 3 panels in a row, with the legend


# ------------------------------------------------------------------------------------------ the leaderboard
def _table(values: dict[str, dict[str, float]], metric: str = "error_rms") -> pd.DataFrame:
    """A full table with ``values[cell][method]`` on the primary backend, ranked as the full table ranks."""
    from jointbench.benchmarks.compare import stats as cs

    recs = []
    for cell, by in values.items():
        r = cs.ranks(np.array(list(by.values()), float), "min" if metric != "vaf_stiffness" else "max")
        for (m, v), k in zip(by.items(), r):
            recs.append({"cell": cell, "backend": "analytic", "method": m, "tuning": "paper", "metric": metric,
                         "value": v, "rank": k, "ranked": int(np.isfinite(r).sum())})
    return pd.DataFrame(recs)


def test_leaderboard_by_hand():
    # s1: A 1 < B 2 < C 4; s2: B 1 < A 3 = C 3 (a tie); s3: A 2 < B 8 (C not ranked there)
    t = _table({"s1": {"A": 1.0, "B": 2.0, "C": 4.0}, "s2": {"A": 3.0, "B": 1.0, "C": 3.0},
                "s3": {"A": 2.0, "B": 8.0}})
    b = lb.leaderboard(t, "analytic").set_index("method")
    # A: ahead of 2/2 in s1, 0/2 in s2 (tied with C, behind B), 1/1 in s3 -> mean of 100, 0, 100
    assert b.loc["A", "ahead_pct"] == pytest.approx(200 / 3) and b.loc["A", "first"] == 2
    # B: 1/2, 2/2, 0/1 -> mean of 50, 100, 0; C: 0/2, 0/2 over its 2 scenarios
    assert b.loc["B", "ahead_pct"] == pytest.approx(50.0) and b.loc["B", "first"] == 1
    assert b.loc["C", "ahead_pct"] == 0.0 and (b.loc["C", "scenarios"], b.loc["C", "of"]) == (2, 3)
    assert list(b.index) == ["A", "B", "C"] and b["position"].tolist() == [1, 2, 3]
    # the gap: value / best per scenario, median: A 1, 3, 1 -> 1; B 2, 1, 4 -> 2; C 4, 3 -> 3.5
    assert b["gap"].tolist() == pytest.approx([1.0, 2.0, 3.5])
    assert list(lb.partial(b.reset_index())["method"]) == ["C"]
    # a VAF: points behind the best
    v = lb.leaderboard(_table({"s1": {"A": 90.0, "B": 70.0}}, "vaf_stiffness"), "analytic").set_index("method")
    assert v.loc["B", "gap"] == pytest.approx(20.0) and v.loc["A", "ahead_pct"] == 100.0


def test_exports_carry_the_leaderboards_numbers(tmp_path):
    t = pd.concat([_table({"s1": {"A": 1.0, "B_x": 2.0, "C": 4.0}, "s2": {"A": 3.0, "B_x": 1.0, "C": 3.0}}),
                   _table({"s1": {"A": 1.0, "B_x": 2.0, "C": 4.0}}).assign(tuning="tuned")])
    board = lb.leaderboard(t, "analytic")
    files = export.write_summary(board, t, "analytic", tmp_path, "m")
    assert files == ["m_summary_wide.csv", "m_summary.tex", "m_values_wide.csv"]
    wide = pd.read_csv(tmp_path / "m_summary_wide.csv").set_index("method")
    for r in board.itertuples():
        assert wide.loc[r.method, f"{r.metric} | {r.tuning} | ahead of others (%)"] == pytest.approx(r.ahead_pct)
        assert wide.loc[r.method, f"{r.metric} | {r.tuning} | first in"] == r.first
    tex = (tmp_path / "m_summary.tex").read_text()
    assert tex.count("\\toprule") == tex.count("\\midrule") == tex.count("\\bottomrule") == 2     # two columns
    assert "|" not in tex.split("\\begin{tabular}")[1].split("}")[0]                            # no vertical rules
    assert "B\\_x" in tex and "\\label{tab:m-leaderboard-paper}" in tex
    # A in the paper column: ahead of 2/2 in s1 and 0/2 in s2 (tied with C, behind B) -> 50 %, first once;
    # in the tuned column (s1 only): 100 %
    paper, tuned = tex.split("\\end{table}")[:2]
    assert "A & 50 (1)" in paper and "A & 100 (1)" in tuned
    values = pd.read_csv(tmp_path / "m_values_wide.csv")
    assert values.set_index(["tuning", "method"]).loc[("paper", "C"), "error_rms | s2"] == 3.0
