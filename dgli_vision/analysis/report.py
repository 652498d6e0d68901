"""Report writers: Markdown and CSV tables, overlays, and the charts as images (arrays;
io writes them).

The charts (heatmaps, confusion, timelines) are drawn by Matplotlib in
:mod:`dgli_vision.analysis.charts`; the functions here give some of them as BGR arrays.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "OverlayEvidence",
    "confusion_image",
    "heatmap_image",
    "markdown_table",
    "overlay_evidence",
    "overlay_image",
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


@dataclass(frozen=True)
class OverlayEvidence:
    """What an overlay shows beside the stickers found: where each missing sticker
    would be and why it is missing, and the objects over the napkin.

    Attributes
    ----------
    predicted_px : ndarray, shape (16, 2)
        Where each missing sticker would lie were its part of the cloth like the rest
        (NaN where that is not known).
    hidden : ndarray of bool, shape (16,)
        Missing because cloth lies on it (evidence of a fold).
    reasons : tuple of str or None
        Why each unknown sticker tells nothing (None for the others).
    objects : ndarray of bool, shape (h, w), optional
        Objects above the table, on a grid of ``stride`` pixels.
    stride : int
    """

    predicted_px: NDArray[np.float64]
    hidden: NDArray[np.bool_]
    reasons: tuple[str | None, ...]
    objects: NDArray[np.bool_] | None = None
    stride: int = 8


def overlay_evidence(result: object) -> OverlayEvidence | None:
    """What an overlay shows of a classified frame's missing stickers and objects: each
    missing sticker hidden (by cloth) or unknown (with its reason), the objects over the
    napkin (None when the frame kept no sticker evidence).

    Parameters
    ----------
    result : FrameResult
        :func:`~dgli_vision.classifier.pipeline.classify_frame`'s result.
    """
    from ..perception.evidence import HIDDEN

    obs = result.observation  # type: ignore[attr-defined]
    ev = obs.evidence
    if ev is None:
        return None
    return OverlayEvidence(
        ev.predicted_px,
        np.asarray(ev.status) == HIDDEN,
        tuple(r if u else None for r, u in zip(ev.reasons, ev.unknown)),
        obs.objects,
        obs.objects_stride,
    )


def _wrapped(text: str, width_px: int, scale: float, weight: int) -> list[str]:
    """``text`` cut at spaces into lines no wider than ``width_px``."""
    import cv2

    lines: list[str] = []
    for word in text.split(" "):
        trial = f"{lines[-1]} {word}" if lines else word
        size = cv2.getTextSize(trial, cv2.FONT_HERSHEY_SIMPLEX, scale, weight + 2)[0][0]
        if lines and size <= width_px:
            lines[-1] = trial
        else:
            lines.append(word)
    return lines


def _draw_segments(img: NDArray, pts: NDArray, scale: float) -> None:
    """The 8 segments as arrows, each label set off to the side of its arrow (away from
    the stickers' ids)."""
    import cv2

    for i in range(len(pts) // 2):
        a, b = pts[2 * i], pts[2 * i + 1]
        if not (np.isfinite(a).all() and np.isfinite(b).all()):
            continue
        pa, pb = tuple(int(round(v)) for v in a), tuple(int(round(v)) for v in b)
        cv2.arrowedLine(
            img, pa, pb, (255, 0, 255), max(1, int(2 * scale)), cv2.LINE_AA, tipLength=0.2
        )
        d = (b - a) / max(float(np.hypot(*(b - a))), 1e-9)
        side = np.array([-d[1], d[0]]) * 18 * scale
        mid = (a + b) / 2 + side
        cv2.putText(
            img, f"s{i}", (int(mid[0]) - 8, int(mid[1]) + 5), cv2.FONT_HERSHEY_SIMPLEX,
            0.5 * scale, (255, 0, 255), 1, cv2.LINE_AA,
        )


def _draw_missing(img: NDArray, evidence: OverlayEvidence, scale: float) -> list[str]:
    """Hollow circles where the missing stickers would be (grey: hidden by cloth;
    orange: unknown), and the legend lines that name the unknown ones' reasons."""
    import cv2

    why: dict[str, list[int]] = {}
    for k, p in enumerate(np.asarray(evidence.predicted_px, dtype=np.float64)):
        reason = evidence.reasons[k] if k < len(evidence.reasons) else None
        if reason:
            why.setdefault(reason, []).append(k)
        if not (np.isfinite(p).all() and (evidence.hidden[k] or reason)):
            continue
        c = tuple(int(round(v)) for v in p)
        colour = (160, 160, 160) if evidence.hidden[k] else (0, 140, 255)
        cv2.circle(img, c, int(9 * scale), colour, max(1, int(2 * scale)), cv2.LINE_AA)
        _outlined_text(img, f"{k}?", (c[0] + 10, c[1] - 8), 0.5 * scale, 1)
    return [
        f"unknown {', '.join(map(str, ids))}: {reason}" for reason, ids in why.items()
    ]


def overlay_image(
    color_rgb: NDArray[np.uint8],
    centroids: NDArray[np.float64],
    verdict: str,
    *,
    detail: str = "",
    evidence: OverlayEvidence | None = None,
) -> NDArray[np.uint8]:
    """The colour image with each detected sticker's id, the 8 segments and the verdict.

    Parameters
    ----------
    color_rgb : ndarray of uint8, shape (H, W, 3)
    centroids : ndarray, shape (16, 2)
        Sticker centroids in pixels, NaN where not detected.
    verdict : str
        First line of the caption (wrapped to the image's width).
    detail : str, keyword-only
        Second line of the caption.
    evidence : OverlayEvidence, keyword-only, optional
        Also draw where the missing stickers would be (hidden by cloth, or unknown with
        the reason in the caption) and outline the objects over the napkin (red).

    Returns
    -------
    ndarray of uint8, shape (H, W, 3)
        BGR, ready to write.
    """
    import cv2

    img = cv2.cvtColor(color_rgb, cv2.COLOR_RGB2BGR)
    scale = max(1.0, img.shape[1] / 1280)
    pts = np.asarray(centroids, dtype=np.float64)
    legend: list[str] = []
    if evidence is not None:
        if evidence.objects is not None and evidence.objects.any():
            mask = cv2.resize(
                evidence.objects.astype(np.uint8), (img.shape[1], img.shape[0]),
                interpolation=cv2.INTER_NEAREST,
            )
            contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
            cv2.drawContours(img, contours, -1, (0, 0, 255), max(1, int(2 * scale)))
        legend = _draw_missing(img, evidence, scale)
    _draw_segments(img, pts, scale)
    for k, p in enumerate(pts):
        if np.isfinite(p).all():
            c = tuple(int(round(v)) for v in p)
            cv2.circle(img, c, int(4 * scale), (0, 0, 0), -1, cv2.LINE_AA)
            _outlined_text(img, str(k), (c[0] + 8, c[1] + 16), 0.55 * scale, 1)
    width = img.shape[1] - int(24 * scale)
    big = _wrapped(verdict, width, 0.8 * scale, 2)
    small = [line for t in (detail, *legend) if t for line in _wrapped(t, width, 0.6 * scale, 1)]
    y = 30 * scale
    for text in big:
        _outlined_text(img, text, (12, int(y)), 0.8 * scale, 2)
        y += 28 * scale
    for text in small:
        _outlined_text(img, text, (12, int(y)), 0.6 * scale, 1)
        y += 22 * scale
    return img


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
