"""Is the napkin in any of the twelve states at all? The checks that need no verdict.

Three things a napkin shows that no state of the twelve does, whatever the nearest
reference is:

* **Crumpled** (:func:`crumpled_problem`): stickers stand well above the table
  (:data:`CRUMPLE_HEIGHT_MM`) and no one flap held up explains them. A fold in progress
  lifts one flap, a rigid turn of the flat napkin about its crease: its raised stickers
  keep their printed distances as one rigid body and belong to one corner, one side, or
  one corner with halves of its neighbours (a diagonal). Raised stickers (seen, or held
  up out of sight) that no one such flap holds, or that no rigid turn of the flat napkin
  places within :data:`ONE_FLAP_RMS_MM`, or that stand beside no part lying flat
  (:data:`NO_FLAT_MM`), are cloth in a heap: the state a robot must flatten first.
* **Too little cloth** (:func:`footprint_problem_below`): the cloth covers less of the
  table than any state's references allow (a napkin folded in quarters covers a quarter
  of its area, the smallest of the twelve a half).
* **A corner folded apart** (:func:`folded_apart_problem`): a corner's stickers lie far
  off their printed distances from each other, beyond what an uncorrected lens does at
  the image border (:data:`FOLDED_APART`): a crease runs between them, which no state of
  the twelve has (their creases pass 20 mm and more from every corner's stickers, but
  for a diagonal fold's two corners on the crease).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from ..core.classes import CORNERS, LIFTED_MM
from ..core.layout import CORNER_STICKERS, NapkinLayout
from ..perception.footprint import Footprint
from .fold_geometry import plane_basis
from .references import ReferenceSet
from .state_fit import moving_flaps, unexplained_in_the_air

__all__ = [
    "CRUMPLE_HEIGHT_MM",
    "FOLDED_APART",
    "NO_FLAT_MM",
    "ONE_FLAP_RMS_MM",
    "SMALLEST_FOOTPRINT_MARGIN",
    "crumpled_problem",
    "diagonal_crease_stretch",
    "folded_apart_problem",
    "footprint_problem_below",
]

#: A sticker this high above the table (mm) stands "well above" it: above a fold's
#: layers and wrinkles (under 10 mm), and above the 20 mm of a flap just lifted.
CRUMPLE_HEIGHT_MM = 30.0
#: The raised stickers of one flap held up keep their printed distances: a rigid turn of
#: the flat napkin places them within this RMS (mm). The twelve states' folds in
#: progress, grasped corners and settling flaps give under 3 mm in renders; a flap
#: sagging under its own weight bends a little, so the bound is generous. Two flaps at
#: different angles leave 19-40 mm.
ONE_FLAP_RMS_MM = 12.0
#: The stickers not in the air (at most ``LIFTED_MM`` up) of a napkin in a state lie flat:
#: their median height is a few mm (wrinkles reach 10 mm, but not under most stickers;
#: the twelve states' renders give at most 3.3 mm). Above this (mm), with at least
#: :data:`MIN_REST` of them seen, no part of the napkin lies flat.
NO_FLAT_MM = 8.0
MIN_REST = 4
#: Footprint (fraction of the napkin's area) below the smallest of every reference's
#: range that rules out every state: the measurement's error is 2-5%.
SMALLEST_FOOTPRINT_MARGIN = 0.1
#: A corner's stickers this far (relative) off their printed distances are folded
#: apart: an uncorrected lens stretches a corner at the image border by 5-8%, a crease
#: between its stickers by 15% and more.
FOLDED_APART = 0.15

def _rigid_rms(src: NDArray[np.float64], dst: NDArray[np.float64]) -> float:
    """RMS distance (same units) of the best proper rigid map of ``src`` (k, 3) onto
    ``dst`` (k, 3)."""
    sc, dc = src - src.mean(axis=0), dst - dst.mean(axis=0)
    u, _, vt = np.linalg.svd(sc.T @ dc)
    d = 1.0 if np.linalg.det(u @ vt) > 0 else -1.0
    rot = (u @ np.diag([1.0, 1.0, d]) @ vt).T
    return float(np.sqrt(np.mean(np.sum((sc @ rot.T - dc) ** 2, axis=1))))


def crumpled_problem(obs: object, layout: NapkinLayout) -> str | None:
    """Why the napkin is crumpled (see the module's description), or None.

    Parameters
    ----------
    obs : ClothObservation
        Its ``points_m``, ``visible``, ``heights_mm`` and ``up``.
    layout : NapkinLayout

    Returns
    -------
    str or None
        ``"crumpled: stickers 3, 8 and 12 stand 40-95 mm above the table, ..."``;
        the caller prefixes ``"cannot tell: "``.
    """
    pts, h = getattr(obs, "points_m", None), getattr(obs, "heights_mm", None)
    if pts is None or h is None:
        return None
    seen = np.asarray(obs.visible, dtype=bool) & np.isfinite(pts).all(axis=1)
    raised = seen & (np.nan_to_num(h) > CRUMPLE_HEIGHT_MM)
    ids = np.flatnonzero(raised)
    if len(ids) < 2:
        return None
    rms = math.nan
    if len(ids) >= 3:
        uv = np.asarray(layout.sticker_uv, dtype=float)[ids]
        flat = np.column_stack([uv, np.zeros(len(ids))])
        plane = (pts[ids] @ plane_basis(obs.up).T) * 1e3
        seen_3d = np.column_stack([plane, h[ids]])
        rms = _rigid_rms(flat, seen_3d)
    held = np.nan_to_num(obs.lifted) > 0.5 if obs.lifted is not None else ~seen & False
    up = seen & (np.nan_to_num(h) > LIFTED_MM)
    one_flap = not unexplained_in_the_air(up, held & ~seen, moving_flaps("01", None, layout))[0]
    rest = h[seen & ~up]
    flat_part = len(rest) < MIN_REST or float(np.median(rest)) <= NO_FLAT_MM
    if one_flap and not rms > ONE_FLAP_RMS_MM and flat_part:
        return None
    listed = ", ".join(str(i) for i in ids[:-1]) + f" and {ids[-1]}"
    lo, hi = float(np.min(h[ids])), float(np.max(h[ids]))
    if not one_flap:
        why = "on no one flap that a fold lifts (a corner, a side or a diagonal's)"
    elif not flat_part:
        why = f"and no part lies flat (the others stand {float(np.median(rest)):.0f} mm up)"
    else:
        why = f"which no one flap held up places (a rigid turn leaves them {rms:.0f} mm off)"
    return (
        f"crumpled: stickers {listed} stand {lo:.0f}-{hi:.0f} mm above the table, {why}; "
        "flatten the napkin first"
    )


def footprint_problem_below(
    footprint: Footprint | None, references: ReferenceSet, napkin_area_mm2: float
) -> str | None:
    """Why the cloth covers too little of the table for any state (see the module's
    description), or None; the caller prefixes ``"cannot tell: no known state fits: "``."""
    if footprint is None:
        return None
    _, hi = footprint.fraction(napkin_area_mm2)
    ranges = references.footprint_ranges()
    if not np.isfinite(hi) or not np.isfinite(ranges[:, 0]).any():
        return None
    smallest = float(np.nanmin(ranges[:, 0]))
    if hi >= smallest - SMALLEST_FOOTPRINT_MARGIN:
        return None
    return (
        f"the cloth covers {100 * hi:.0f}% of the napkin's area, less than any known "
        f"state does (at least {100 * smallest:.0f}%): folded more than the twelve "
        "states are (in quarters?)"
    )


def _corner_stretch(
    obs: object, layout: NapkinLayout
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Each corner's median relative distance of its sticker pairs' 3D distances from
    their printed ones (at the napkin's measured scale), shape (4,), NaN for a corner
    with fewer than three stickers seen; and whether a crease along the corner's
    diagonal explains it (the pairs on one side of the diagonal keep their distances),
    shape (4,)."""
    from .consistency import RIGIDITY_TOLERANCE

    out = np.full(len(CORNERS), np.nan)
    diagonal = np.zeros(len(CORNERS), dtype=bool)
    pts = getattr(obs, "points_m", None)
    ruler = getattr(obs, "ruler", None)
    if pts is None or ruler is None or not ruler.scale > 0:
        return out, diagonal
    uv = np.asarray(layout.sticker_uv, dtype=float)
    corner_uv = np.asarray(layout.corner_uv, dtype=float)
    seen = np.asarray(obs.visible, dtype=bool) & np.isfinite(pts).all(axis=1)
    for k, ids in enumerate(CORNER_STICKERS):
        ids = np.asarray([i for i in ids if seen[i]])
        if len(ids) < 3:
            continue
        i, j = np.triu_indices(len(ids), 1)
        a, b = ids[i], ids[j]
        flat = np.linalg.norm(uv[a] - uv[b], axis=1)
        got = np.linalg.norm(pts[a] - pts[b], axis=1) * 1e3 / ruler.scale
        off = np.abs(got / flat - 1.0)
        out[k] = float(np.median(off))
        d = corner_uv[(k + 2) % 4] - corner_uv[k]
        rel = uv[ids] - corner_uv[k]
        side = np.sign(d[0] * rel[:, 1] - d[1] * rel[:, 0])  # (the stickers never lie on it)
        same = side[i] == side[j]
        diagonal[k] = bool(np.all(off[same] <= RIGIDITY_TOLERANCE))
    return out, diagonal


def _diagonal_only(apart: NDArray[np.intp], diagonal: NDArray[np.bool_]) -> bool:
    """Whether the corners ``apart`` are one corner, or two opposite ones, that a crease
    along the diagonal explains."""
    return bool(
        len(apart) and np.all(diagonal[apart])
        and (len(apart) == 1 or (len(apart) == 2 and (apart[0] + 2) % 4 == apart[1]))
    )


def diagonal_crease_stretch(obs: object, layout: NapkinLayout) -> bool:
    """Whether the corners whose stickers do not keep their printed distances (beyond the
    rigidity check's tolerance) are those a diagonal fold's crease cuts: one corner, or
    two opposite ones, whose stickers on either side of its diagonal keep theirs. Such
    a frame is left to the state fit: a diagonal fold explains it, or no state does."""
    from .consistency import RIGIDITY_TOLERANCE

    stretch, diagonal = _corner_stretch(obs, layout)
    return _diagonal_only(np.flatnonzero(np.nan_to_num(stretch) > RIGIDITY_TOLERANCE), diagonal)


def folded_apart_problem(obs: object, layout: NapkinLayout, *, lens_possible: bool) -> str | None:
    """Why some corner's stickers are folded apart (see the module's description), or
    None; the caller prefixes ``"cannot tell: no known state fits: "``.

    A corner is folded apart when its stickers lie :data:`FOLDED_APART` or more off
    their printed distances, or (where no lens can be the cause: ``lens_possible``
    False, no sticker near the image border) beyond the rigidity check's tolerance.
    One corner, or two opposite ones, whose stickers on either side of its diagonal
    keep their distances are a diagonal fold's, whose crease runs beside them and may
    cut one: that is left to the rigidity check.
    """
    from .consistency import RIGIDITY_TOLERANCE

    ruler = getattr(obs, "ruler", None)
    if ruler is None or ruler.worst_against_scale <= RIGIDITY_TOLERANCE:
        return None  # every corner keeps its distances (the ruler measured them)
    stretch, diagonal = _corner_stretch(obs, layout)
    limit = FOLDED_APART if lens_possible else RIGIDITY_TOLERANCE
    apart = np.flatnonzero(np.nan_to_num(stretch) > limit)
    if not len(apart):
        return None
    if _diagonal_only(apart, diagonal):
        return None  # a diagonal fold's crease corners
    names = " and ".join(CORNERS[k] for k in apart)
    worst = float(np.nanmax(stretch[apart]))
    lens = (
        "more than a lens bends them" if lens_possible
        else "no sticker lies near the image border, where a lens bends them"
    )
    return (
        f"corner {names}'s stickers lie {100 * worst:.0f}% off their printed distances "
        f"from each other ({lens}): a crease runs between them, which no known state has"
    )
