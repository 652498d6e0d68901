"""Pictures of affordances and plans: graspable corners, grasp and place points, fold
lines, drawn on an overlay image (BGR)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["draw_corners", "draw_folds", "draw_step", "fold_caption"]

#: BGR colours: a graspable corner (green ring), a corner not graspable (grey cross),
#: the grasp (magenta), the place (cyan) and the fold line (white dashes).
GRASPABLE = (60, 200, 60)
NOT_GRASPABLE = (150, 150, 150)
GRASP = (200, 0, 200)
PLACE = (230, 200, 0)
FOLD = (255, 255, 255)


def _scale(img: NDArray) -> float:
    return max(1.0, img.shape[1] / 1280)


def _px(p: Any) -> tuple[int, int]:
    return int(round(float(p[0]))), int(round(float(p[1])))


def draw_corners(img: NDArray[np.uint8], affordances: Any) -> NDArray[np.uint8]:
    """Mark each corner placed: a green ring and its name where it can be grasped, a
    grey cross where it cannot (``affordances``: an
    :class:`~dgli_vision.classifier.affordances.Affordances`, or None: unchanged)."""
    import cv2

    if affordances is None:
        return img
    s = _scale(img)
    for c in affordances.corners.values():
        if c.pixel is None:
            continue
        u, v = _px(c.pixel)
        if c.graspable:
            cv2.circle(img, (u, v), int(14 * s), GRASPABLE, max(2, int(3 * s)), cv2.LINE_AA)
            cv2.putText(
                img, c.corner, (u + int(16 * s), v - int(10 * s)), cv2.FONT_HERSHEY_SIMPLEX,
                0.7 * s, GRASPABLE, max(2, int(2 * s)), cv2.LINE_AA,
            )
        else:
            r = int(8 * s)
            cv2.line(img, (u - r, v - r), (u + r, v + r), NOT_GRASPABLE, 2, cv2.LINE_AA)
            cv2.line(img, (u - r, v + r), (u + r, v - r), NOT_GRASPABLE, 2, cv2.LINE_AA)
    return img


def fold_caption(fold: Any) -> str:
    """A fold's sizes in a few words: ``"B: AB 178, BC 160 mm"``, ``"CD: inset 132 mm,
    skew 1 deg"``, ``"B: offset 3 mm, turn -1 deg"``; ``"B: ?"`` when not measured."""
    g = fold.geometry
    name = fold.corner or fold.side
    if g is None or g.why is not None:
        return f"{name}: ?"
    v = g.values
    if "legs_mm" in v:
        legs = ", ".join(f"{e} {x:.0f}" for e, x in v["legs_mm"].items() if x is not None)
        return f"{name}: {legs} mm"
    if "inset_mm" in v:
        return f"{name}: inset {v['inset_mm']:.0f} mm, skew {round(v['skew_deg']):d} deg"
    return f"{name}: offset {v['offset_mm']:.0f} mm, turn {round(v['turn_deg']):d} deg"


def draw_folds(img: NDArray[np.uint8], affordances: Any, intrinsics: Any) -> NDArray[np.uint8]:
    """Draw each fold's line on the table (thin white) with its sizes in mm beside its
    middle (:func:`fold_caption`)."""
    import cv2

    if affordances is None:
        return img
    s = _scale(img)
    for f in affordances.folds:
        if f.line is None:
            continue
        ends = np.asarray(f.line, dtype=float)
        if np.any(ends[:, 2] <= 0):
            continue
        a, b = (_px(p) for p in intrinsics.project(ends))
        cv2.line(img, a, b, FOLD, max(1, int(s)), cv2.LINE_AA)
        mid = ((a[0] + b[0]) // 2 + int(6 * s), (a[1] + b[1]) // 2 - int(6 * s))
        text = fold_caption(f)
        width = max(1, int(1.5 * s))
        for dx, dy in ((-1, -1), (1, 1), (-1, 1), (1, -1), (0, 0)):  # a dark rim, then white
            colour = FOLD if dx == dy == 0 else (0, 0, 0)
            cv2.putText(img, text, (mid[0] + dx, mid[1] + dy), cv2.FONT_HERSHEY_SIMPLEX,
                        0.55 * s, colour, width, cv2.LINE_AA)
    return img


def draw_step(
    img: NDArray[np.uint8], step: Any, intrinsics: Any, caption: str = ""
) -> NDArray[np.uint8]:
    """Draw a plan's step: the fold line (dashed), the grasp (magenta disc), the place
    (cyan ring) and an arrow from one to the other, with a caption."""
    import cv2

    s = _scale(img)
    a, b = (intrinsics.project(np.asarray(p, dtype=float)[None])[0] for p in step.fold_line)
    n = 24
    for k in range(0, n, 2):
        p = a + (b - a) * k / n
        q = a + (b - a) * (k + 1) / n
        cv2.line(img, _px(p), _px(q), FOLD, max(2, int(3 * s)), cv2.LINE_AA)
    g = intrinsics.project(np.asarray(step.grasp_point, dtype=float)[None])[0]
    pl = intrinsics.project(np.asarray(step.place_point, dtype=float)[None])[0]
    cv2.arrowedLine(img, _px(g), _px(pl), GRASP, max(2, int(2 * s)), cv2.LINE_AA, tipLength=0.05)
    cv2.circle(img, _px(g), int(10 * s), GRASP, -1, cv2.LINE_AA)
    cv2.circle(img, _px(pl), int(12 * s), PLACE, max(2, int(3 * s)), cv2.LINE_AA)
    if caption:
        y = img.shape[0] - int(16 * s)
        cv2.putText(img, caption, (12, y), cv2.FONT_HERSHEY_SIMPLEX, 0.7 * s, (0, 0, 0),
                    int(5 * s), cv2.LINE_AA)
        cv2.putText(img, caption, (12, y), cv2.FONT_HERSHEY_SIMPLEX, 0.7 * s,
                    (255, 255, 255), max(1, int(2 * s)), cv2.LINE_AA)
    return img
