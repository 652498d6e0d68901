"""A classified frame's picture, in one place: the colour image with each sticker found
and its id, the 8 segments, where the missing stickers would be (hidden by cloth, or
unknown and why), the objects over the napkin, the corners that can be grasped, the folds
seen with their sizes, and the verdict (what ``dgli classify --overlay``, ``dgli watch
--overlays``, ``dgli plan --overlay`` and the reports' galleries draw).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from .report import _outlined_text

if TYPE_CHECKING:
    from ..classifier.pipeline import FrameResult
    from ..core.frame import RGBDFrame

__all__ = [
    "OverlayEvidence",
    "frame_overlay",
    "overlay_evidence",
    "overlay_image",
    "verdict_line",
]


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


def overlay_evidence(result: FrameResult) -> OverlayEvidence | None:
    """What an overlay shows of a classified frame's missing stickers and objects: each
    missing sticker hidden (by cloth) or unknown (with its reason), the objects over the
    napkin (None when the frame kept no sticker evidence).

    Parameters
    ----------
    result : FrameResult
        :func:`~dgli_vision.classifier.pipeline.classify_frame`'s result.
    """
    from ..perception.evidence import HIDDEN

    obs = result.observation
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


def verdict_line(result: FrameResult) -> str:
    """One readable line for a classified frame (``dgli classify``'s answer, and the
    overlay's caption)."""
    p = result.prediction
    if p is None:
        return f"no class: {result.reason}"
    text = f"{p.class_id} {p.name}"
    if p.variant:
        text += f" ({p.variant})"
    text += f", distance {p.distance:.3f}, confidence {p.confidence:.2f}"
    if p.runner_up:
        ru = p.runner_up
        text += f"; runner-up {ru.class_id} {ru.name}" + (f" ({ru.variant})" if ru.variant else "")
        text += f" {ru.distance:.3f}"
    return text


def frame_overlay(frame: RGBDFrame, result: FrameResult) -> NDArray[np.uint8]:
    """The overlay picture of a classified frame (BGR, ready to write): the stickers
    found, where the missing ones would be (hidden or unknown, and why), the objects over
    the napkin, the corners and folds (:mod:`dgli_vision.planning.overlay`), the
    verdict. ``frame`` is the frame as the pipeline read it
    (:meth:`~dgli_vision.classifier.pipeline.FrameResult.frame_as_read`: un-mirrored for a
    camera declared mirrored), whose pixels the result's are."""
    from ..planning.overlay import draw_corners, draw_folds

    obs = result.observation
    evidence = overlay_evidence(result)
    detail = f"{int(obs.visible.sum())}/16 stickers found"
    image = overlay_image(
        frame.color, result.detections.centroids, verdict_line(result), detail=detail,
        evidence=evidence,
    )
    return draw_folds(draw_corners(image, result.affordances), result.affordances,
                      frame.intrinsics)
