"""benchmarks.harness.png.tight_png: savefig's tight PNG in one draw (the same picture to the nearest
whole pixel); savefig itself where something is drawn beyond the canvas."""
import io

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from PIL import Image  # noqa: E402

from jointbench.benchmarks.harness.png import tight_png  # noqa: E402

DPI = 110


def _figure(outside: bool = False, edge: bool = False):
    fig, axes = plt.subplots(1, 2, figsize=(6.0, 3.0))
    t = np.linspace(0, 1, 200)
    for k, ax in enumerate(axes):
        ax.plot(t, np.sin(2 * np.pi * (k + 1) * t), label=f"sine {k + 1}")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("angle (rad)")
        ax.set_title(f"panel {k + 1}")
        ax.legend(fontsize=7)
    fig.tight_layout()
    if outside:
        fig.text(-0.05, 0.5, "beyond the left edge", rotation=90, va="center")
    if edge:
        fig.text(0.0, 0.5, "at the edge", rotation=90, va="center", ha="left")
    return fig


def _pixels(data: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB")).astype(float)


def _savefig(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, bbox_inches="tight")
    return buf.getvalue()


def _best_offset_difference(a: np.ndarray, b: np.ndarray) -> float:
    """Mean absolute difference (0-255) of the two pictures at the best of the whole-pixel offsets -1, 0, 1."""
    best = np.inf
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            h = min(a.shape[0], b.shape[0]) - 2
            w = min(a.shape[1], b.shape[1]) - 2
            pa = a[1:1 + h, 1:1 + w]
            pb = b[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
            best = min(best, float(np.abs(pa - pb).mean()))
    return best


@pytest.fixture
def draws(monkeypatch):
    """The figure draws made from the moment it is asked for (a list, one item a draw)."""
    made = []
    real = Figure.draw

    def counting(self, renderer):
        made.append(1)
        return real(self, renderer)
    monkeypatch.setattr(Figure, "draw", counting)
    return made


def test_the_same_picture_as_savefig_in_one_draw(request):
    reference = _pixels(_savefig(_figure()))
    draws = request.getfixturevalue("draws")
    fig = _figure()
    data = tight_png(fig, DPI)
    assert len(draws) == 1                                    # savefig's tight path draws twice
    ours = _pixels(data)
    assert abs(ours.shape[0] - reference.shape[0]) <= 1 and abs(ours.shape[1] - reference.shape[1]) <= 1
    # the content sits to the nearest whole pixel instead of at savefig's fraction of one: at the best
    # whole-pixel alignment, what remains is the anti-aliasing of edges moved by less than a pixel
    # (a few grey levels on average; a missing line or label would cost tens)
    assert _best_offset_difference(ours, reference) < 3.0
    assert Image.open(io.BytesIO(data)).info["dpi"] == pytest.approx((DPI, DPI), abs=0.01)
    plt.close("all")


def test_content_beyond_the_canvas_is_savefigs_picture_in_two_draws(request):
    reference = _savefig(_figure(outside=True))
    draws = request.getfixturevalue("draws")
    assert tight_png(_figure(outside=True), DPI) == reference      # the same bytes
    assert len(draws) == 2                                          # savefig's tight path alone: 2
    plt.close("all")


def test_the_pad_beyond_the_canvas_is_the_background():
    fig = _figure(edge=True)
    ours = _pixels(tight_png(fig, DPI))
    reference = _pixels(_savefig(_figure(edge=True)))
    assert abs(ours.shape[1] - reference.shape[1]) <= 1       # the left pad is there, beyond the canvas
    pad = int(0.1 * DPI) - 2
    assert (ours[:, :pad] == 255).all()                       # white, as savefig paints it
    plt.close("all")
