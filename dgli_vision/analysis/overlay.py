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
    "folded_over",
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


#: BGR colours of the overlay: the segments, a sticker hidden by cloth, one unknown.
SEGMENT = (255, 0, 255)
HIDDEN = (160, 160, 160)
UNKNOWN = (0, 140, 255)


def _draw_segments(img: NDArray, pts: NDArray, scale: float) -> None:
    """The 8 segments as arrows (sticker 2i to 2i + 1; the legend says so: the stickers'
    own ids name them, so they carry no label of their own)."""
    import cv2

    for i in range(len(pts) // 2):
        a, b = pts[2 * i], pts[2 * i + 1]
        if not (np.isfinite(a).all() and np.isfinite(b).all()):
            continue
        pa, pb = tuple(int(round(v)) for v in a), tuple(int(round(v)) for v in b)
        cv2.arrowedLine(
            img, pa, pb, SEGMENT, max(1, int(2 * scale)), cv2.LINE_AA, tipLength=0.2
        )


def _legend(img: NDArray, entries: list[str], scale: float) -> None:
    """A legend in the bottom-left corner, on a dark panel: one line per mark drawn."""
    import cv2

    marks = {
        "sticker": "sticker found (its id)",
        "segment": "segment: sticker 2i to 2i + 1",
        "hidden": "hidden by cloth (where it lies)",
        "unknown": "unknown (reason above)",
        "object": "object over the napkin",
        "graspable": "corner that can be grasped",
        "not graspable": "corner that cannot",
        "fold": "fold line (sizes in mm)",
    }
    shown = [k for k in marks if k in entries]
    if not shown:
        return
    font, fs, row = cv2.FONT_HERSHEY_SIMPLEX, 0.5 * scale, int(22 * scale)
    width = max(cv2.getTextSize(marks[k], font, fs, 1)[0][0] for k in shown) + int(44 * scale)
    h, w = img.shape[:2]
    x0, y0 = int(10 * scale), h - int(10 * scale) - row * len(shown) - int(8 * scale)
    panel = img[y0 : h - int(10 * scale), x0 : min(w, x0 + width)]
    panel[:] = (panel * 0.35).astype(np.uint8)  # darkened: the marks and text stand out
    for k, key in enumerate(shown):
        cy = y0 + int(8 * scale) + row * k + row // 2
        cx = x0 + int(16 * scale)
        r, t = int(6 * scale), max(1, int(2 * scale))
        if key == "sticker":
            cv2.circle(img, (cx, cy), int(4 * scale), (255, 255, 255), -1, cv2.LINE_AA)
        elif key == "segment":
            cv2.arrowedLine(img, (cx - r, cy), (cx + r, cy), SEGMENT, t, cv2.LINE_AA,
                            tipLength=0.4)
        elif key in ("hidden", "unknown"):
            colour = HIDDEN if key == "hidden" else UNKNOWN
            cv2.circle(img, (cx, cy), r, colour, t, cv2.LINE_AA)
        elif key == "object":
            cv2.rectangle(img, (cx - r, cy - r), (cx + r, cy + r), (0, 0, 255), t)
        elif key == "graspable":
            cv2.circle(img, (cx, cy), r, (60, 200, 60), t, cv2.LINE_AA)
        elif key == "not graspable":
            cv2.line(img, (cx - r, cy - r), (cx + r, cy + r), (150, 150, 150), t, cv2.LINE_AA)
            cv2.line(img, (cx - r, cy + r), (cx + r, cy - r), (150, 150, 150), t, cv2.LINE_AA)
        else:  # the fold line: white dashes on a dark rim, as drawn
            for a, b in ((cx - r, cx - 2), (cx + 2, cx + r)):
                cv2.line(img, (a, cy), (b, cy), (0, 0, 0), t + 3, cv2.LINE_AA)
                cv2.line(img, (a, cy), (b, cy), (255, 255, 255), t, cv2.LINE_AA)
        cv2.putText(img, marks[key], (cx + int(16 * scale), cy + int(5 * scale)), font, fs,
                    (255, 255, 255), 1, cv2.LINE_AA)


def _draw_missing(img: NDArray, evidence: OverlayEvidence, scale: float) -> list[str]:
    """Hollow circles where the missing stickers lie (grey: hidden by cloth; orange:
    unknown), and the caption lines that name the unknown ones' reasons."""
    import cv2

    why: dict[str, list[int]] = {}
    for k, p in enumerate(np.asarray(evidence.predicted_px, dtype=np.float64)):
        reason = evidence.reasons[k] if k < len(evidence.reasons) else None
        if reason:
            why.setdefault(reason, []).append(k)
        if not (np.isfinite(p).all() and (evidence.hidden[k] or reason)):
            continue
        c = tuple(int(round(v)) for v in p)
        colour = HIDDEN if evidence.hidden[k] else UNKNOWN
        cv2.circle(img, c, int(9 * scale), colour, max(1, int(2 * scale)), cv2.LINE_AA)
        _outlined_text(img, f"{k}?", (c[0] + 10, c[1] - 8), 0.5 * scale, 1)
    return [
        f"unknown {', '.join(map(str, ids))}: {reason}" for reason, ids in why.items()
    ]


def _marks(evidence: OverlayEvidence | None, pts: NDArray) -> list[str]:
    """The legend's entries for what an overlay draws."""
    found = np.isfinite(pts).all(axis=1)
    marks = ["sticker"] if found.any() else []
    if (found[0::2] & found[1::2]).any():
        marks.append("segment")
    if evidence is not None:
        shown = np.isfinite(np.asarray(evidence.predicted_px, dtype=float)).all(axis=1)
        if (shown & np.asarray(evidence.hidden, dtype=bool)).any():
            marks.append("hidden")
        if any(r for r, s in zip(evidence.reasons, shown) if s):
            marks.append("unknown")
        if evidence.objects is not None and evidence.objects.any():
            marks.append("object")
    return marks


def folded_over(
    predicted_px: NDArray[np.float64],
    hidden: NDArray[np.bool_],
    found_px: NDArray[np.float64],
    fold_lines_px: list[NDArray[np.float64]],
) -> NDArray[np.float64]:
    """Where the hidden stickers lie: ``predicted_px`` is where each would be on the flat
    napkin; one beyond a fold line (on the other side from the stickers found) is on a
    flap turned over that line, so it lies at its mirror image across the line (on the
    cloth, face down), not off the napkin's edge.

    Parameters
    ----------
    predicted_px : ndarray, shape (16, 2)
    hidden : ndarray of bool, shape (16,)
    found_px : ndarray, shape (16, 2)
        The stickers found (NaN where not).
    fold_lines_px : list of ndarray, shape (2, 2)
        The folds seen, as two pixels each.

    Returns
    -------
    ndarray, shape (16, 2)
        ``predicted_px`` with each hidden sticker beyond a fold mirrored across the
        nearest such fold line.
    """
    out = np.array(predicted_px, dtype=np.float64, copy=True)
    seen = found_px[np.isfinite(found_px).all(axis=1)]
    if not len(seen):
        return out
    for k in np.flatnonzero(np.asarray(hidden, dtype=bool) & np.isfinite(out).all(axis=1)):
        best = None
        for line in fold_lines_px:
            a, b = np.asarray(line, dtype=np.float64)
            d = b - a
            n = np.array([-d[1], d[0]]) / max(float(np.hypot(*d)), 1e-9)
            side = float((out[k] - a) @ n)
            cloth = float(np.median((seen - a) @ n))
            if side * cloth < 0 and (best is None or abs(side) < abs(best[0])):
                best = (side, n)
        if best is not None:
            out[k] = out[k] - 2 * best[0] * best[1]
    return out


def overlay_image(
    color_rgb: NDArray[np.uint8],
    centroids: NDArray[np.float64],
    verdict: str,
    *,
    detail: str = "",
    evidence: OverlayEvidence | None = None,
    extra_marks: tuple[str, ...] = (),
    show_legend: bool = True,
) -> NDArray[np.uint8]:
    """The colour image with each detected sticker's id, the 8 segments and the verdict,
    and a legend of the marks drawn (bottom left).

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
    extra_marks : tuple of str, keyword-only
        More legend entries for what the caller draws on top (``"graspable"``, ``"not
        graspable"``, ``"fold"``).
    show_legend : bool, keyword-only
        Draw the legend.

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
    marks = _marks(evidence, pts) + list(extra_marks)
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
    if show_legend:
        _legend(img, marks, scale)
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


def frame_overlay(
    frame: RGBDFrame, result: FrameResult, *, legend: bool = True
) -> NDArray[np.uint8]:
    """The overlay picture of a classified frame (BGR, ready to write): the stickers
    found, where the missing ones lie (hidden by cloth, on the flap folded over, or
    unknown and why), the objects over the napkin, the corners and folds
    (:mod:`dgli_vision.planning.overlay`), the verdict and (``legend``) a legend of the
    marks, bottom left (a plan's overlay draws its own there). ``frame`` is the frame as
    the pipeline read it
    (:meth:`~dgli_vision.classifier.pipeline.FrameResult.frame_as_read`: un-mirrored for a
    camera declared mirrored), whose pixels the result's are."""
    from dataclasses import replace

    from ..planning.overlay import draw_corners, draw_folds

    obs = result.observation
    evidence = overlay_evidence(result)
    lines = _fold_lines_px(result.affordances, frame.intrinsics)
    if evidence is not None:
        evidence = replace(evidence, predicted_px=folded_over(
            evidence.predicted_px, evidence.hidden, result.detections.centroids, lines))
    detail = f"{int(obs.visible.sum())}/16 stickers found"
    extra = _corner_marks(result.affordances) + (("fold",) if lines else ())
    image = overlay_image(
        frame.color, result.detections.centroids, verdict_line(result), detail=detail,
        evidence=evidence, extra_marks=extra, show_legend=legend,
    )
    return draw_folds(draw_corners(image, result.affordances), result.affordances,
                      frame.intrinsics)


def _fold_lines_px(affordances: object, intrinsics: object) -> list[NDArray[np.float64]]:
    """The folds seen, each as its two pixels (those in front of the camera)."""
    lines = []
    for f in getattr(affordances, "folds", ()) or ():
        if f.line is None:
            continue
        ends = np.asarray(f.line, dtype=float)
        if np.all(ends[:, 2] > 0):
            lines.append(intrinsics.project(ends))
    return lines


def _corner_marks(affordances: object) -> tuple[str, ...]:
    """The legend entries of the corners drawn."""
    corners = getattr(affordances, "corners", None) or {}
    marks = []
    if any(c.pixel is not None and c.graspable for c in corners.values()):
        marks.append("graspable")
    if any(c.pixel is not None and not c.graspable for c in corners.values()):
        marks.append("not graspable")
    return tuple(marks)
