"""States outside the twelve: what a fold that went wrong, or a napkin folded some other
way, leaves on the table.

SPEC's twelve states are the ones the tool names; a robot's napkin is often in none of
them. This generator makes such states from the same isometric fold operator
(:mod:`.fold`) as the twelve, with folds the twelve do not have, so that the classifier
can be tested on saying "no known state fits" (labels ``none``):

========================  ==============================================================
kind                      what is folded
========================  ==============================================================
``quarter``               in half over a mid-line, then in half again across it
``gate``                  two opposite strips folded over to the middle (a gate fold)
``strip-and-corner``      a strip over on one side and a corner over on the opposite side
``corner-twice``          a corner folded over, then its tip folded back out
``skew``                  one fold along a line 18-27 degrees off every edge and diagonal
``two-strips``            the strips of two adjacent sides folded over (an L)
``diagonal-half``         folded over a diagonal, then the triangle in half again
``crumpled``              two flaps left standing at 60-120 degrees, and wrinkles up to
                          40 mm: a napkin dropped in a heap, heights up to about 120 mm
========================  ==============================================================

Each kind's sizes are drawn from ranges well away from the twelve's (a gate fold's two
strips are 85-110 mm wide where a strip over is 125-140 mm and only one), so that every
state drawn here is, by its folds, none of the twelve.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ...core.classes import CORNERS, OUTSIDE
from ...core.errors import InvalidValueError
from ...core.layout import NapkinLayout, default_layout
from .states import (
    ClothState,
    FoldStep,
    corner_fold_line,
    make_state,
    normalize_rng,
    side_fold_line,
)

__all__ = ["OUTSIDE_KINDS", "OUTSIDE_LABEL", "sample_outside"]

#: The label of a state outside the twelve (labels.csv, ``ClothState.class_id``).
OUTSIDE_LABEL = OUTSIDE

#: The kinds of state outside the twelve, in the order ``dgli render --outside`` takes
#: them (sample ``k`` is of kind ``OUTSIDE_KINDS[k % 8]``).
OUTSIDE_KINDS: tuple[str, ...] = (
    "quarter",
    "gate",
    "strip-and-corner",
    "corner-twice",
    "skew",
    "two-strips",
    "diagonal-half",
    "crumpled",
)

_SIDES = ("AB", "BC", "CD", "DA")


def _opposite(side: str) -> str:
    return _SIDES[(_SIDES.index(side) + 2) % 4]


def _steps(
    kind: str, layout: NapkinLayout, rng: np.random.Generator
) -> tuple[list[FoldStep], list[float] | None, float, dict[str, Any]]:
    """The folds of a state of ``kind``, their angles (None: every fold laid flat), the
    wrinkles' amplitude (mm) and what was drawn."""
    u = rng.uniform
    side = _SIDES[int(rng.integers(4))]
    corner = CORNERS[int(rng.integers(4))]
    w = min(layout.width_mm, layout.height_mm)
    s = w / 400.0  # sizes are drawn for the 400 mm napkin
    wrinkle = float(u(0, 6))
    if kind == "quarter":
        first = side_fold_line(layout, side, float(u(195, 205)) * s)
        # across the first crease: the line through the middle of the two other sides
        k = _SIDES.index(side)
        second = side_fold_line(layout, _SIDES[(k + 1) % 4], float(u(195, 205)) * s)
        return [first, second], None, wrinkle, {"sides": [side, _SIDES[(k + 1) % 4]]}
    if kind == "gate":
        a, b = float(u(85, 110)) * s, float(u(85, 110)) * s
        steps = [side_fold_line(layout, side, a), side_fold_line(layout, _opposite(side), b)]
        return steps, None, wrinkle, {"sides": [side, _opposite(side)], "insets_mm": [a, b]}
    if kind == "strip-and-corner":
        far = _opposite(side)
        near_corner = far[int(rng.integers(2))]
        inset = float(u(125, 140)) * s
        legs = (float(u(110, 160)) * s, float(u(110, 160)) * s)
        steps = [side_fold_line(layout, side, inset), corner_fold_line(layout, near_corner, *legs)]
        return steps, None, wrinkle, {"side": side, "corner": near_corner, "inset_mm": inset}
    if kind == "corner-twice":
        legs = float(u(160, 200)) * s
        tip = float(u(60, 130)) * s  # the tip folded back, measured along the legs
        steps = [
            corner_fold_line(layout, corner, legs, legs),
            corner_fold_line(layout, corner, tip, tip),
        ]
        return steps, None, wrinkle, {"corner": corner, "legs_mm": legs, "tip_mm": tip}
    if kind == "skew":
        return _skew(layout, rng, wrinkle)
    if kind == "two-strips":
        k = _SIDES.index(side)
        a, b = float(u(100, 140)) * s, float(u(100, 140)) * s
        steps = [side_fold_line(layout, side, a), side_fold_line(layout, _SIDES[(k + 1) % 4], b)]
        return steps, None, wrinkle, {"sides": [side, _SIDES[(k + 1) % 4]]}
    if kind == "diagonal-half":
        c = layout.corner_uv
        k = CORNERS.index(corner)
        here, prev, nxt = c[k], c[(k - 1) % 4], c[(k + 1) % 4]
        diag = FoldStep(tuple(prev), tuple(nxt), tuple(here))
        # then the triangle in half: the line from the middle of the diagonal to the
        # opposite corner, the half with the next corner folded over the other
        mid = 0.5 * (prev + nxt)
        far = c[(k + 2) % 4]
        second = FoldStep(tuple(mid), tuple(far), tuple(nxt))
        return [diag, second], None, wrinkle, {"corner": corner}
    if kind == "crumpled":
        return _crumpled(layout, rng)
    raise InvalidValueError(f"unknown kind {kind!r}; expected one of {', '.join(OUTSIDE_KINDS)}")


