"""A fold's size in millimetres, read off its crease line on the flat napkin.

A fold is an isometry of the cloth: its flap is the napkin's mirror image across the
crease. Everything a robot or a benchmark asks of one fold follows from the crease, a
line in material coordinates ``(u, v)`` (mm, SPEC section 1: A at the origin):

- a corner fold (``"B over"``): its **legs**, the distances from the corner along its
  two edges to where the crease crosses them, keyed by the edge's name (``"AB"``,
  ``"BC"``, counter-clockwise names), and its **tip**, where the corner lands: the
  corner mirrored across the crease, on the flat napkin's plan;
- a strip or a half fold (``"CD strip over"``, ``"AB half"``): its **inset**, the
  crease's distance from the side that moved (measured through the side's middle), and
  its **skew**, the crease's angle to that side (degrees, counter-clockwise positive);
- a diagonal fold (``"B diagonal"``): the crease's **offset** from the diagonal through
  the two neighbouring corners (measured through the napkin's centre, positive towards
  the moving corner) and its **turn** from it (degrees, counter-clockwise positive).

The same functions give the simulator's truth (its fold lines) and the tool's measure
(the crease fitted to the stickers), and compare a crease with a planned one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .classes import CORNERS
from .layout import NapkinLayout

__all__ = [
    "Crease",
    "crease_distance_mm",
    "edge_name",
    "fold_kind",
    "fold_measures",
    "leg_edges",
    "planned_crease",
]


@dataclass(frozen=True)
class Crease:
    """A line on the flat napkin: a point and a unit direction, material mm."""

    point: tuple[float, float]
    direction: tuple[float, float]

    @classmethod
    def through(cls, p0: NDArray | tuple, p1: NDArray | tuple) -> Crease:
        """The line through two material points (mm)."""
        a, b = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
        d = b - a
        d = d / math.hypot(d[0], d[1])
        return cls((float(a[0]), float(a[1])), (float(d[0]), float(d[1])))

    @classmethod
    def from_normal(cls, angle: float, offset: float) -> Crease:
        """The line ``n . x = offset`` with ``n = (cos angle, sin angle)``."""
        n = (math.cos(angle), math.sin(angle))
        return cls((offset * n[0], offset * n[1]), (-n[1], n[0]))

    def reflect(self, uv: NDArray[np.float64]) -> NDArray[np.float64]:
        """Material points (k, 2) mirrored across the line."""
        p, t = np.asarray(self.point), np.asarray(self.direction)
        n = np.array([-t[1], t[0]])
        q = np.atleast_2d(np.asarray(uv, dtype=float))
        return q - 2.0 * ((q - p) @ n)[:, None] * n

    def ends_in(self, layout: NapkinLayout) -> list[list[float]] | None:
        """The two points ``[[u, v], [u, v]]`` where the line crosses the napkin's
        outline, or None when it misses the napkin."""
        p, t = self.point, self.direction
        lo, hi = -math.inf, math.inf
        for k, size in ((0, float(layout.width_mm)), (1, float(layout.height_mm))):
            if abs(t[k]) < 1e-12:
                if not 0.0 <= p[k] <= size:
                    return None
                continue
            s0, s1 = sorted(((0.0 - p[k]) / t[k], (size - p[k]) / t[k]))
            lo, hi = max(lo, s0), min(hi, s1)
        if not hi > lo:
            return None
        return [[p[0] + s * t[0], p[1] + s * t[1]] for s in (lo, hi)]


def edge_name(a: str, b: str) -> str:
    """SPEC's name of the edge between corners a and b (counter-clockwise: ``"DA"``,
    never ``"AD"``)."""
    i, j = CORNERS.index(a), CORNERS.index(b)
    return a + b if (i + 1) % 4 == j else b + a


def leg_edges(corner: str) -> tuple[str, str]:
    """The edges of a corner's two legs: the one leaving it (counter-clockwise), then
    the one arriving at it (``"B"`` -> ``("BC", "AB")``)."""
    k = CORNERS.index(corner)
    return edge_name(corner, CORNERS[(k + 1) % 4]), edge_name(CORNERS[k - 1], corner)


def fold_kind(word: str) -> tuple[str, str]:
    """``("corner", "B")``, ``("side", "CD")`` or ``("diagonal", "B")`` for a fold word
    (``"B over"``, ``"B over crossing A"``, ``"CD strip under"``, ``"AB half"``,
    ``"B diagonal"``)."""
    name, kind = word.split(" ", 1)
    if kind == "diagonal":
        return "diagonal", name
    if len(name) == 2:
        return "side", name
    return "corner", name


def _corner(layout: NapkinLayout, name: str) -> NDArray[np.float64]:
    return np.asarray(layout.corner_uv[CORNERS.index(name)], dtype=float)


def _corner_xy(layout: NapkinLayout, name: str) -> tuple[float, float]:
    c = layout.corner_uv[CORNERS.index(name)]
    return float(c[0]), float(c[1])


def _angle_deg(t: tuple[float, float], ref: tuple[float, float]) -> float:
    """The angle (degrees, in [-90, 90)) from line direction ``ref`` to line direction
    ``t``, counter-clockwise positive (a line has no sense: 180 degrees is 0)."""
    a = math.degrees(math.atan2(ref[0] * t[1] - ref[1] * t[0], ref[0] * t[0] + ref[1] * t[1]))
    return (a + 90.0) % 180.0 - 90.0


def _meet(crease: Crease, a: tuple[float, float], d: tuple[float, float]) -> float | None:
    """Where ``a + s d`` crosses the crease: s (None when parallel)."""
    (px, py), (tx, ty) = crease.point, crease.direction
    den = d[1] * tx - d[0] * ty  # d . n with n = (-ty, tx)
    if abs(den) < 1e-9:
        return None
    return ((py - a[1]) * tx - (px - a[0]) * ty) / den


def _unit(a: tuple[float, float], b: tuple[float, float]) -> tuple[float, float]:
    dx, dy = b[0] - a[0], b[1] - a[1]
    norm = math.hypot(dx, dy)
    return dx / norm, dy / norm


def fold_measures(word: str, crease: Crease, layout: NapkinLayout) -> dict[str, object]:
    """The sizes of the fold ``word`` whose crease is ``crease`` (see the module's
    description).

    Returns
    -------
    dict
        ``{"legs_mm": {edge: mm or None, ...}, "tip_mm": [u, v]}`` for a corner fold,
        ``{"inset_mm", "skew_deg"}`` for a strip or half fold, ``{"offset_mm",
        "turn_deg"}`` for a diagonal fold. A leg is None where the crease runs along
        its edge (it never crosses it).
    """
    kind, name = fold_kind(word)
    t = crease.direction
    if kind == "corner":
        k = CORNERS.index(name)
        here = _corner_xy(layout, name)
        legs: dict[str, float | None] = {}
        for other, edge in zip((CORNERS[(k + 1) % 4], CORNERS[k - 1]), leg_edges(name)):
            legs[edge] = _meet(crease, here, _unit(here, _corner_xy(layout, other)))
        (px, py), (tx, ty) = crease.point, crease.direction
        s = (here[0] - px) * -ty + (here[1] - py) * tx
        tip = [here[0] + 2.0 * s * ty, here[1] - 2.0 * s * tx]
        return {"legs_mm": legs, "tip_mm": tip}
    if kind == "side":
        x, y = _corner_xy(layout, name[0]), _corner_xy(layout, name[1])
        e = _unit(x, y)
        mid = (0.5 * (x[0] + y[0]), 0.5 * (x[1] + y[1]))
        return {"inset_mm": _meet(crease, mid, (-e[1], e[0])), "skew_deg": _angle_deg(t, e)}
    k = CORNERS.index(name)
    prev, nxt, here = (_corner_xy(layout, CORNERS[i % 4]) for i in (k - 1, k + 1, k))
    e = _unit(prev, nxt)
    n = (-e[1], e[0])
    if n[0] * (here[0] - prev[0]) + n[1] * (here[1] - prev[1]) < 0:
        n = (-n[0], -n[1])
    mid = (0.5 * (prev[0] + nxt[0]), 0.5 * (prev[1] + nxt[1]))
    return {"offset_mm": _meet(crease, mid, n), "turn_deg": _angle_deg(t, e)}


def planned_crease(
    word: str,
    layout: NapkinLayout,
    *,
    legs: dict[str, float] | None = None,
    inset_mm: float | None = None,
    tip_mm: tuple[float, float] | None = None,
    skew_deg: float = 0.0,
    offset_mm: float = 0.0,
    turn_deg: float = 0.0,
) -> Crease | None:
    """The crease that makes the fold ``word`` with the given sizes: a corner fold by
    its legs (keyed by edge name, both needed) or by where its tip lands; a strip or half
    fold by its inset (and skew); a diagonal fold by its offset and turn. None when the
    sizes given do not name a crease (a corner fold without legs or tip, a tip on the
    corner itself)."""
    kind, name = fold_kind(word)
    if kind == "corner":
        here = _corner(layout, name)
        if tip_mm is not None:
            tip = np.asarray(tip_mm, dtype=float)
            d = tip - here
            if math.hypot(d[0], d[1]) < 1e-6:
                return None
            mid = 0.5 * (tip + here)
            return Crease.through(mid, mid + np.array([-d[1], d[0]]))
        if not legs:
            return None
        k = CORNERS.index(name)
        ends = []
        for other, edge in zip((CORNERS[(k + 1) % 4], CORNERS[k - 1]), leg_edges(name)):
            if edge not in legs:
                return None
            d = _corner(layout, other) - here
            ends.append(here + float(legs[edge]) * d / np.linalg.norm(d))
        return Crease.through(ends[0], ends[1])
    if kind == "side":
        if inset_mm is None:
            return None
        x, y = _corner(layout, name[0]), _corner(layout, name[1])
        e = (y - x) / np.linalg.norm(y - x)
        p = 0.5 * (x + y) + inset_mm * np.array([-e[1], e[0]])
        a = math.radians(skew_deg)
        return Crease.through(p, p + _turned(e, a))
    k = CORNERS.index(name)
    prev, nxt, here = (_corner(layout, CORNERS[i % 4]) for i in (k - 1, k + 1, k))
    e = (nxt - prev) / np.linalg.norm(nxt - prev)
    n = np.array([-e[1], e[0]])
    if n @ (here - prev) < 0:
        n = -n
    p = 0.5 * (prev + nxt) + offset_mm * n
    a = math.radians(turn_deg)
    return Crease.through(p, p + _turned(e, a))


def _turned(e: NDArray, a: float) -> NDArray[np.float64]:
    """The direction ``e`` turned by ``a`` radians counter-clockwise."""
    c, s = math.cos(a), math.sin(a)
    return np.array([c * e[0] - s * e[1], s * e[0] + c * e[1]])


def crease_distance_mm(a: Crease, b: Crease, layout: NapkinLayout) -> float | None:
    """How far apart two creases lie on the napkin: the largest distance of either's
    ends on the napkin (where it crosses the outline) from the other line; None when
    one misses the napkin."""
    worst = 0.0
    for this, other in ((a, b), (b, a)):
        ends = this.ends_in(layout)
        if ends is None:
            return None
        (px, py), (tx, ty) = other.point, other.direction
        for ex, ey in ends:
            worst = max(worst, abs(-(ex - px) * ty + (ey - py) * tx))
    return worst
