"""Pictures of affordances and plans: graspable corners, grasp and place points, fold
lines and each hand's path, drawn on an overlay image (BGR). Every marker and label is
kept inside the image (a point at its edge is drawn just inside it), and a plan's step
comes with a legend that also gives the grasp point in 3D, the lift height and the
number of hands."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "draw_corners",
    "draw_folds",
    "draw_no_plan",
    "draw_path",
    "draw_step",
    "draw_step_legend",
    "fold_caption",
]

#: BGR colours: a graspable corner (green ring), a corner not graspable (grey cross),
#: the grasp (orange, apart from the stickers' segments' magenta), the place (cyan) and
#: the fold line (white dashes on a dark rim, seen on a white napkin too).
GRASPABLE = (60, 200, 60)
NOT_GRASPABLE = (150, 150, 150)
GRASP = (0, 120, 255)
PLACE = (230, 200, 0)
FOLD = (255, 255, 255)
RIM = (0, 0, 0)
#: The stickers' segments (drawn by :func:`~dgli_vision.analysis.report.overlay_image`).
SEGMENT = (255, 0, 255)
#: A hand's path (its arc over the fold line, seen from the camera): light orange, the
#: waypoints where the gripper closes and opens marked.
PATH = (80, 190, 255)


def _scale(img: NDArray) -> float:
    return max(1.0, img.shape[1] / 1280)


def _px(p: Any) -> tuple[int, int]:
    return int(round(float(p[0]))), int(round(float(p[1])))


def _inside(img: NDArray, p: tuple[int, int], margin: int) -> tuple[int, int]:
    """``p`` moved just inside the image, ``margin`` pixels from each edge."""
    h, w = img.shape[:2]
    return (min(max(p[0], margin), w - 1 - margin), min(max(p[1], margin), h - 1 - margin))


def _text_inside(
    img: NDArray, text: str, org: tuple[int, int], scale: float, weight: int
) -> tuple[int, int]:
    """Where to write ``text`` near ``org`` (its baseline's left end) so that it lies
    wholly inside the image."""
    import cv2

    (tw, th), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, weight + 2)
    h, w = img.shape[:2]
    x = min(max(org[0], 2), max(2, w - tw - 3))
    y = min(max(org[1], th + 3), h - base - 3)
    return x, y


def _rimmed_text(
    img: NDArray, text: str, org: tuple[int, int], scale: float, colour: tuple, weight: int
) -> None:
    """``text`` in ``colour`` on a dark rim, kept inside the image."""
    import cv2

    x, y = _text_inside(img, text, org, scale, weight)
    for dx, dy in ((-1, -1), (1, 1), (-1, 1), (1, -1), (0, 0)):
        cv2.putText(img, text, (x + dx, y + dy), cv2.FONT_HERSHEY_SIMPLEX, scale,
                    colour if dx == dy == 0 else RIM, weight, cv2.LINE_AA)


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
        if c.graspable:
            u, v = _inside(img, _px(c.pixel), int(18 * s))
            cv2.circle(img, (u, v), int(14 * s), GRASPABLE, max(2, int(3 * s)), cv2.LINE_AA)
            _rimmed_text(img, c.corner, (u + int(16 * s), v - int(10 * s)), 0.7 * s,
                         GRASPABLE, max(2, int(2 * s)))
        else:
            r = int(8 * s)
            u, v = _inside(img, _px(c.pixel), r + 2)
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
    """Draw each fold's line on the table (white dashes on a dark rim: seen on the white
    napkin as on the table) with its sizes in mm beside its middle
    (:func:`fold_caption`)."""
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
        pa, pb = intrinsics.project(ends)
        a, b = _px(pa), _px(pb)
        _dashes(img, np.asarray(pa, dtype=float), np.asarray(pb, dtype=float),
                max(1, int(2 * s)), n=max(8, int(np.hypot(*(pb - pa)) / (12 * s)) // 2 * 2))
        mid = ((a[0] + b[0]) // 2 + int(6 * s), (a[1] + b[1]) // 2 - int(6 * s))
        text = fold_caption(f)
        width = max(1, int(1.5 * s))
        for dx, dy in ((-1, -1), (1, 1), (-1, 1), (1, -1), (0, 0)):  # a dark rim, then white
            colour = FOLD if dx == dy == 0 else (0, 0, 0)
            cv2.putText(img, text, (mid[0] + dx, mid[1] + dy), cv2.FONT_HERSHEY_SIMPLEX,
                        0.55 * s, colour, width, cv2.LINE_AA)
    return img


def _dashes(img: NDArray, a: NDArray, b: NDArray, width: int, n: int = 24) -> None:
    """A dashed line from ``a`` to ``b``: dark dashes a little wider, then white ones
    on them (seen on the white napkin as on the table)."""
    import cv2

    for colour, w in ((RIM, width + 4), (FOLD, width)):
        for k in range(0, n, 2):
            p = a + (b - a) * k / n
            q = a + (b - a) * (k + 1) / n
            cv2.line(img, _px(p), _px(q), colour, w, cv2.LINE_AA)


def _step_lines(step: Any, caption: str) -> list[str]:
    """The legend's text of a step: what it is, then the grasp point in 3D, the lift
    height and the place point (metres, camera frame)."""

    def xyz(p: Any) -> str:
        return "(" + ", ".join(f"{v:.3f}" for v in p) + ") m"

    lines = [caption] if caption else []
    hands = getattr(step, "hands", ())
    if step.grasp_point is not None:
        lift = f", lift {step.lift_height:.3f} m" if step.lift_height is not None else ""
        lines.append(f"grasp {xyz(step.grasp_point)}{lift}")
    if len(hands) > 1:
        t = hands[0].path[-1].t
        lines.append(f"{len(hands)} hands: " + ", ".join(h.grasps.split(" of ")[0]
                                                         for h in hands) + f"; {t:.1f} s")
    elif hands:
        lines.append(f"path {hands[0].path[-1].t:.1f} s, carry "
                     f"{hands[0].speeds['carry_m_s']:.2f} m/s")
    if step.place_point is not None:
        lines.append(f"place {xyz(step.place_point)}")
    return lines


#: The legend's symbols, in order: name and how it is drawn.
_KEYS = (
    ("grasp", "disc"),
    ("place", "ring"),
    ("fold line", "dashes"),
    ("path", "path"),
    ("graspable corner", "corner"),
    ("sticker segment", "segment"),
)


def _legend(img: NDArray, lines: list[str], keys: tuple, avoid: list[tuple[int, int]]) -> None:
    """A dark box with ``lines`` of text over the symbols of ``keys``, in the lower
    corner of the image (left or right) with fewer of the points ``avoid`` under it."""
    import cv2

    s = _scale(img)
    font, scale, weight = cv2.FONT_HERSHEY_SIMPLEX, 0.55 * s, max(1, int(s))
    line_h, pad, sym = int(22 * s), int(8 * s), int(30 * s)
    key_w = [sym + cv2.getTextSize(k, font, scale, weight)[0][0] + int(14 * s) for k, _ in keys]
    text_w = max((cv2.getTextSize(t, font, scale, weight)[0][0] for t in lines), default=0)
    h, w = img.shape[:2]
    box_w = min(w - 4, max(text_w, sum(key_w)) + 2 * pad)
    rows = len(lines) + (1 if keys else 0)
    box_h = rows * line_h + 2 * pad
    y0 = h - box_h - 2

    def under(x0: int) -> int:
        return sum(x0 <= u <= x0 + box_w and y0 <= v for u, v in avoid)

    x0 = min((2, w - box_w - 2), key=under)
    dark = img[y0 : y0 + box_h, x0 : x0 + box_w]
    dark[:] = (dark * 0.35).astype(np.uint8)
    y = y0 + pad + int(16 * s)
    for t in lines:
        cv2.putText(img, t, (x0 + pad, y), font, scale, (255, 255, 255), weight, cv2.LINE_AA)
        y += line_h
    x, mid = x0 + pad, y - int(5 * s)
    for (name, how), kw in zip(keys, key_w, strict=True):
        c = (x + sym // 2, mid)
        if how == "disc":
            cv2.circle(img, c, int(7 * s), GRASP, -1, cv2.LINE_AA)
        elif how == "ring":
            cv2.circle(img, c, int(8 * s), PLACE, max(2, int(2 * s)), cv2.LINE_AA)
        elif how == "dashes":
            _dashes(img, np.array([x + 2.0, mid]), np.array([x + sym - 2.0, mid]),
                    max(2, int(2 * s)), n=5)
        elif how == "path":
            cv2.line(img, (x + 2, mid), (x + sym - 2, mid), PATH, max(2, int(2 * s)),
                     cv2.LINE_AA)
        elif how == "corner":
            cv2.circle(img, c, int(8 * s), GRASPABLE, max(2, int(2 * s)), cv2.LINE_AA)
        else:
            cv2.arrowedLine(img, (x + 2, mid), (x + sym - 2, mid), SEGMENT, max(1, int(2 * s)),
                            cv2.LINE_AA, tipLength=0.3)
        cv2.putText(img, name, (x + sym + int(4 * s), y), font, scale, (255, 255, 255), weight,
                    cv2.LINE_AA)
        x += kw


def draw_step(
    img: NDArray[np.uint8], step: Any, intrinsics: Any, caption: str = "", *,
    legend: bool = True,
) -> NDArray[np.uint8]:
    """Draw a plan's step: the fold line (white dashes on a dark rim), the grasp (an
    orange disc), the place (a cyan ring) and an arrow from one to the other, each kept
    inside the image, and (``legend``) a legend with ``caption``, the grasp point in 3D,
    the lift height and the place point (:func:`draw_step_legend`: drawn last, over
    whatever else is drawn after the marks)."""
    import cv2

    s = _scale(img)
    a, b = (intrinsics.project(np.asarray(p, dtype=float)[None])[0] for p in step.fold_line)
    _dashes(img, a, b, max(2, int(3 * s)))
    for k, hand in enumerate(getattr(step, "hands", ())):
        draw_path(img, hand, intrinsics, second=k > 0)
    r_grasp, r_place = int(10 * s), int(12 * s)
    g = _inside(img, _px(intrinsics.project(np.asarray(step.grasp_point, float)[None])[0]),
                r_grasp + 3)
    pl = _inside(img, _px(intrinsics.project(np.asarray(step.place_point, float)[None])[0]),
                 r_place + 4)
    d = np.subtract(pl, g, dtype=float)
    length = float(np.hypot(*d))
    if length > r_grasp + r_place + 8:  # the arrow ends at the place's ring, its tip seen
        tip = _px(np.asarray(g) + d * (1 - (r_place + 5) / length))
        for colour, width in ((RIM, max(2, int(2 * s)) + 3), (GRASP, max(2, int(2 * s)))):
            cv2.arrowedLine(img, g, tip, colour, width, cv2.LINE_AA,
                            tipLength=min(0.5, 18 * s / length))
    cv2.circle(img, g, r_grasp + 2, RIM, -1, cv2.LINE_AA)
    cv2.circle(img, g, r_grasp, GRASP, -1, cv2.LINE_AA)
    cv2.circle(img, pl, r_place, RIM, max(2, int(3 * s)) + 3, cv2.LINE_AA)
    cv2.circle(img, pl, r_place, PLACE, max(2, int(3 * s)), cv2.LINE_AA)
    _rimmed_text(img, "grasp", (g[0] + r_grasp + 4, g[1] + r_grasp + int(14 * s)), 0.55 * s,
                 GRASP, max(1, int(s)))
    _rimmed_text(img, "place", (pl[0] + r_place + 4, pl[1] + r_place + int(14 * s)),
                 0.55 * s, PLACE, max(1, int(s)))
    if legend:
        draw_step_legend(img, step, intrinsics, caption)
    return img


def draw_path(img: NDArray[np.uint8], hand: Any, intrinsics: Any, *,
              second: bool = False) -> NDArray[np.uint8]:
    """Draw one hand's path (a :class:`~dgli_vision.planning.motion.Hand`): its
    waypoints joined on a dark rim, a small dot where the gripper closes or opens; a
    ``second`` hand's grasp and place marked as the first's (disc and ring), smaller."""
    import cv2

    s = _scale(img)
    pts = np.asarray([w.point for w in hand.path], dtype=float)
    if np.any(pts[:, 2] <= 0):
        return img
    px = [_inside(img, _px(p), 2) for p in intrinsics.project(pts)]
    poly = np.asarray(px, dtype=np.int32).reshape(-1, 1, 2)
    width = max(1, int(2 * s))
    cv2.polylines(img, [poly], False, RIM, width + 3, cv2.LINE_AA)
    cv2.polylines(img, [poly], False, PATH, width, cv2.LINE_AA)
    for w0, w1, p in zip(hand.path, hand.path[1:], px[1:]):
        if w0.gripper != w1.gripper:
            cv2.circle(img, p, int(4 * s), RIM, -1, cv2.LINE_AA)
            cv2.circle(img, p, int(3 * s), PATH, -1, cv2.LINE_AA)
    if second:
        g = _inside(img, _px(intrinsics.project(np.asarray(hand.grasp_point)[None])[0]), 12)
        q = _inside(img, _px(intrinsics.project(np.asarray(hand.place_point)[None])[0]), 12)
        cv2.circle(img, g, int(8 * s) + 2, RIM, -1, cv2.LINE_AA)
        cv2.circle(img, g, int(8 * s), GRASP, -1, cv2.LINE_AA)
        cv2.circle(img, q, int(9 * s), RIM, max(2, int(2 * s)) + 3, cv2.LINE_AA)
        cv2.circle(img, q, int(9 * s), PLACE, max(2, int(2 * s)), cv2.LINE_AA)
    return img


def draw_step_legend(
    img: NDArray[np.uint8], step: Any, intrinsics: Any, caption: str = ""
) -> NDArray[np.uint8]:
    """The legend of :func:`draw_step`'s marks, in the lower corner with fewer of them
    under it: ``caption``, the grasp point in 3D with the lift height, the place point,
    and what each mark is."""
    marks = [step.grasp_point, step.place_point, *step.fold_line]
    for hand in getattr(step, "hands", ()):
        marks += [w.point for w in hand.path]
    avoid = [_px(intrinsics.project(np.asarray(p, dtype=float)[None])[0]) for p in marks]
    _legend(img, _step_lines(step, caption), _KEYS, avoid)
    return img


def draw_no_plan(img: NDArray[np.uint8], reason: str) -> NDArray[np.uint8]:
    """Write why there is no plan at the foot of an overlay (wrapped to its width; a
    state that cannot be told points at the verdict's reason above)."""
    import cv2

    s = _scale(img)
    lines: list[str] = []
    if reason.startswith("the state cannot be told"):
        reason = "the state cannot be told (why: the verdict above)"
    for word in f"no plan: {reason}".split(" "):  # cut at spaces to the image's width
        trial = f"{lines[-1]} {word}" if lines else word
        wide = cv2.getTextSize(trial, cv2.FONT_HERSHEY_SIMPLEX, 0.55 * s, max(1, int(s)))[0][0]
        if lines and wide <= img.shape[1] - int(30 * s):
            lines[-1] = trial
        else:
            lines.append(word)
    _legend(img, lines, (), [])
    return img
