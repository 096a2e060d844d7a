"""The comparison page's overview in headless Chromium: it opens on the leaderboard of the main metric and the
heat map, switches by metric and tuning column, shows the summary over scenarios and its critical-difference
diagram when the run has them (nothing when not); and a method has one colour on the whole page (every
k_hat(t) panel, its legend, the leaderboards), the colour of the static figures. Skipped when no Chromium can
be had (tests/test_nightly.py's fixture)."""
from __future__ import annotations

import json
import re
import types

import pandas as pd
import pytest

from jointbench.benchmarks.compare import figures as compare
from jointbench.benchmarks.compare import leaderboard as lb
from jointbench.benchmarks.compare import page as cp
from jointbench.benchmarks.compare.styles import method_styles
from tests.test_comparison_report import synthetic_rows
from tests.test_nightly import _browser, chromium  # noqa: F401  (the project's Chromium fixture)


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    """The synthetic grid with 'slow' made the best on VAF of k in one scenario (wrist / sine), so the plots
    list the methods in different orders: a colour that followed the order would change between panels."""
    rows, curves = synthetic_rows(R=6)
    best = (rows["estimator"] == "slow") & (rows["scenario"] == "wrist") & (rows["variation"] == "sine") \
        & (rows["metric"] == "vaf_stiffness")
    rows.loc[best, "value"] += 30.0
    folder = tmp_path_factory.mktemp("matrix")
    compare.compare_figures(types.SimpleNamespace(name="matrix"), rows, curves, folder, None)
    return folder / "matrix_comparison.html", pd.read_csv(folder / "matrix_scores.csv")


def _data(text: str) -> dict:
    blob = re.search(r'<script type="application/json" id="data">(.*?)</script>', text, re.S)[1]
    return json.loads(blob.replace("<\\/", "</"))


def _dom(chromium, profile, url: str) -> str:  # noqa: F811
    r = _browser(chromium, profile, "--virtual-time-budget=10000", "--dump-dom", url)
    assert r.returncode == 0, r.stderr
    return r.stdout


def _shown(dom: str, tag: str, cls: str) -> list[tuple[str, str]]:
    """(attributes, body) of each ``<tag class="cls" ...>`` the script left visible (no ``hidden``)."""
    found = re.findall(rf'<{tag} class="{cls}"([^>]*)>(.*?)</{tag}>', dom, re.S)
    return [(a, b) for a, b in found if not re.search(r"\shidden(=|\s|$)", a)]


def test_the_page_opens_on_the_overview(page, chromium, tmp_path):  # noqa: F811
    path, table = page
    dom = _dom(chromium, tmp_path / "p1", path.as_uri())
    assert dom.index('id="overview"') < dom.index("The full table")           # the overview comes first
    assert re.search(r'<body[^>]*data-boards="1"', dom)
    board = lb.leaderboard(table, "analytic")
    want = board[(board["metric"] == "error_rms") & (board["tuning"] == "paper")]
    shown = _shown(dom, "div", "board")
    assert len(shown) == 1 and 'data-metric="error_rms"' in shown[0][0] and 'data-tuning="paper"' in shown[0][0]
    methods = re.findall(r'<td class="method"><svg[^>]*data-method="([^"]+)"', shown[0][1])
    assert methods == want["method"].tolist() and len(methods) >= 2          # the leaderboard, best first
    heat = _shown(dom, "figure", "heatmap")
    assert len(heat) == 1 and 'data-tuning="paper"' in heat[0][0] and 'src="data:image/png;base64,' in heat[0][1]
    assert 'class="cd"' in dom                        # the summary over scenarios (Friedman, its diagrams)
    # another metric and column, from the address
    dom = _dom(chromium, tmp_path / "p2", path.as_uri() + "#overview=vaf_stiffness/tuned")
    shown = _shown(dom, "div", "board")
    assert len(shown) == 1 and 'data-metric="vaf_stiffness"' in shown[0][0] and 'data-tuning="tuned"' in shown[0][0]
    assert [a for a, _ in _shown(dom, "figure", "heatmap")] == [' data-tuning="tuned"']
    # and the images decode: a probe writes the count into the title
    probe = tmp_path / "probe.html"
    probe.write_text(path.read_text().replace("</body>", """<script>
      window.addEventListener('load', () => {
        const imgs = [...document.querySelectorAll('.overview img')];
        const ok = imgs.filter(i => i.complete && i.naturalWidth > 100).length;
        document.title = `probe imgs ${ok}/${imgs.length}`;
      });</script></body>"""))
    m = re.search(r"<title>probe imgs (\d+)/(\d+)</title>", _dom(chromium, tmp_path / "p3", probe.as_uri()))
    assert m and int(m[2]) >= 2 and m[1] == m[2]       # the two heat maps and the summary's diagrams, all decoded


