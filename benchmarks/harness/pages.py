"""The report model: a page of sections holding paragraphs, lists, code, tables and figures in order,
rendered by Jinja2 templates to HTML and to markdown.

Every report of the harness is one of these pages: the study report (``results/<study>/report.md`` and
``report.html``, :mod:`benchmarks.report`), the nightly report and its history page
(:mod:`benchmarks.harness.nightly_pages`), and the README's status tables (:func:`markdown_table`).

Every text in the model is *inline markdown*: ``**bold**``, ``_italic_``, ```code``` and
``[text](relative link)``. The markdown template writes it as it is; the HTML template escapes it
(autoescape) and turns those marks into tags (:func:`inline_html`), so no markup is assembled by hand.
The HTML is static and self-contained: styles in the page, figures as ``data:`` URIs, no script and no
network. In markdown a figure stored in a file is linked relative to the page's folder.
"""
from __future__ import annotations

import base64
import dataclasses
import json
import math
import os
import re
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pandas as pd

TEMPLATES = Path(__file__).with_name("templates")


@dataclasses.dataclass
class Paragraph:
    text: str
    cls: str = ""            # css class: note, empty
    kind: ClassVar[str] = "paragraph"


@dataclasses.dataclass
class Items:
    """A bullet list."""

    items: list[str]
    kind: ClassVar[str] = "items"


@dataclasses.dataclass
class Code:
    text: str
    kind: ClassVar[str] = "code"


@dataclasses.dataclass
class Cell:
    text: str
    cls: str = ""            # css class: pass, miss, bad, good, num, warn


@dataclasses.dataclass
class Table:
    title: str
    columns: list[str]
    rows: list[list[Cell]]
    note: str = ""
    empty: str = "none"
    kind: ClassVar[str] = "table"


@dataclasses.dataclass
class Figure:
    """A PNG figure: its bytes (``png``) or a file (``path``, linked from markdown, inlined in HTML)."""

    caption: str
    png: bytes | None = None
    path: Path | None = None
    kind: ClassVar[str] = "figure"

    def data(self) -> bytes | None:
        if self.png is not None:
            return self.png
        if self.path is not None and Path(self.path).is_file():
            return Path(self.path).read_bytes()
        return None

    @property
    def data_uri(self) -> str:
        """The figure as a ``data:`` URI; empty when its file is missing."""
        png = self.data()
        return "" if png is None else "data:image/png;base64," + base64.b64encode(png).decode("ascii")


@dataclasses.dataclass
class Section:
    """A titled part of a page; ``body`` holds blocks and sections (one level deeper) in order."""

    title: str
    body: list = dataclasses.field(default_factory=list)
    anchor: str = ""
    cls: str = ""
    collapsed: bool = False                      # <details> in HTML
    kind: ClassVar[str] = "section"

    def add(self, *blocks) -> "Section":
        self.body.extend(b for b in blocks if b is not None)
        return self


@dataclasses.dataclass
class Page:
    title: str
    body: list = dataclasses.field(default_factory=list)   # blocks and sections, in order
    banner: str = ""
    banner_cls: str = ""                          # regression, ok, baseline, dirty
    facts: list[tuple[str, str]] = dataclasses.field(default_factory=list)
    links: list[tuple[str, str]] = dataclasses.field(default_factory=list)
    footer: str = ""


def paragraphs(text: str) -> list[Paragraph]:
    """A text with blank lines between its paragraphs, as paragraphs."""
    return [Paragraph(p.strip()) for p in re.split(r"\n\s*\n", text or "") if p.strip()]


def fmt(v: Any, spec: str = ".4g") -> str:
    """A cell's text: numbers by ``spec``, NaN and None as empty."""
    if v is None:
        return ""
    if isinstance(v, (float, np.floating)):
        return "" if math.isnan(v) else format(float(v), spec)
    if isinstance(v, (np.integer,)):
        return str(int(v))
    return str(v)


def table(title: str, df: pd.DataFrame, columns: dict[str, str] | None = None, classes=None,
          note: str = "", empty: str = "none") -> Table:
    """A :class:`Table` from a frame. ``columns`` maps column -> header (and picks them); ``classes``
    maps a row (a dict) to {column: css class}."""
    columns = columns or {c: c for c in df.columns}
    rows = []
    for rec in df.to_dict("records"):
        css = classes(rec) if classes else {}
        rows.append([Cell(fmt(rec.get(c)), css.get(c, "num" if isinstance(rec.get(c), (int, float, np.number))
                                            and not isinstance(rec.get(c), bool) else ""))
                     for c in columns])
    return Table(title, [str(c) for c in columns.values()], rows, note, empty)


def figure_png(fig, dpi: int = 100) -> bytes:
    """``fig`` as PNG bytes cropped to what is drawn (:func:`jointbench.benchmarks.harness.png.tight_png`),
    and closed."""
    import matplotlib.pyplot as plt

    from jointbench.benchmarks.harness.png import tight_png

    try:
        return tight_png(fig, dpi)
    finally:
        plt.close(fig)


