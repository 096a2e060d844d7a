"""The report model (benchmarks/harness/pages.py): one page rendered to markdown and to HTML, and the
study report written from it (report.md and a self-contained report.html)."""
from __future__ import annotations

import re
from html.parser import HTMLParser
from pathlib import Path

import pandas as pd
import pytest

from jointbench.benchmarks import report
from jointbench.benchmarks.config import load_study
from jointbench.benchmarks.figures import PartReport
from jointbench.benchmarks.harness.pages import (Code, Figure, Items, Page, Paragraph, Section, inline_html,
                                                 markdown_table, table, to_html, to_markdown)
from jointbench.benchmarks.checks import judge

PNG = bytes.fromhex("89504e470d0a1a0a0000000d4948445200000001000000010806000000"
                    "1f15c4890000000d49444154789c6360f8cfc0f01f0005000201e5276a4a0000000049454e44ae426082")


class _Text(HTMLParser):
    """Visible text, headings and images of an HTML page."""

    def __init__(self):
        super().__init__()
        self.text, self.headings, self.imgs, self.links, self._h = [], [], [], [], None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "img":
            self.imgs.append(a.get("src", ""))
        if tag == "a":
            self.links.append(a.get("href", ""))
        if re.fullmatch(r"h[1-6]", tag):
            self._h = [int(tag[1]), ""]

    def handle_endtag(self, tag):
        if self._h is not None and tag == f"h{self._h[0]}":
            self.headings.append(tuple(self._h))
            self._h = None

    def handle_data(self, data):
        self.text.append(data)
        if self._h is not None:
            self._h[1] += data


def parse(html: str) -> _Text:
    p = _Text()
    p.feed(html)
    return p


def test_inline_markdown_becomes_escaped_html():
    html = str(inline_html("**W1** (`K_a`, _reading R2_): <script>x</script> & [report](../a/report.html); "
                           "snake_case_names and 2*3*4 stay"))
    assert html.startswith("<strong>W1</strong> (<code>K_a</code>, <em>reading R2</em>): "
                           "&lt;script&gt;x&lt;/script&gt; &amp; <a href=\"../a/report.html\">report</a>;")
    assert html.endswith("snake_case_names and 2*3*4 stay")
    assert str(inline_html("`<b>`")) == "<code>&lt;b&gt;</code>"


def test_one_page_gives_the_same_content_in_markdown_and_html(tmp_path):
    fig = tmp_path / "study" / "f.png"
    fig.parent.mkdir()
    fig.write_bytes(PNG)
    df = pd.DataFrame({"check": ["A|B", "C"], "value": [1.234567, float("nan")], "status": ["pass", "**MISS**"]})
    page = Page("Title & more", banner="**WARNING: dirty.** Commit `x`.", banner_cls="dirty", body=[
        Paragraph("Intro with `code`."),
        Section("Checks", anchor="checks", body=[
            Paragraph("_Why._"),
            table("", df, classes=lambda r: {"status": "pass" if r["status"] == "pass" else "miss"}),
            Items(["**A** one", "two"]),
            Section("Inner", body=[Figure("a caption", path=fig), Figure("in memory", png=PNG)])]),
        Section("Reproduce", body=[Code("jointbench run x")])])
    md = to_markdown(page, tmp_path / "study")
    assert md.splitlines()[:4] == ["# Title & more", "", "> **WARNING: dirty.** Commit `x`.", ""]
    assert "## Checks\n\n_Why._\n\n| check | value | status |\n|---|---|---|\n| A\\|B | 1.235 | pass |\n" \
           "| C |  | **MISS** |\n\n- **A** one\n- two\n\n### Inner\n\n![a caption](f.png)\n\n_a caption_\n\n" \
           "_in memory_\n" in md
    assert md.endswith("## Reproduce\n\n```\njointbench run x\n```\n")
    # linked relative to another folder (the nightly's)
    assert "![a caption](../study/f.png)" in to_markdown(page, tmp_path / "nightly")
    html = to_html(page)
    doc = parse(html)
    assert [h for h in doc.headings] == [(1, "Title & more"), (2, "Checks"), (3, "Inner"), (2, "Reproduce")]
    assert len(doc.imgs) == 2 and all(s.startswith("data:image/png;base64,") for s in doc.imgs)
    assert '<td class="miss"><strong>MISS</strong></td>' in html and "<code>jointbench run x</code>" in html
    assert '<div class="banner dirty"><strong>WARNING: dirty.</strong> Commit <code>x</code>.</div>' in html
    assert not re.search(r"""(src|href)=["']?(https?:)?//""", html)