def _skew(
    layout: NapkinLayout, rng: np.random.Generator, wrinkle: float
) -> tuple[list[FoldStep], None, float, dict[str, Any]]:
    """One fold along a line 18-27 degrees off every edge and diagonal (22.5 degrees is
    the farthest a line can be from all four directions), through a point that leaves
    a flap of a fifth to two fifths of the napkin."""
    c = layout.corner_uv
    centre = c.mean(axis=0)
    off = float(rng.uniform(18, 27))
    theta = np.radians(45.0 * int(rng.integers(4)) + off)
    t = np.array([np.cos(theta), np.sin(theta)])
    n = np.array([-t[1], t[0]])
    shift = float(rng.uniform(40, 110)) * min(layout.width_mm, layout.height_mm) / 400.0
    p0 = centre + shift * n
    flap = centre + (shift + 150.0) * n
    step = FoldStep(tuple(p0), tuple(p0 + 100.0 * t), tuple(flap))
    return [step], None, wrinkle, {"line_deg": float(np.degrees(theta)), "shift_mm": shift}


def _crumpled(
    layout: NapkinLayout, rng: np.random.Generator
) -> tuple[list[FoldStep], list[float], float, dict[str, Any]]:
    """Two flaps of two different corners left standing at 60-120 degrees, with smooth
    wrinkles up to 40 mm high on top."""
    u = rng.uniform
    s = min(layout.width_mm, layout.height_mm) / 400.0
    k = int(rng.integers(4))
    first, second = CORNERS[k], CORNERS[(k + int(rng.integers(1, 4))) % 4]
    steps = [
        corner_fold_line(layout, first, float(u(150, 220)) * s, float(u(150, 220)) * s),
        corner_fold_line(layout, second, float(u(130, 190)) * s, float(u(130, 190)) * s),
    ]
    angles = [float(np.radians(u(60, 120))), float(np.radians(u(60, 120)))]
    return steps, angles, float(u(20, 40)), {
        "corners": [first, second], "angles_deg": [float(np.degrees(a)) for a in angles],
    }


def sample_outside(
    kind: str,
    rng: np.random.Generator | int | None = None,
    *,
    layout: NapkinLayout | None = None,
    placement: bool = True,
    spacing_mm: float = 5.0,
) -> ClothState:
    """Draw one state outside the twelve.

    Parameters
    ----------
    kind : str
        One of :data:`OUTSIDE_KINDS`.
    rng : Generator or int, optional
        The only source of randomness.
    layout : NapkinLayout, keyword-only, optional
        Defaults to the packaged layout.
    placement : bool, keyword-only
        Random rotation about the vertical and position, as :func:`.states.sample_state`.
    spacing_mm : float, keyword-only
        Mesh spacing.

    Returns
    -------
    ClothState
        With ``class_id`` :data:`OUTSIDE_LABEL` (``"none"``), ``variant`` None and
        ``params["outside"]`` the kind.
    """
    if kind not in OUTSIDE_KINDS:
        raise InvalidValueError(
            f"unknown kind {kind!r} of state outside the twelve; expected one of "
            f"{', '.join(OUTSIDE_KINDS)}"
        )
    rng = normalize_rng(rng)
    layout = layout or default_layout()
    steps, angles, wrinkle_mm, drawn = _steps(kind, layout, rng)
    params = {"outside": kind, **drawn}
    return make_state(
        OUTSIDE_LABEL,
        None,
        steps,
        layout=layout,
        angles=angles,
        wrinkle_mm=wrinkle_mm,
        yaw=float(rng.uniform(0, 2 * np.pi)) if placement else 0.0,
        offset_m=tuple(rng.uniform(-0.05, 0.05, size=2)) if placement else (0.0, 0.0),
        rng=rng,
        spacing_mm=spacing_mm,
        params=params,
    )
