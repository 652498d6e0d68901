"""Report writers: Markdown tables and the charts as images (arrays; io writes them). A
classified frame's overlay is drawn by :mod:`dgli_vision.analysis.overlay`.

The charts (heatmaps, confusion, timelines) are drawn by Matplotlib in
:mod:`dgli_vision.analysis.charts`; the functions here give some of them as BGR arrays.
"""

from __future__ import annotations

from collections.abc import Sequence

from numpy.typing import NDArray

__all__ = [
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

