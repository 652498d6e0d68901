"""Each state's folds as lines on the flat napkin, at the middle of its class's sizes.

The twelve classes give ranges for their fold sizes (legs of a corner fold, the inset of
a strip or a half fold, the diagonal); the middle of each range, scaled with the napkin
(:attr:`~dgli_vision.core.layout.NapkinLayout.fold_scale`), gives one nominal fold line
per fold word of :func:`~dgli_vision.core.fold_graph.folds_of`. Perception uses them to
tell which stickers lie on which flap; the planner uses them as the folds to make.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from .classes import CORNERS
from .fold_graph import folds_of
from .layout import NapkinLayout

__all__ = ["NominalFold", "along_scale", "fold_for_word", "nominal_folds", "reflect_uv"]

#: Middle of each corner class's leg ranges (mm on the 400 mm napkin): one leg size, or
#: (along the shared edge, along the other edge) for the two corners of one side.
CORNER_LEGS_MM: dict[str, float | tuple[float, float]] = {
    "02": 175.0,
    "03": 175.0,
    "04": (155.0, 165.0),
    "05": (182.5, 245.0),
    "06": 175.0,
    "07": 160.0,
    "08": 185.0,
}
#: The leg ranges of each corner class (mm on the 400 mm napkin): (along the edge shared
#: with the other folded corner of the side, along the other edge); the same for both
#: legs where the class has one range.
CORNER_LEG_RANGES: dict[str, tuple[tuple[float, float], tuple[float, float]]] = {
    "02": ((150.0, 200.0), (150.0, 200.0)),
    "03": ((150.0, 200.0), (150.0, 200.0)),
    "04": ((150.0, 160.0), (150.0, 180.0)),
    "05": ((170.0, 195.0), (230.0, 260.0)),
    "06": ((150.0, 200.0), (150.0, 200.0)),
    "07": ((150.0, 170.0), (150.0, 170.0)),
    "08": ((170.0, 200.0), (170.0, 200.0)),
}
#: The inset ranges of the side classes (mm on the 400 mm napkin, SPEC section 3).
SIDE_INSET_RANGES: dict[str, tuple[float, float]] = {
    "09": (125.0, 140.0), "10": (125.0, 140.0), "11": (198.0, 210.0),
}
#: Middle of the inset ranges of the side classes (mm on the 400 mm napkin).
SIDE_INSET_MM: dict[str, float] = {k: 0.5 * (lo + hi) for k, (lo, hi) in SIDE_INSET_RANGES.items()}


@dataclass(frozen=True)
class NominalFold:
    """One fold as a line on the flat napkin.

    Attributes
    ----------
    word : str
        The fold word (``"A over"``, ``"AB strip over"``, ``"B over crossing A"``...).
    p0, p1 : tuple of float
        Two material points (mm) on the fold line.
    flap : tuple of float
        The material point that moves most: the corner, or the middle of the side.
    under : bool
        The flap goes beneath the napkin.
    corner : str or None
        The corner a corner or diagonal fold moves.
    side : str or None
        The side a strip or half fold moves.
    """

    word: str
    p0: tuple[float, float]
    p1: tuple[float, float]
    flap: tuple[float, float]
    under: bool = False
    corner: str | None = None
    side: str | None = None

    @property
    def moved_corners(self) -> tuple[str, ...]:
        """The corners on the flap."""
        return (self.corner,) if self.corner else tuple(self.side or "")

    def on_flap(self, uv: NDArray[np.float64], margin_mm: float = 0.0) -> NDArray[np.bool_]:
        """Which material points (k, 2) lie on the flap side, more than ``margin_mm``
        beyond the line."""
        return _signed(np.asarray(uv, dtype=float), self) > margin_mm


@lru_cache(maxsize=256)
def _frame(f: NominalFold) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A point of the fold line and its unit normal towards the flap."""
    a, b, c = (np.asarray(x, dtype=float) for x in (f.p0, f.p1, f.flap))
    t = (b - a) / np.linalg.norm(b - a)
    n = np.array([-t[1], t[0]])
    return a, (n if (c - a) @ n >= 0 else -n)


def _signed(uv: NDArray[np.float64], f: NominalFold) -> NDArray[np.float64]:
    """Distance (mm) of material points beyond the fold line, positive on the flap side."""
    a, n = _frame(f)
    return (np.atleast_2d(uv) - a) @ n


def reflect_uv(uv: NDArray[np.float64], f: NominalFold) -> NDArray[np.float64]:
    """Material points (k, 2) mirrored across the fold line of ``f``: where a point of
    the flap lands on the flat napkin once it is folded, and back."""
    a, n = _frame(f)
    rel = np.atleast_2d(uv) - a
    return np.atleast_2d(uv) - 2.0 * (rel @ n)[:, None] * n


