"""The interactive comparison page in headless Chromium: the full table sorts and filters, every k_hat(t)
plot renders; and the page is one file that loads nothing. Skipped when no Chromium can be had."""
from __future__ import annotations

import html as htmllib
import json
import re
import types

import pandas as pd
import pytest

from jointbench.benchmarks.compare import figures as compare
from tests.test_comparison_report import synthetic_rows
from tests.test_nightly import _browser, chromium  # noqa: F401  (the project's Chromium fixture)


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    rows, curves = synthetic_rows(R=6)
    folder = tmp_path_factory.mktemp("matrix")
    compare.compare_figures(types.SimpleNamespace(name="matrix"), rows, curves, folder, None)
    return folder / "matrix_comparison.html", pd.read_csv(folder / "matrix_scores.csv")


def _data(text: str) -> dict:
    blob = re.search(r'<script type="application/json" id="data">(.*?)</script>', text, re.S)[1]
    return json.loads(blob.replace("<\\/", "</"))


def test_page_is_one_file_that_loads_nothing(page):
    path, table = page
    text = path.read_text()
    assert not re.search(r"""(src|href)=["']?(https?:)?//""", text), "the page must not load anything"
    assert "<script src" not in text and "<link" not in text
    d = _data(text)
    assert len(d["rows"]) == len(table)                       # the full table, every row
    assert {p["cell"] for p in d["plots"]} == set(table[table["backend"] == "analytic"]["cell"])


def _values(dom: str, column: int) -> list[float]:
    """The numbers (``data-v``) of one column of the full table's body, top to bottom."""
    body = dom[dom.index('<table id="full">'):]
    body = body[body.index("<tbody>"):body.index("</tbody>")]
    out = []
    for tr in re.findall(r"<tr>(.*?)</tr>", body, re.S):
        v = re.search(r'data-v="([^"]*)"', re.findall(r"<td([^>]*)>", tr)[column])[1]
        out.append(float(v) if v not in ("", "inf", "-inf") else float(v.replace("", "") or "nan"))
    return out


def test_page_sorts_filters_and_draws_every_plot_in_chromium(page, chromium, tmp_path):  # noqa: F811
    path, table = page
    d = _data(path.read_text())
    col = d["keys"].index("value")
    url = path.as_uri() + "#sort=value&dir=desc&metric=vaf_stiffness&backend=analytic"
    dom = _browser(chromium, tmp_path / "p1", "--virtual-time-budget=10000", "--dump-dom", url)
    assert dom.returncode == 0, dom.stderr
    m = re.search(r'<body[^>]*data-rows="(\d+)"[^>]*data-plots="(\d+)"', dom.stdout)
    assert m, dom.stdout[:500]
    n_rows, n_plots = map(int, m.groups())
    want = table[(table["metric"] == "vaf_stiffness") & (table["backend"] == "analytic")]
    assert n_rows == len(want) > 3
    assert n_plots == len(d["plots"]) > 0                        # every plot has its curves drawn
    values = _values(dom.stdout, col)
    assert len(values) == n_rows and values == sorted(values, reverse=True)
    assert values[0] == pytest.approx(want["value"].max(), rel=1e-3)
    # every plot's SVG has the truth and at least one mean estimate with points in it
    svgs = re.findall(r'<svg[^>]*class="khat"[^>]*>(.*?)</svg>', dom.stdout, re.S)
    assert len(svgs) == len(d["plots"])
    assert all('class="truth"' in s and 'class="mean"' in s and re.search(r'd="M[\d.]', s) for s in svgs)
    # clicking the header sorts: a probe clicks 'value' twice (ascending, then descending) and reports
    probe = tmp_path / "probe.html"
    probe.write_text(path.read_text().replace("</body>", """<script>
      window.addEventListener('load', () => {
        const th = [...document.querySelectorAll('#full thead th')].find(t => t.textContent === 'value');
        const first = () => [...document.querySelectorAll('#full tbody tr')].slice(0, 40)
          .map(tr => tr.children[%d].dataset.v).filter(v => v !== '' && v !== 'inf' && v !== '-inf').map(Number);
        th.click(); const up = first(); th.click(); const down = first();
        const sorted = (a, s) => a.every((v, i) => i === 0 || s * (v - a[i - 1]) >= 0);
        document.title = `probe up ${sorted(up, 1)} down ${sorted(down, -1)} n ${up.length}`;
      });</script></body>""" % col))
    dom = _browser(chromium, tmp_path / "p2", "--virtual-time-budget=10000", "--dump-dom",
                   probe.as_uri() + "#metric=vaf_stiffness")
    m = re.search(r"<title>probe up (\w+) down (\w+) n (\d+)</title>", dom.stdout)
    assert m, htmllib.unescape(dom.stdout[:800])
    assert m[1] == "true" and m[2] == "true" and int(m[3]) > 3