def _hex(rgb: str) -> str:
    nums = [int(x) for x in re.findall(r"\d+", rgb)[:3]]
    return "#%02x%02x%02x" % tuple(nums)


def test_a_methods_colour_is_the_same_in_every_panel(page, chromium, tmp_path):  # noqa: F811
    path, table = page
    d = _data(path.read_text())
    orders = {tuple(m["name"] for m in p["methods"]) for p in d["plots"]}
    assert len(orders) > 1                      # the plots order the methods differently (so rank != colour)
    dom = _dom(chromium, tmp_path / "p1", path.as_uri())
    colours: dict[str, set] = {}
    panels: dict[str, int] = {}
    for svg in re.findall(r'<svg[^>]*class="khat"[^>]*>(.*?)</svg>', dom, re.S):
        for name, body in re.findall(r'<g data-method="([^"]+)">(.*?)</g>', svg, re.S):
            mean = re.search(r'<path[^>]*stroke="([^"]+)"[^>]*class="mean"', body)
            colours.setdefault(name, set()).add(mean[1].lower())
            marks = re.findall(r'<path[^>]*fill="([^"]+)"[^>]*class="mark"', body)
            assert marks, name                                      # its marker along the line
            colours[name] |= {c.lower() for c in marks}
            panels[name] = panels.get(name, 0) + 1
    legend = [a for a in re.findall(r"<span ([^>]*)>", dom) if "data-method=" in a]
    for attrs in legend:
        name, style = re.search(r'data-method="([^"]+)"', attrs)[1], re.search(r"color: ([^;]+);", attrs)[1]
        colours.setdefault(name, set()).add(_hex(style))
    swatches = re.findall(r'<svg class="swatch"[^>]*data-method="([^"]+)"><line[^>]*stroke="([^"]+)"', dom)
    for name, stroke in swatches:
        colours.setdefault(name, set()).add(stroke.lower())
    assert len(legend) == sum(panels.values()) and len(swatches) >= len(panels)
    styles = method_styles(table["method"])        # what the static figures use (tests/test_comparison_styles.py)
    assert max(panels.values()) >= 4 and set(panels) <= set(styles)
    for name, seen in colours.items():
        assert seen == {styles[name].color}, (name, seen)
    assert len({styles[n].color for n in colours}) == len(colours)           # and no two methods share one
    assert {m: s["color"] for m, s in d["styles"].items()} == {m: s.color for m, s in styles.items()}


def test_the_summary_slot_shows_the_diagram_and_table_when_given(page, chromium, tmp_path):  # noqa: F811
    path, table = page
    assert cp.summary_over_scenarios(None, None) is None
    assert cp.summary_over_scenarios({("error_rms", "paper"): tmp_path / "missing.png"}, None) is None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figs = {}
    for key in (("error_rms", "paper"), ("error_rms", "tuned")):
        fig, ax = plt.subplots(figsize=(4, 2))
        ax.plot([0, 1], [0, 1])
        figs[key] = tmp_path / f"cd_{key[1]}.png"
        fig.savefig(figs[key])
        plt.close(fig)
    summary = pd.DataFrame({"metric": ["error_rms"], "tuning": ["paper"], "friedman p": [0.001]})
    board = lb.leaderboard(table, "analytic")
    ov = cp.Overview(boards=cp.board_tables(board), heatmaps={}, styles=method_styles(table["method"]),
                     summary=cp.summary_over_scenarios(figs, summary, "Summary over scenarios (test)"),
                     note="", default_metric="error_rms")
    html = cp.render("t", ["intro"], cp.page_data(table, {}), [], ov)
    out = tmp_path / "with_summary.html"
    out.write_text(html)
    dom = _dom(chromium, tmp_path / "p1", out.as_uri() + "#overview=error_rms/tuned")
    cd = _shown(dom, "figure", "cd")
    assert len(cd) == 1 and 'data-tuning="tuned"' in cd[0][0] and 'src="data:image/png;base64,' in cd[0][1]
    assert "Summary over scenarios (test)" in dom and "friedman p" in dom
