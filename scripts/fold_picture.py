"""Draw docs/folds.png: the sizes of a corner fold, a strip and a diagonal fold on the
flat napkin (material coordinates, A at the bottom left as in SPEC section 1).

Usage: .venv/bin/python scripts/fold_picture.py [OUT.png]
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import cv2
import numpy as np

from dgli_vision.core.fold_measure import fold_measures, planned_crease
from dgli_vision.core.layout import default_layout

SCALE, PAD = 1.3, 60
LAYOUT = default_layout()
SIDE = int(400 * SCALE)


def _px(uv) -> tuple[int, int]:
    """Material mm -> panel pixel (v up)."""
    return int(PAD + uv[0] * SCALE), int(PAD + SIDE - uv[1] * SCALE)


def _text(img, text, at, colour=(30, 30, 30), size=0.55):
    cv2.putText(img, text, at, cv2.FONT_HERSHEY_SIMPLEX, size, colour, 1, cv2.LINE_AA)


def _panel(word: str, title: str, lines: list[str], **sizes) -> np.ndarray:
    img = np.full((SIDE + 2 * PAD + 60, SIDE + 2 * PAD, 3), 255, np.uint8)
    crease = planned_crease(word, LAYOUT, **sizes)
    ends = crease.ends_in(LAYOUT)
    corners = [tuple(c) for c in LAYOUT.corner_uv]
    # the flap (grey): the part of the napkin on the moving side of the crease
    grid = np.array([[u, v] for u in range(0, 401, 4) for v in range(0, 401, 4)], float)
    (px, py), (tx, ty) = crease.point, crease.direction
    side = (grid[:, 0] - px) * -ty + (grid[:, 1] - py) * tx
    moved = np.mean([c for c, name in zip(corners, "ABCD") if name in word.split()[0]], axis=0)
    sign = np.sign((moved[0] - px) * -ty + (moved[1] - py) * tx)
    for uv in grid[side * sign > 0]:
        cv2.circle(img, _px(uv), 2, (215, 215, 215), -1)
    cv2.polylines(img, [np.array([_px(c) for c in corners], np.int32)], True, (0, 0, 0), 2)
    for name, c in zip("ABCD", corners):
        off = (-22 if c[0] == 0 else 8, 18 if c[1] == 0 else -8)
        _text(img, name, (_px(c)[0] + off[0], _px(c)[1] + off[1]), size=0.7)
    for uv in LAYOUT.sticker_uv:
        cv2.circle(img, _px(uv), 4, (120, 120, 120), -1)
    a, b = (_px(e) for e in ends)
    cv2.line(img, a, b, (40, 40, 220), 2, cv2.LINE_AA)
    m = fold_measures(word, crease, LAYOUT)
    if "tip_mm" in m:
        cv2.circle(img, _px(m["tip_mm"]), 7, (200, 0, 200), 2, cv2.LINE_AA)
        cv2.arrowedLine(img, _px(moved), _px(m["tip_mm"]), (200, 0, 200), 1, cv2.LINE_AA,
                        tipLength=0.04)
        _text(img, "tip", (_px(m["tip_mm"])[0] + 10, _px(m["tip_mm"])[1] + 5), (200, 0, 200))
        for edge, leg in m["legs_mm"].items():
            other = corners["ABCD".index(edge.replace(word[0], ""))]
            d = np.subtract(other, moved) / 400.0
            end = np.asarray(moved) + leg * d
            p0, p1 = _px(moved), _px(end)
            shift = (int(-12 * d[1]), int(-12 * d[0]))
            cv2.line(img, (p0[0] + shift[0], p0[1] + shift[1]),
                     (p1[0] + shift[0], p1[1] + shift[1]), (0, 140, 0), 3)
            mid = ((p0[0] + p1[0]) // 2 + 3 * shift[0], (p0[1] + p1[1]) // 2 + 3 * shift[1])
            _text(img, f"legs_mm.{edge}", (mid[0] - 40, mid[1]), (0, 120, 0))
    _text(img, title, (PAD, 30), size=0.7)
    for k, line in enumerate(lines):
        _text(img, line, (PAD, SIDE + 2 * PAD + 10 + 22 * k))
    return img


def main(out: Path) -> None:
    corner = _panel("B over", "corner fold (02/B)", [
        "legs: B to where the crease crosses", "AB and BC; tip: B's landing place"],
        legs={"AB": 180.0, "BC": 160.0})
    strip = _panel("CD strip over", "strip or half fold (09/CD)", [
        "inset_mm: crease to side CD, through", "its middle; skew_deg: angle to CD"],
        inset_mm=130.0, skew_deg=6.0)
    diag = _panel("B diagonal", "diagonal fold (12/B)", [
        "offset_mm: crease to the diagonal AC at", "the centre (+ towards B); turn_deg"],
        offset_mm=12.0, turn_deg=-5.0)
    # the strip's inset and the diagonal's offset, marked through the middle
    for img, a, b in ((strip, (200, 400), (200, 400 - 130)), (diag, (200, 200), (
            200 + 12 / math.sqrt(2), 200 - 12 / math.sqrt(2)))):
        cv2.arrowedLine(img, _px(a), _px(b), (0, 140, 0), 2, cv2.LINE_AA, tipLength=0.2)
    cv2.imwrite(str(out), np.concatenate([corner, strip, diag], axis=1))


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("docs/folds.png"))