# ------------------------------------------------------------------------------------------ rendering
_INLINE = re.compile(r"`(?P<code>[^`]+)`"
                     r"|\*\*(?P<strong>.+?)\*\*"
                     r"|(?<![\w\\])_(?P<em>[^\s_](?:.*?[^\s\\])?)_(?!\w)"
                     r"|\[(?P<text>[^\]]+)\]\((?P<href>[^)\s]+)\)")


#: the schemes a page's link may have (a relative link has none): never ``javascript:``, ``data:``, ``vbscript:``
SAFE_SCHEMES = frozenset({"http", "https", "mailto"})
#: a URL's scheme, as a browser reads it (after dropping ASCII whitespace and control characters)
_SCHEME = re.compile(r"([A-Za-z][A-Za-z0-9+.\-]*):")


def safe_href(href: Any) -> str | None:
    """``href`` when a page may link to it: relative (no scheme) or of a :data:`SAFE_SCHEMES` scheme; ``None``
    otherwise (``javascript:alert(1)``, ``JaVa\tScript:...``, ``data:...``). Every link of every page passes
    here (:func:`inline_html`, the ``href`` filter of the templates)."""
    text = str(href).strip()
    m = _SCHEME.match(re.sub(r"[\x00-\x20\x7f]", "", text))
    return text if m is None or m.group(1).lower() in SAFE_SCHEMES else None


def script_json(data: Any):
    """``data`` as JSON that is safe inside an HTML ``<script>`` block: ``<``, ``>``, ``&``, U+2028 and U+2029
    written as ``\\u`` escapes, so that no text (``</script>``, ``<!--<script``, ``]]>``) can end or
    re-open the block; a NaN or an infinity is an error (JSON has none). The one writer of a page's
    embedded data."""
    from markupsafe import Markup

    text = json.dumps(data, separators=(",", ":"), allow_nan=False)
    for ch, code in (("&", "\\u0026"), ("<", "\\u003c"), (">", "\\u003e"), ("\u2028", "\\u2028"),
                     ("\u2029", "\\u2029")):
        text = text.replace(ch, code)
    return Markup(text)


def inline_html(text: Any):
    """Inline markdown as escaped HTML: code, strong, emphasis and links (only to :func:`safe_href` targets:
    any other link is its text); everything else is text."""
    from markupsafe import Markup, escape

    text = str(text)
    out, pos = [], 0
    for m in _INLINE.finditer(text):
        out.append(escape(text[pos:m.start()]))
        if m["code"] is not None:
            out.append(Markup("<code>%s</code>") % m["code"])
        elif m["strong"] is not None:
            out.append(Markup("<strong>%s</strong>") % inline_html(m["strong"]))
        elif m["em"] is not None:
            out.append(Markup("<em>%s</em>") % inline_html(m["em"]))
        elif safe_href(m["href"]) is None:
            out.append(inline_html(m["text"]))
        else:
            out.append(Markup('<a href="%s">%s</a>') % (safe_href(m["href"]), inline_html(m["text"])))
        pos = m.end()
    out.append(escape(text[pos:]))
    return Markup("").join(out)


def md_cell(text: Any) -> str:
    """A table cell (or header) in markdown: one line, ``|`` escaped."""
    return str(text).replace("|", "\\|").replace("\n", " ")


def template_env():
    """A Jinja2 environment of the report templates (:data:`TEMPLATES`), with the ``md`` and ``md_cell``
    filters; a page or table gets one of its own."""
    import jinja2

    env = jinja2.Environment(loader=jinja2.FileSystemLoader(str(TEMPLATES)),
                             autoescape=jinja2.select_autoescape(enabled_extensions=("html.j2",),
                                                                 default_for_string=False),
                             undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True,
                             keep_trailing_newline=True)
    env.filters["md"] = inline_html
    env.filters["md_cell"] = md_cell
    env.filters["href"] = lambda href: safe_href(href) or "#"
    return env


def to_html(page: Page, template: str = "page.html.j2") -> str:
    """The page as one static HTML file (figures inline)."""
    return template_env().get_template(template).render(page=page)


def _figure_links(page: Page, base: Path | None) -> dict[int, str]:
    """Markdown link of every figure stored in a file: relative to ``base`` (the page's folder)."""
    links = {}

    def walk(body):
        for b in body:
            if isinstance(b, Section):
                walk(b.body)
            elif isinstance(b, Figure) and b.path is not None:
                p = Path(b.path)
                links[id(b)] = (os.path.relpath(p, base) if base is not None and p.is_absolute()
                                else p.name).replace(os.sep, "/")
    walk(page.body)
    return links


def to_markdown(page: Page, base: Path | None = None) -> str:
    """The same page as markdown; figure files are linked relative to ``base`` (the page's folder)."""
    links = _figure_links(page, base)
    text = template_env().get_template("page.md.j2").render(page=page, link=lambda f: links.get(id(f), ""))
    return re.sub(r"\n{3,}", "\n\n", text).rstrip("\n") + "\n"


def markdown_table(df: pd.DataFrame, empty: str = "no rows") -> str:
    """A frame as a markdown table (the template's own table: the one markdown table of the project)."""
    module = template_env().get_template("macros.md.j2").module
    return str(module.render_table(table("", df, empty=empty))).strip("\n") + "\n"