def test_markdown_table_is_the_pages_table():
    df = pd.DataFrame({"a": [1, 2], "b | c": ["x", "y\nz"]})
    assert markdown_table(df) == "| a | b \\| c |\n|---|---|\n| 1 | x |\n| 2 | y z |\n"
    assert markdown_table(df.iloc[0:0]) == "_(no rows)_\n"


def _meta(folder: Path, **kw) -> dict:
    return {"commit": "abc1234", "command": "jointbench run westwick2012", "n_cases": 2, "n_cached": 0,
            "wall_s": 1.0, "workers": 1, "parts": ["fig2", "fig3"], "from_cache": [], "folder": folder, **kw}


def test_study_report_is_one_page_written_as_markdown_and_self_contained_html(tmp_path):
    s = load_study("westwick2012")
    (tmp_path / "fig2.png").write_bytes(PNG)
    comp = judge(s.checks, pd.DataFrame(columns=["part", "status", "metric", "value"]), {"fig2", "fig3"}, "abc1234")
    parts = {"fig2": PartReport(figures=[("fig2.png", "Fig. 2 caption")], text="Text one.\n\nText two.",
                                tables=[("A table", pd.DataFrame({"x": [1.5]}))]),
             "fig3": "ValueError: broken plot"}
    page = report.page(s, comp, parts, [], _meta(tmp_path))
    md_path, html_path = report.write(tmp_path, page)
    md, html = md_path.read_text(), html_path.read_text()
    assert md == report.render(s, comp, parts, [], _meta(tmp_path))
    # every heading of the markdown is a heading of the HTML page, at the same level
    md_heads = [(len(m[1]), m[2]) for m in re.finditer(r"^(#+) (.*)$", md, re.M)]
    doc = parse(html)
    assert [(lvl, re.sub(r"[`*_]", "", t)) for lvl, t in md_heads] == doc.headings
    assert "![Fig. 2 caption](fig2.png)" in md and len(doc.imgs) == 1 and doc.imgs[0].startswith("data:image/png")
    assert "Text one.\n\nText two." in md and "Figures could not be drawn: ValueError: broken plot" in md
    text = " ".join(doc.text)
    for must in ("Reproduction: 0 of", "Why the bands are what they are", "Misses and their likely reasons",
                 "Not reproduced", "Interpretation", "A table", "jointbench run westwick2012"):
        assert must in md.replace("*", "") and must in text, must
    assert not re.search(r"""(src|href)=["']?(https?:)?//""", html)
    assert all(h.startswith("#") for h in doc.links)     # the page links only to its own sections


def test_the_report_says_dirty_in_both_formats(tmp_path):
    s = load_study("westwick2012")
    page = report.page(s, pd.DataFrame(), {}, [], _meta(tmp_path, commit="abc1234-dirty", parts=list(s.parts)))
    assert to_markdown(page).splitlines()[2].startswith("> **WARNING: generated from an uncommitted tree")
    assert '<div class="banner dirty"><strong>WARNING: generated from an uncommitted tree' in to_html(page)


def test_committed_reports_have_their_html_twin():
    """Every committed report.md that has a report.html beside it: same commit, same figures (inline)."""
    root = Path(__file__).resolve().parents[1] / "results"
    pairs = [(f, f.with_suffix(".html")) for f in sorted(root.glob("**/report.md")) if f.with_suffix(".html").is_file()]
    if not pairs:
        pytest.skip("the committed results predate report.html: `make reproduce` regenerates them")
    for md_path, html_path in pairs:
        md, html = md_path.read_text(), html_path.read_text()
        commit = re.search(r"at commit `([^`]+)`", md)[1]
        assert f"at commit <code>{commit}</code>" in html, html_path
        assert len(parse(html).imgs) == md.count("![") and "data:image/png;base64," in html, html_path
