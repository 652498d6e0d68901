"""Report writers: Markdown tables and the charts as images (arrays; io writes them). A
classified frame's overlay is drawn by :mod:`dgli_vision.analysis.overlay`.

The charts (heatmaps, confusion, timeline) are drawn by Matplotlib in
:mod:`dgli_vision.analysis.charts`; the functions here give them as BGR arrays.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "confusion_image",
    "heatmap_image",
    "markdown_table",
]


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """A GitHub-flavoured Markdown table (pipes in cells are escaped)."""

    def cell(v: object) -> str:
        text = f"{v:.4g}" if isinstance(v, float) else str(v)
        return text.replace("|", "\\|")

    lines = ["| " + " | ".join(cell(h) for h in header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def heatmap_image(
    matrix: NDArray[np.float64],
    *,
    title: str,
    groups: Sequence[str] | None = None,
    value_label: str = "",
    ticks: Sequence[object] | None = None,
    tick_label: str = "frame",
) -> NDArray[np.uint8]:
    """A matrix as a BGR heatmap image with title, axes, group labels and colour bar
    (:func:`~dgli_vision.analysis.charts.heatmap_figure`, drawn by Matplotlib).

    Parameters
    ----------
    matrix : ndarray, shape (n, k)
        Values; NaN is drawn grey.
    title : str, keyword-only
    groups : sequence of str, optional, keyword-only
        Label of every row (and column, for square matrices), consecutive runs forming
        groups: drawn as separators and centred labels (e.g. class ids).
    value_label : str, keyword-only
        What the colour means, shown by the colour bar.
    ticks : sequence, optional, keyword-only
        What every column is (e.g. its frame number): about ten of them are marked on a
        tick axis under the matrix, named ``tick_label``.
    tick_label : str, keyword-only

    Returns
    -------
    ndarray of uint8, shape (h, w, 3)
    """
    from .charts import figure_bgr, heatmap_figure

    return figure_bgr(heatmap_figure(matrix, title=title, groups=groups,
                                     value_label=value_label, ticks=ticks,
                                     tick_label=tick_label))


def _text(img: NDArray, text: str, org: tuple[int, int], scale: float = 0.5) -> None:
    import cv2

    cv2.putText(img, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale, (20, 20, 20), 1, cv2.LINE_AA)


def _label_width(labels: Sequence[str], scale: float) -> int:
    """Pixels the widest of ``labels`` takes at ``scale`` (the left margin that shows
    every class name whole)."""
    import cv2

    return max(
        (cv2.getTextSize(t, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)[0][0] for t in labels), default=0
    )


def _outlined_text(
    img: NDArray, text: str, org: tuple[int, int], scale: float, weight: int
) -> None:
    """White text with a black outline, readable on any background."""
    import cv2

    font = cv2.FONT_HERSHEY_SIMPLEX
    # the outline: the same text shifted a pixel each way (a thicker stroke would also
    # advance each letter further, and the outline would run past the text)
    for dx, dy in ((-1, -1), (-1, 1), (1, -1), (1, 1), (-2, 0), (2, 0), (0, -2), (0, 2)):
        cv2.putText(img, text, (org[0] + dx, org[1] + dy), font, scale, (0, 0, 0), weight,
                    cv2.LINE_AA)
    cv2.putText(img, text, org, font, scale, (255, 255, 255), weight, cv2.LINE_AA)


def confusion_image(
    confusion: NDArray,
    labels: Sequence[str],
    *,
    names: dict[str, str] | None = None,
    title: str = "",
) -> NDArray[np.uint8]:
    """Two confusion-matrix panels, counts and row-normalised, as one BGR image
    (:func:`~dgli_vision.analysis.charts.confusion_figure`, drawn by Matplotlib).

    Parameters
    ----------
    confusion : array, shape (k, k + 1)
        Rows true class, columns predicted class, the last column "none".
    labels : sequence of str
        The k class ids.
    names : dict, optional, keyword-only
        Class id -> name, shown on the row axis.
    title : str, keyword-only
    """
    from .charts import confusion_figure, figure_bgr

    return figure_bgr(confusion_figure(confusion, labels, names=names, title=title))


def timeline_image(
    classes: Sequence[str],
    smoothed: Sequence[str],
    raw: Sequence[str | None],
    *,
    truth: Sequence[str] | None = None,
    names: dict[str, str] | None = None,
    title: str = "",
) -> NDArray[np.uint8]:
    """A state timeline as a BGR image: frames across, states down (drawn with OpenCV;
    the reports' charts use :func:`~dgli_vision.analysis.charts.timeline_figure`).

    ``dgli label`` draws each episode's timeline with this: no Matplotlib in its loop,
    where a stop signal interrupts the work wherever it is (a Matplotlib figure's
    weak-reference callbacks would print the interruption as an ignored exception).

    The true state (when given) is a pale band, each frame's own verdict a dot (a
    hollow ring where it gave none), the smoothed state a line.

    Parameters
    ----------
    classes : sequence of str
        The rows, top to bottom (class ids).
    smoothed : sequence of str
        Smoothed class of every frame.
    raw : sequence of str or None
        Each frame's own class (None: no answer).
    truth : sequence of str, optional, keyword-only
    names : dict, optional, keyword-only
        Class id -> name for the row labels.
    title : str, keyword-only
    """
    import cv2

    n = len(smoothed)
    row_of = {c: k for k, c in enumerate(classes)}
    cell_w = max(4, min(24, 1000 // max(n, 1)))
    row_h = 26
    row_names = [f"{c} {names.get(c, '')}" if names else c for c in classes]
    left, top, bottom = max(50, _label_width(row_names, 0.42) + 16), 50, 50
    legend = "line: smoothed   dot: frame's own verdict   ring: none"
    if truth is not None:
        legend += "   green: true state"
    w = left + max(cell_w * n, _label_width([legend, title], 0.6)) + 20
    h = top + row_h * len(classes) + bottom
    img = np.full((h, w, 3), 255, np.uint8)

    def y_of(c: str) -> int:
        return top + row_of[c] * row_h + row_h // 2

    for k in range(len(classes)):
        y = top + k * row_h
        cv2.line(img, (left, y), (w - 20, y), (235, 235, 235), 1)
        _text(img, row_names[k], (6, y + row_h // 2 + 5), 0.42)
    if truth is not None:
        for t, c in enumerate(truth):
            if c in row_of:
                x0, y0 = left + t * cell_w, top + row_of[c] * row_h
                img[y0 + 3 : y0 + row_h - 2, x0 : x0 + cell_w] = (200, 230, 200)
    pts = [
        (left + t * cell_w + cell_w // 2, y_of(c)) for t, c in enumerate(smoothed) if c in row_of
    ]
    for a, b in itertools.pairwise(pts):
        cv2.line(img, a, b, (200, 90, 30), 2, cv2.LINE_AA)
    for t, c in enumerate(raw):
        x = left + t * cell_w + cell_w // 2
        if c is None:
            cv2.circle(img, (x, y_of(smoothed[t])), max(2, cell_w // 4), (60, 60, 200), 1)
        elif c in row_of:
            cv2.circle(img, (x, y_of(c)), max(2, cell_w // 4), (20, 20, 20), -1, cv2.LINE_AA)
    for t in range(0, n, max(1, n // 10)):
        _text(img, str(t), (left + t * cell_w, h - bottom + 20), 0.4)
    _text(img, "frame", (left + cell_w * n // 2 - 20, h - 10), 0.45)
    _text(img, title, (left, 22), 0.6)
    _text(img, legend, (left, 42), 0.4)
    return img
