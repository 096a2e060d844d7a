"""A figure as a PNG cropped to its drawn content, drawn once.

``savefig(bbox_inches="tight")`` draws a figure twice: once with rendering switched off to find the
extent of what is drawn (text layout, ticks and labels: nearly all of the cost of a draw), then again,
shifted by that extent, for the pixels. The figures of a study run spent half of their time in the first
of those draws (the test suite, sampled: 42 of 96 CPU-s in savefig, issue 22). :func:`tight_png` draws once at
the output's resolution, measures the extent with the same renderer, and cuts it out of the pixels: the
same picture, with the content placed to the nearest whole pixel instead of at the fraction of a pixel
where the second draw would place it; the pad beyond the canvas's edge is the figure's background, as
``savefig`` paints it. A figure with something drawn outside its canvas (a label or legend beyond the
edge) needs the second draw, shifted, to hold it: ``savefig`` makes it with the extent this draw measured
(two draws, as before, and the same bytes as savefig's tight path).

Kept (issue 34 weighed every speed-only mechanism): savefig's tight path instead would change the bytes
of 17 of the paper studies' 23 figures (the content placed at a fraction of a pixel), and the figures are
committed. What it saves a warm study run is small (CPU-s, medians of 3 interleaved runs, savefig's
tight path -> this: vanderuit2018_table1 6.66 -> 6.49, westwick2012 3.54 -> 3.46, xu1998 5.67 -> 5.63,
vanderuit2018_table2 2.66 -> 2.69); the test suite draws many more figures.

References
----------
Matplotlib's ``FigureCanvasBase.print_figure`` (``bbox_inches="tight"``; ``savefig.pad_inches``).
"""
from __future__ import annotations

import io


def tight_png(fig, dpi: float) -> bytes:
    """The PNG of ``fig`` at ``dpi``, cropped to its tight extent padded by ``savefig.pad_inches``, as
    ``fig.savefig(..., format="png", dpi=dpi, bbox_inches="tight")`` writes it (see the module's docstring:
    the content to the nearest whole pixel). Leaves ``fig`` drawn at ``dpi`` (callers close it)."""
    import matplotlib as mpl
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    pad = mpl.rcParams["savefig.pad_inches"]
    if not isinstance(pad, (int, float)):
        return _savefig(fig, dpi)                  # "layout": constrained layout's own pads, savefig's rules
    fig.dpi = dpi
    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    canvas.draw()
    inner = fig.get_tightbbox(canvas.get_renderer())
    width, height = fig.get_size_inches()
    box = inner.padded(pad)
    if inner.x0 < 0 or inner.y0 < 0 or inner.x1 > width or inner.y1 > height:
        return _beyond(fig, dpi, box)              # content beyond the canvas: only a second draw holds it
    pixels = np.asarray(canvas.buffer_rgba())
    rows, cols = pixels.shape[:2]
    # savefig's size (the renderer truncates the extent's pixels) from the nearest whole pixel of its
    # corner (row 0 at the top); the pad beyond the canvas is the figure's background
    width_px, height_px = int(box.width * dpi), int(box.height * dpi)
    left = round(box.x0 * dpi)
    top = round(rows - box.y0 * dpi - height_px)
    right, bottom = left + width_px, top + height_px
    cut = pixels[max(0, top):min(rows, bottom), max(0, left):min(cols, right)]
    margins = ((max(0, -top), max(0, bottom - rows)), (max(0, -left), max(0, right - cols)))
    if any(m for pair in margins for m in pair):
        face = np.round(np.asarray(mpl.colors.to_rgba(fig.get_facecolor())) * 255).astype(np.uint8)
        cut = np.stack([np.pad(cut[..., k], margins, constant_values=face[k]) for k in range(4)], axis=-1)
    buf = io.BytesIO()
    mpl.image.imsave(buf, cut, format="png", origin="upper", dpi=dpi)
    return buf.getvalue()


def _savefig(fig, dpi: float) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    return buf.getvalue()


def _beyond(fig, dpi: float, box) -> bytes:
    """savefig's tight PNG for a figure drawn beyond its canvas, given the extent ``box`` (inches) that the
    draw just made measured: savefig then draws once more (shifted) instead of twice. A placeholder
    layout engine (what ``tight_layout()`` leaves; it lays nothing out) is set aside for that call,
    since savefig draws once more for any engine."""
    import matplotlib as mpl
    from matplotlib.layout_engine import PlaceHolderLayoutEngine

    engine = fig.get_layout_engine()
    placeholder = isinstance(engine, PlaceHolderLayoutEngine) and not (
        mpl.rcParams["figure.autolayout"] or mpl.rcParams["figure.constrained_layout.use"])   # None: no engine
    if placeholder:
        fig.set_layout_engine(None)                # None removes it ("none" would leave a placeholder)
    try:
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi, bbox_inches=box)
        return buf.getvalue()
    finally:
        if placeholder:
            fig.set_layout_engine(engine)