def along_scale(layout: NapkinLayout, a: str, b: str) -> float:
    """Scale of a fold size measured from corner a towards corner b."""
    c = layout.corner_uv
    d = np.abs(c[CORNERS.index(b)] - c[CORNERS.index(a)])
    return float(d @ np.array(layout.fold_scale) / d.sum())


def _corner(layout: NapkinLayout, name: str, legs: tuple[float, float], word: str) -> NominalFold:
    """A corner fold with legs (along the leaving edge, along the arriving edge), mm on
    the 400 mm napkin."""
    k = CORNERS.index(name)
    c = layout.corner_uv
    here, nxt, prev = c[k], c[(k + 1) % 4], c[(k - 1) % 4]
    out = legs[0] * along_scale(layout, name, CORNERS[(k + 1) % 4])
    inn = legs[1] * along_scale(layout, name, CORNERS[k - 1])
    p0 = here + out * (nxt - here) / np.linalg.norm(nxt - here)
    p1 = here + inn * (prev - here) / np.linalg.norm(prev - here)
    return NominalFold(
        word, _pt(p0), _pt(p1), _pt(here), under=" under" in word, corner=name
    )


def _side(layout: NapkinLayout, side: str, inset_mm: float, word: str) -> NominalFold:
    c = layout.corner_uv
    x, y = c[CORNERS.index(side[0])], c[CORNERS.index(side[1])]
    e = (y - x) / np.linalg.norm(y - x)
    inward = np.array([-e[1], e[0]])
    k = CORNERS.index(side[1])
    inset = inset_mm * along_scale(layout, side[1], CORNERS[(k + 1) % 4])
    return NominalFold(
        word, _pt(x + inset * inward), _pt(y + inset * inward), _pt((x + y) / 2),
        under=" under" in word, side=side,
    )


def _diagonal(layout: NapkinLayout, name: str, word: str) -> NominalFold:
    k = CORNERS.index(name)
    c = layout.corner_uv
    prev, nxt = c[(k - 1) % 4], c[(k + 1) % 4]
    return NominalFold(word, _pt(prev), _pt(nxt), _pt(c[k]), corner=name)


def _pt(p: NDArray) -> tuple[float, float]:
    return float(p[0]), float(p[1])


def fold_for_word(
    word: str,
    class_id: str,
    layout: NapkinLayout,
    side: str | None = None,
    within: str | None = None,
) -> NominalFold:
    """The fold ``word`` at the middle of the sizes of class ``class_id``.

    Parameters
    ----------
    word : str
        A fold word of :func:`~dgli_vision.core.fold_graph.folds_of`.
    class_id : str
        The class whose size ranges apply (corner words take a corner class's legs; a
        class without corner folds gives the corner-over legs).
    layout : NapkinLayout
    side : str, optional
        For the two corners of one side (04, 05): that side, whose edge takes the
        shared leg.
    within : str, optional
        A corner class whose leg ranges the legs are brought into (the nearest size in
        range): a fold made towards one class that passes through another.
    """
    name, kind = word.split(" ", 1)
    if kind in ("over", "under") or kind.startswith("over crossing"):
        legs = CORNER_LEGS_MM.get(class_id, CORNER_LEGS_MM["02"])
        shared, other = (legs, legs) if isinstance(legs, float) else legs
        if within in CORNER_LEG_RANGES:
            (s_lo, s_hi), (o_lo, o_hi) = CORNER_LEG_RANGES[within]
            shared, other = min(max(shared, s_lo), s_hi), min(max(other, o_lo), o_hi)
        crossing = kind.startswith("over crossing")
        partner = kind.split()[-1] if crossing else None
        k = CORNERS.index(name)
        if partner is None:  # the side shared with the other folded corner of the class
            partner = side.replace(name, "") if side and name in side else CORNERS[(k + 1) % 4]
        out_shared = CORNERS[(k + 1) % 4] == partner
        pair = (shared, other) if out_shared else (other, shared)
        return _corner(layout, name, pair, word)
    if kind == "diagonal":
        return _diagonal(layout, name, word)
    inset = SIDE_INSET_MM["11" if kind == "half" else "09"]
    return _side(layout, name, inset, word)


@lru_cache(maxsize=512)
def nominal_folds(
    class_id: str, variant: str | None, layout: NapkinLayout
) -> tuple[NominalFold, ...]:
    """The folds of a state, each at the middle of its class's sizes, in the order they
    are made (a crossing flap last).

    For the two corners of one side (04), the shared edge is the side of the variant;
    for 05 it is the side too, the first corner's flap lying under the crossing one.
    """
    words = sorted(folds_of(class_id, variant), key=lambda w: (" crossing " in w, w))
    side = variant.split("/")[0] if class_id in ("04", "05") and variant else None
    return tuple(fold_for_word(w, class_id, layout, side) for w in words)
