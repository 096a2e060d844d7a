"""One style per method of a comparison: the colour and marker a method has in every figure, every panel and
on the interactive page (:mod:`jointbench.benchmarks.compare.plots`, :mod:`jointbench.benchmarks.compare.page`).

The styles are keyed on the method's name: :func:`method_styles` gives each name of a comparison its own
colour and marker, in the order of the sorted names, so a method keeps them across panels, tuning columns,
figures and the page (and across runs with the same methods). The colours are Glasbey's maximally distinct
categorical colours (colorcet's ``glasbey_dark``, made for a white background), of which only those that
stand out from a white background by WCAG's 3:1 for graphics, and not so dark that they read as the truth's
black, are kept; the marker is a second, colour-independent cue (:data:`MARKERS`) for readers and prints
that cannot tell two colours apart.

References
----------
Glasbey, van der Heijden, Toh & Gray, "Colour displays for categorical images", Color Research and
Application 32(4), 304-309, 2007 (the palette: each colour as far as possible, in CIELAB, from those before it).
Kovesi, "Good colour maps: how to design them", arXiv:1509.03700, 2015 (colorcet).
W3C, Web Content Accessibility Guidelines 2.1, success criterion 1.4.11 "Non-text contrast" and the definitions
of relative luminance and contrast ratio (the 3:1 rule).
"""
from __future__ import annotations

import dataclasses
from functools import lru_cache
from typing import Iterable

#: matplotlib marker codes, cycled independently of the colours (13 shapes: a method's (colour, marker) pair is
#: unique for any number of methods below the product of the two cycles)
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "p", "h", "*", "d")
#: contrast ratio against white a method's colour must reach (WCAG 2.1 SC 1.4.11, graphics)
MIN_CONTRAST = 3.0
#: above this contrast against white a colour is too dark: it reads as the truth's black, and dark colours are
#: hard to tell apart as thin lines (10: relative luminance 0.055, CIELAB lightness about 28; black: 21)
MAX_CONTRAST = 10.0
#: the colour of the truth in every figure and on the page
TRUTH = "#000000"


@dataclasses.dataclass(frozen=True)
class MethodStyle:
    """How one method is drawn: ``color`` ('#rrggbb'), ``marker`` (matplotlib's code) and ``svg_marker`` (the
    same marker as an SVG path of unit size centred at 0, y pointing down: the page draws it)."""

    color: str
    marker: str
    svg_marker: str

    def as_dict(self) -> dict:
        return {"color": self.color, "marker": self.marker, "path": self.svg_marker}


def contrast_with_white(color: str) -> float:
    """WCAG 2.1 contrast ratio of ``color`` against white: (1 + 0.05) / (L + 0.05), L the relative luminance
    (sRGB channels linearized, weighted 0.2126, 0.7152, 0.0722)."""
    from matplotlib.colors import to_rgb

    lin = [c / 12.92 if c <= 0.03928 else ((c + 0.055) / 1.055) ** 2.4 for c in to_rgb(color)]
    lum = 0.2126 * lin[0] + 0.7152 * lin[1] + 0.0722 * lin[2]
    return 1.05 / (lum + 0.05)


@lru_cache(maxsize=1)
def palette() -> tuple[str, ...]:
    """The method colours in order: colorcet's ``glasbey_dark`` less the colours whose contrast with white is
    below :data:`MIN_CONTRAST` or above :data:`MAX_CONTRAST`."""
    import colorcet

    return tuple(c for c in colorcet.glasbey_dark if MIN_CONTRAST <= contrast_with_white(c) <= MAX_CONTRAST)


@lru_cache(maxsize=None)
def svg_marker(marker: str) -> str:
    """matplotlib's ``marker`` as an SVG path ('M x y L ... Z', unit size, y down), from matplotlib's own path
    of the marker, so the page draws the shapes of the figures."""
    from matplotlib.markers import MarkerStyle
    from matplotlib.path import Path

    m = MarkerStyle(marker)
    path = m.get_path().transformed(m.get_transform())
    out = []
    for pts, code in path.iter_segments(simplify=False, curves=True):
        xy = [f"{v:.3g}" for v in (pts.reshape(-1, 2) * [1, -1]).ravel()]
        if code == Path.MOVETO:
            out.append("M" + " ".join(xy))
        elif code == Path.LINETO:
            out.append("L" + " ".join(xy))
        elif code == Path.CURVE3:
            out.append("Q" + " ".join(xy))
        elif code == Path.CURVE4:
            out.append("C" + " ".join(xy))
        elif code == Path.CLOSEPOLY:
            out.append("Z")
    return "".join(out)


def method_styles(methods: Iterable[str]) -> dict[str, MethodStyle]:
    """Each distinct method name its style: the k-th name in sorted order gets colour k and marker k of
    :func:`palette` and :data:`MARKERS` (each cycled). Give it every method of the comparison (not those of
    one panel) and every figure and panel drawn with the result shows a method alike."""
    names = sorted({str(m) for m in methods if m is not None and str(m) != ""})
    colors = palette()
    return {m: MethodStyle(colors[k % len(colors)], MARKERS[k % len(MARKERS)], svg_marker(MARKERS[k % len(MARKERS)]))
            for k, m in enumerate(names)}
