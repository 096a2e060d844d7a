"""A small report model (page, sections, tables, figures) rendered to HTML by Jinja2 and to markdown.

The HTML is static and self-contained: styles in the page, figures as ``data:`` URIs, no script and no
network. Every text is escaped by the template engine (autoescape), never assembled by hand.
"""
from __future__ import annotations

import base64
import dataclasses
import io
import math
from pathlib import Path
from typing import Any, Iterable

import numpy as np
import pandas as pd

TEMPLATES = Path(__file__).with_name("templates")


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


@dataclasses.dataclass
class Figure:
    caption: str
    png: bytes

    @property
    def data_uri(self) -> str:
        return "data:image/png;base64," + base64.b64encode(self.png).decode("ascii")


@dataclasses.dataclass
class Section:
    title: str
    anchor: str = ""
    paragraphs: list[str] = dataclasses.field(default_factory=list)
    items: list[str] = dataclasses.field(default_factory=list)          # a bullet list
    tables: list[Table] = dataclasses.field(default_factory=list)
    figures: list[Figure] = dataclasses.field(default_factory=list)
    children: list["Section"] = dataclasses.field(default_factory=list)
    cls: str = ""
    collapsed: bool = False                                               # <details> in HTML


@dataclasses.dataclass
class Page:
    title: str
    banner: str = ""
    banner_cls: str = ""
    facts: list[tuple[str, str]] = dataclasses.field(default_factory=list)
    links: list[tuple[str, str]] = dataclasses.field(default_factory=list)
    sections: list[Section] = dataclasses.field(default_factory=list)
    footer: str = ""


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
    return Table(title, list(columns.values()), rows, note, empty)


def figure_png(fig, dpi: int = 100) -> bytes:
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    return buf.getvalue()


def _env():
    import jinja2

    return jinja2.Environment(loader=jinja2.FileSystemLoader(str(TEMPLATES)),
                              autoescape=jinja2.select_autoescape(default=True, default_for_string=True),
                              undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True)


def to_html(page: Page, template: str = "page.html.j2") -> str:
    return _env().get_template(template).render(page=page)


def _md_escape(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _md_table(t: Table) -> list[str]:
    out = [f"**{t.title}**", ""] if t.title else []
    if not t.rows:
        return out + [f"_({t.empty})_", ""]
    out.append("| " + " | ".join(_md_escape(c) for c in t.columns) + " |")
    out.append("|" + "|".join("---" for _ in t.columns) + "|")
    out += ["| " + " | ".join(_md_escape(c.text) for c in row) + " |" for row in t.rows]
    if t.note:
        out += ["", t.note]
    return out + [""]


def _md_section(s: Section, level: int, figures_to: Path | None, stem: str) -> list[str]:
    out = ["#" * level + " " + s.title, ""]
    for p in s.paragraphs:
        out += [p, ""]
    if s.items:
        out += [f"- {i}" for i in s.items] + [""]
    for t in s.tables:
        out += _md_table(t)
    for k, f in enumerate(s.figures):
        if figures_to is not None:
            name = f"{stem}-{s.anchor or 'fig'}-{k}.png"
            (figures_to / name).write_bytes(f.png)
            out += [f"![{f.caption}]({name})", ""]
        out += [f"_{f.caption}_", ""]
    for c in s.children:
        out += _md_section(c, min(level + 1, 6), figures_to, stem)
    return out


def to_markdown(page: Page, figures_to: Path | None = None, stem: str = "figure") -> str:
    """The same page as markdown (figures written beside it when ``figures_to`` is given)."""
    out = [f"# {page.title}", ""]
    if page.banner:
        out += [f"**{page.banner}**", ""]
    if page.facts:
        out += [f"- {k}: {v}" for k, v in page.facts] + [""]
    for s in page.sections:
        out += _md_section(s, 2, figures_to, stem)
    if page.footer:
        out += [page.footer, ""]
    return "\n".join(out)


def cells(values: Iterable[Any]) -> list[Cell]:
    return [Cell(fmt(v)) for v in values]
