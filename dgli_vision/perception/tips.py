"""Whether each corner lies where a flat corner would: bare table seen there says the
corner has moved.

A gripper over a corner hides that corner's stickers, and a flat napkin with its corner
under the arm then ranks close to a corner folded away. The cloth next to the arm may
still tell them apart: fitted to the stickers of the napkin that stays (lying flat,
front face up), the flat napkin puts the corner's region at a known place on the table.
Where that region shows bare table (neither cloth nor an object), the corner is not
there.

The region is a band across the corner, inside the smallest fold of the twelve states
(the smallest corner fold has 150 mm legs, a strip 125 mm, on a 400 mm napkin), so every
state that moves a corner clears it, and a state that leaves the corner flat covers it
with cloth. :func:`expected_tip_clear` gives the share of it a state clears (a diagonal
fold clears half of the two corners on its crease).

Only table seen is evidence: a flap held up can stand over its own corner's place, so
cloth seen there says nothing.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ..core.camera import Intrinsics
from ..core.classes import LIFTED_MM
from ..core.fold_lines import fold_for_word, nominal_folds, reflect_uv
from ..core.layout import NapkinLayout
from .params import TipParams
from .rigid import RigidFit, fit_rigid, flat_points_m

__all__ = [
    "TipParams", "corner_tips", "corner_tips_and_pose", "expected_tip_clear",
    "settled_stickers", "stage_tip_clear",
]


@lru_cache(maxsize=64)
def _tip_samples(layout: NapkinLayout, k: int, p: TipParams) -> NDArray[np.float64]:
    """Material points (n, 2), mm, of corner ``k``'s band (read-only: made once per
    layout and corner)."""
    c = layout.corner_uv
    here = c[k]
    e1 = (c[(k + 1) % 4] - here) / np.linalg.norm(c[(k + 1) % 4] - here)
    e2 = (c[(k - 1) % 4] - here) / np.linalg.norm(c[(k - 1) % 4] - here)
    scale = min(layout.fold_scale)
    leg, near = p.leg_mm * scale, p.near_mm * scale
    s = np.arange(p.inset_mm, leg, p.step_mm)
    a, b = np.meshgrid(s, s)
    keep = ((a + b) <= leg) & ((a + b) >= near)
    q = here + a[keep][:, None] * e1 + b[keep][:, None] * e2
    q.flags.writeable = False
    return q


@lru_cache(maxsize=512)
def expected_tip_clear(
    class_id: str, variant: str | None, layout: NapkinLayout, params: TipParams | None = None
) -> tuple[float, ...]:
    """The share of each corner's band a state leaves bare table: on a flap's side of
    one of its folds and not under a flap laid down (its nominal folds).

    Parameters
    ----------
    class_id : str
    variant : str or None
    layout : NapkinLayout
    params : TipParams, optional

    Returns
    -------
    tuple of 4 float
        Corners A-D, each in [0, 1].
    """
    p = params or TipParams()
    folds = nominal_folds(class_id, variant, layout)
    size = np.array([layout.width_mm, layout.height_mm])
    # the four bands at once (each point is judged on its own), then each band's share
    bands = [_tip_samples(layout, k, p) for k in range(len(layout.corner_uv))]
    q = np.concatenate(bands)
    clear = np.zeros(len(q), dtype=bool)
    for f in folds:
        clear |= f.on_flap(q, 2.0)
    for f in folds:  # a flap laid down over the place covers it again
        src = reflect_uv(q, f)
        inside = np.all((src >= 0) & (src <= size), axis=1)
        clear &= ~(inside & f.on_flap(src, 2.0))
    ends = np.cumsum([len(b) for b in bands])
    return tuple(float(part.mean()) for part in np.split(clear, ends[:-1]))


def stage_tip_clear(
    class_id: str, variant: str | None, stage: str, layout: NapkinLayout
) -> tuple[float, ...]:
    """:func:`expected_tip_clear` of a reference with a fold in progress (its ``stage``,
    ``"rising A over, 50-90 deg"``): the corners that fold moves may show their place
    bare as well (a flap standing up clears its corner's place, in part)."""
    base = list(expected_tip_clear(class_id, variant, layout))
    if stage:
        word = stage.split(",")[0].split(" ", 1)[1]
        for name in _moved_corners(word, class_id, layout):
            base[layout.corner_names.index(name)] = 1.0
    return tuple(base)


@lru_cache(maxsize=256)
def _moved_corners(word: str, class_id: str, layout: NapkinLayout) -> tuple[str, ...]:
    """The corners the fold ``word`` of class ``class_id`` moves (the references share a
    few dozen folds: each is made once)."""
    return fold_for_word(word, class_id, layout).moved_corners


def _lying(
    points: NDArray[np.float64],
    heights_mm: NDArray[np.float64],
    turns: NDArray[np.float64] | None,
    layout: NapkinLayout,
) -> NDArray[np.bool_]:
    """The located stickers lying on the table (below ``LIFTED_MM``), leaving out the
    corners whose ``turns`` say they show their back face (on a flap), shape (16,)."""
    found = np.isfinite(points).all(axis=1)
    lying = found & (np.asarray(heights_mm) < LIFTED_MM)  # (NaN: not lying)
    if turns is not None:
        lying &= np.asarray(turns)[layout.sticker_corners] >= 0
    return lying


def _stay_fit(
    points: NDArray[np.float64],
    lying: NDArray[np.bool_],
    layout: NapkinLayout,
    up: NDArray[np.float64],
    p: TipParams,
) -> RigidFit | None:
    """The rigid map of the napkin that stays, fitted to the ``lying`` stickers
    (:func:`.rigid.fit_rigid`): at least three, spanning two corners (a far corner's
    place is then interpolated, not extrapolated from one corner's stickers 80 mm
    apart), front face up (every flap folded over lies face down, and a flap folded
    under is out of sight); None otherwise."""
    fit = fit_rigid(flat_points_m(layout), points, lying, p.fit_tolerance_mm * 1e-3)
    if fit is None or fit.corners_spanned(layout.sticker_corners) < 2:
        return None
    if fit.face_cos(up) < p.min_face_cos:
        return None
    return fit


def settled_stickers(
    points: NDArray[np.float64],
    heights_mm: NDArray[np.float64],
    turns: NDArray[np.float64] | None,
    layout: NapkinLayout,
    up: NDArray[np.float64],
    params: TipParams | None = None,
    *,
    pose: RigidFit | None = None,
) -> NDArray[np.bool_]:
    """Stickers whose place a sticker beside them tells: one of the two stickers along the
    same edge of a corner lies at its flat place, an inlier of the rigid fit of the
    napkin that stays (front face up) fitted with stickers of two other corners.

    Every fold of the twelve states moves both stickers of such a pair or neither: a
    corner fold (legs of 150 mm or more) and a strip (125 mm or more) take every sticker
    of the corner (within 100 mm of its tip along an edge, 20 mm in), and a diagonal
    crease through the corner leaves each edge's pair on one side. So the other sticker
    of the pair lies flat at its place too, seen or not.

    ``pose``: the napkin's pose fitted to the same stickers before
    (:func:`corner_tips_and_pose`), not fitted again; None: fitted here.

    Returns
    -------
    ndarray of bool, shape (16,)
        True for both stickers of each pair with one at its flat place.
    """
    p = params or TipParams()
    corner_of = layout.sticker_corners
    # (a fit whose inliers span fewer than two corners settles none: each inlier needs
    # two other corners' inliers beside it)
    fit = pose
    if fit is None:
        fit = _stay_fit(points, _lying(points, heights_mm, turns, layout), layout, up, p)
    out = np.zeros(len(points), dtype=bool)
    if fit is None:
        return out
    inliers = fit.inliers
    pair = _edge_pairs(layout)
    for k in np.flatnonzero(inliers):
        others = set(corner_of[inliers & (corner_of != corner_of[k])].tolist())
        if len(others) >= 2:
            out |= pair == pair[k]
    return out


def _edge_pairs(layout: NapkinLayout) -> NDArray[np.int64]:
    """Each sticker's pair (the stickers along the same edge of the same corner), as
    2 * corner + the edge (0: the one its u runs along)."""
    corner_of = layout.sticker_corners
    gap = np.abs(layout.sticker_uv - layout.corner_uv[corner_of])
    return 2 * corner_of + (gap[:, 0] < gap[:, 1]).astype(np.int64)


def corner_tips(
    points: NDArray[np.float64],
    heights_mm: NDArray[np.float64],
    unknown: NDArray[np.bool_],
    held_up: NDArray[np.bool_],
    turns: NDArray[np.float64] | None,
    layout: NapkinLayout,
    intrinsics: Intrinsics,
    up: NDArray[np.float64],
    cloth: NDArray[np.bool_] | None,
    cell_px: int,
    objects: NDArray[np.bool_] | None,
    stride: int,
    params: TipParams | None = None,
) -> NDArray[np.float64]:
    """The share of each corner's band seen as bare table
    (:func:`corner_tips_and_pose` without the pose)."""
    return corner_tips_and_pose(
        points, heights_mm, unknown, held_up, turns, layout, intrinsics, up, cloth,
        cell_px, objects, stride, params,
    )[0]


def corner_tips_and_pose(
    points: NDArray[np.float64],
    heights_mm: NDArray[np.float64],
    unknown: NDArray[np.bool_],
    held_up: NDArray[np.bool_],
    turns: NDArray[np.float64] | None,
    layout: NapkinLayout,
    intrinsics: Intrinsics,
    up: NDArray[np.float64],
    cloth: NDArray[np.bool_] | None,
    cell_px: int,
    objects: NDArray[np.bool_] | None,
    stride: int,
    params: TipParams | None = None,
) -> tuple[NDArray[np.float64], RigidFit | None]:
    """The share of each corner's band seen as bare table, where it can be told, and the
    napkin's pose it was told with (None where none was fitted: no corner to tell, or
    no fit), for :func:`settled_stickers` of the same frame.

    A corner is told when fewer than two of its stickers were located (else they tell
    more) and one of the others is unknown, none may be on cloth held up, the napkin
    that stays (the stickers lying flat, front face up) fits rigidly, and at least
    ``params.min_table_share`` of the band's samples show table.

    Parameters
    ----------
    points : ndarray, shape (16, 3)
        Located stickers, camera frame, metres; NaN where not located.
    heights_mm : ndarray, shape (16,)
        Their heights above the table.
    unknown : ndarray of bool, shape (16,)
        Missing stickers not known to be under cloth: only a corner with one is looked
        at (a corner whose stickers lie under a fold is told by that).
    held_up : ndarray of bool, shape (16,)
        Missing stickers that may lie on cloth held up.
    turns : ndarray, shape (4,) or None
        Each corner's face towards the camera (+1 front, -1 back, 0 not told): corners
        showing their back lie on a flap and are left out of the fit.
    layout : NapkinLayout
    intrinsics : Intrinsics
    up : ndarray, shape (3,)
        The table's unit normal towards the camera.
    cloth : ndarray of bool, shape (H // cell_px, W // cell_px) or None
        Cells of cloth (the napkin's footprint and any other white region); None:
        nothing is told.
    cell_px : int
    objects : ndarray of bool, shape (H // stride + 1, W // stride + 1) or None
        Objects above the table.
    stride : int
    params : TipParams, optional

    Returns
    -------
    tips : ndarray, shape (4,)
        Corners A-D: share of the band seen as table among its samples seen as table or
        cloth; NaN where not told.
    pose : RigidFit or None
        The rigid fit of the napkin that stays, when one was made.
    """
    import cv2

    p = params or TipParams()
    out = np.full(len(layout.corner_uv), np.nan)
    if cloth is None:
        return out, None
    found = np.isfinite(points).all(axis=1)
    lying = _lying(points, heights_mm, turns, layout)
    todo = _corners_to_tell(layout.sticker_corners, found, lying, unknown, held_up, len(out))
    fit = _stay_fit(points, lying, layout, up, p) if todo else None
    if fit is None:
        return out, None
    r, t = fit.rotation, fit.translation
    near_objects = None
    if objects is not None and objects.any():
        near_objects = cv2.dilate(objects.view(np.uint8), np.ones((5, 5), np.uint8)).view(bool)
    for k in todo:
        uv = _tip_samples(layout, k, p)
        px = intrinsics.project(np.column_stack([uv * 1e-3, np.zeros(len(uv))]) @ r.T + t)
        out[k] = _table_share(px, cloth, cell_px, near_objects, stride, p.min_table_share)
    return out, fit


def _corners_to_tell(
    corner_of: NDArray[np.intp],
    found: NDArray[np.bool_],
    lying: NDArray[np.bool_],
    unknown: NDArray[np.bool_],
    held_up: NDArray[np.bool_],
    n_corners: int,
) -> list[int]:
    """The corners with fewer than two stickers located, one unknown, and none held up
    or standing (:func:`corner_tips`)."""

    def per_corner(which: NDArray[np.bool_]) -> NDArray[np.intp]:
        return np.bincount(corner_of[which], minlength=n_corners)

    return np.flatnonzero(
        (per_corner(found) < 2)
        & (per_corner(np.asarray(unknown, dtype=bool)) > 0)
        & (per_corner(np.asarray(held_up, dtype=bool) | (found & ~lying)) == 0)
    ).tolist()


def _table_share(
    px: NDArray[np.float64],
    cloth: NDArray[np.bool_],
    cell_px: int,
    near_objects: NDArray[np.bool_] | None,
    stride: int,
    min_share: float,
) -> float:
    """The share of a corner's band samples (pixels ``px``, (n, 2)) seen as table among
    those seen as table or cloth; NaN with fewer than ``min_share`` of them on table.
    ``near_objects``: objects above the table grown by two samples (None: none)."""
    h, w = cloth.shape
    ok = np.isfinite(px).all(axis=1)
    cx = np.where(ok, px[:, 0], -1.0) // cell_px
    cy = np.where(ok, px[:, 1], -1.0) // cell_px
    inview = (cx >= 0) & (cy >= 0) & (cx < w) & (cy < h)
    cxi, cyi = np.clip(cx, 0, w - 1).astype(int), np.clip(cy, 0, h - 1).astype(int)
    is_cloth = inview & cloth[cyi, cxi]
    is_object = np.zeros(len(px), dtype=bool)
    if near_objects is not None:
        gy, gx = near_objects.shape
        oy = np.clip(np.round(np.where(ok, px[:, 1], 0) / stride).astype(int), 0, gy - 1)
        ox = np.clip(np.round(np.where(ok, px[:, 0], 0) / stride).astype(int), 0, gx - 1)
        is_object = inview & ~is_cloth & near_objects[oy, ox]
    table = inview & ~is_cloth & ~is_object
    if table.sum() >= min_share * len(px):
        return float(table.sum() / (table.sum() + is_cloth.sum()))
    return float("nan")
