"""Test helper: the texts of a drawn matplotlib figure must neither overlap nor leave it.

``text_problems(fig)`` draws the figure on its own canvas, records every text matplotlib
actually draws (tick labels in view, axis labels, titles, legend entries, annotations, offset
texts) and returns a line for each pair of them whose boxes overlap and for each one that
reaches outside the figure. Boxes are the renderer's (``Text.get_window_extent`` with the
canvas's renderer), in pixels at the figure's dpi.
"""

from __future__ import annotations

from itertools import combinations
from unittest import mock


def drawn_texts(fig) -> list:
    """The non-empty :class:`matplotlib.text.Text` artists a draw of ``fig`` renders."""
    from matplotlib.text import Text

    drawn: dict[int, Text] = {}
    draw = Text.draw

    def record(self, renderer):
        if self.get_visible() and self.get_text().strip():
            drawn[id(self)] = self
        return draw(self, renderer)

    with mock.patch.object(Text, "draw", record):
        fig.canvas.draw()
    return list(drawn.values())


def text_problems(fig, *, tolerance: float = 0.5) -> list[str]:
    """Overlapping text boxes and texts outside the figure, one line each.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        Laid out as it will be shown (its layout engine, if any, runs in the draw).
    tolerance : float
        Overlap [pixels] that is not counted (anti-aliasing).

    Returns
    -------
    list of str
        Empty when every text stands free and inside the figure.
    """
    texts = drawn_texts(fig)
    renderer = fig.canvas.get_renderer()
    boxes = [(t.get_text().replace("\n", " "), t.get_window_extent(renderer)) for t in texts]
    width, height = fig.canvas.get_width_height()
    out = []
    for name, b in boxes:
        if b.x0 < -tolerance or b.y0 < -tolerance or b.x1 > width + tolerance \
                or b.y1 > height + tolerance:
            out.append(f"{name!r} reaches outside the figure: {b.bounds}")
    for (n1, b1), (n2, b2) in combinations(boxes, 2):
        dx = min(b1.x1, b2.x1) - max(b1.x0, b2.x0)
        dy = min(b1.y1, b2.y1) - max(b1.y0, b2.y0)
        if dx > tolerance and dy > tolerance:
            out.append(f"{n1!r} overlaps {n2!r} ({dx:.1f} x {dy:.1f} px)")
    return out
