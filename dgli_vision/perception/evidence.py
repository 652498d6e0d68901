"""What a missing sticker says: hidden by the cloth (evidence of a fold), or unknown.

A sticker the detector did not find is evidence of a fold only when the cloth itself can
be what hides it. Where the napkin lies flat and rigid, the stickers that were found tell
where a missing one would be (a rigid fit from material to camera coordinates: folding
is isometric). If that place is out of view, under an object above the napkin, or in a
highlight, the sticker is *unknown*: the classifier ignores it. Otherwise it is *hidden*.

Before that, the located stickers are checked against the napkin's size: folding never
stretches cloth, so two stickers can never be farther apart in 3D than on the flat
napkin. A sticker that breaks this with others is a false detection and is dropped.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

from ..camera import Intrinsics
from ..layout import NapkinLayout
from .lift import Markers3D
from .napkin import NapkinView

__all__ = [
    "HELD_UP",
    "HIDDEN",
    "SEEN",
    "UNKNOWN",
    "WASHED_OUT",
    "EvidenceParams",
    "StickerEvidence",
    "assess_stickers",
    "drop_inconsistent",
]

SEEN, HIDDEN, UNKNOWN = 1, 0, -1
#: Why a sticker is unknown when it may be on a flap held up steeply.
HELD_UP = "possibly on cloth held up (seen edge-on)"
#: Why a sticker is unknown when pastel sticker colour lies where it should be.
WASHED_OUT = "possibly washed out by a sheen"


@dataclass(frozen=True)
class EvidenceParams:
    """How missing stickers are judged. Every field has a unit and a reason.

    Attributes
    ----------
    stretch_tolerance_mm : float
        How much farther apart two located stickers may be in 3D than on the flat napkin
        before one of them is a false detection. Default 15 mm: sticker centres are
        found to about 1 mm in x, y and a few mm in depth; wrinkles shorten distances.
    fit_tolerance_mm : float
        Residual of a sticker under a rigid fit for it to lie on the same flat part of
        the cloth. Default 10 mm: wrinkles are up to about 10 mm out of plane.
    napkin_margin_mm : float
        How near the napkin, in the image, an object above the table must come to be
        over it. Default 15 mm: the napkin's own outline is found to a sample or two, and
        an object set down beside the napkin keeps farther off.
    near_radii : float
        How close, in sticker radii, a missing sticker's predicted place must come to a
        highlight, an object or the image border to be unknown. Default 1.5: the
        prediction is good to a few millimetres, and half a sticker covered is enough to
        lose it.
    min_corner_support : int
        With an object over the napkin, a missing sticker is unknown unless at least this
        many stickers of its corner were seen. Default 3: a corner folded over moves its
        four stickers together, and three of them fix where the fourth lies; with fewer,
        its flap may lie under the object, if the object comes within
        ``flap_reach_mm`` of the sticker's flat place.
    flap_reach_mm : float
        How far from its flat place a corner folded over lays its stickers, at most, for
        :attr:`min_corner_support`. Default 250 mm.
    held_up_reach : float
        How near cloth held up (a flap being folded) must come to the place a missing
        sticker would have lying flat, as a fraction of the napkin's shorter side, for
        the sticker to be possibly on it, seen edge-on. Default 0.5: a flap turns about
        its fold line, and no sticker lies farther from a fold line than half the napkin.
    cover_mm : float
        How much higher than the napkin around it the surface over a missing sticker's
        flat place must stand for the sticker to be under a layer held above it (not on
        the raised flap itself). Default 12 mm: above wrinkles and a folded layer.
    steep_foreshortening : float
        A sticker seen more foreshortened than this (minor / major axis) lies on cloth
        held up steeply. Default 0.6 (53 degrees from flat): a flap turned past 120
        degrees lies over the napkin at a gentle angle and shows its stickers better.
    """

    stretch_tolerance_mm: float = 15.0
    fit_tolerance_mm: float = 10.0
    napkin_margin_mm: float = 15.0
    near_radii: float = 1.5
    min_corner_support: int = 3
    flap_reach_mm: float = 150.0
    held_up_reach: float = 0.5
    cover_mm: float = 12.0
    steep_foreshortening: float = 0.6


@dataclass(frozen=True, eq=False)
class StickerEvidence:
    """The state of each sticker.

    Attributes
    ----------
    status : ndarray of int8, shape (16,)
        :data:`SEEN`, :data:`HIDDEN` (evidence of cloth on top) or :data:`UNKNOWN`.
    reasons : tuple of str or None, length 16
        Why a sticker is unknown (or was dropped).
    predicted_px : ndarray, shape (16, 2)
        Where a missing sticker would be if its part of the cloth lay as the rest,
        pixels; NaN where that cannot be told.
    occluded : bool
        Something that is not napkin stands over the napkin.
    near_object : ndarray of bool, shape (16,), optional
        Missing stickers whose place may lie under that object (their reason may still be
        cloth held up, which tells more when the flap's lean is measured).
    """

    status: NDArray[np.int8]
    reasons: tuple[str | None, ...]
    predicted_px: NDArray[np.float64]
    occluded: bool = False
    near_object: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(16, dtype=bool))

    @property
    def seen(self) -> NDArray[np.bool_]:
        """Stickers located, shape (16,)."""
        return self.status == SEEN

    @property
    def unknown(self) -> NDArray[np.bool_]:
        """Stickers neither seen nor evidence of a fold, shape (16,)."""
        return self.status == UNKNOWN

    def summary(self) -> str:
        """``"2 stickers under an object above the napkin, 1 in a highlight"`` or ``""``."""
        counts: dict[str, int] = {}
        for st, why in zip(self.status, self.reasons):
            if st == UNKNOWN and why:
                counts[why] = counts.get(why, 0) + 1
        return ", ".join(f"{k} sticker{'s' if k > 1 else ''} {why}" for why, k in counts.items())


def drop_inconsistent(
    markers: Markers3D, layout: NapkinLayout, params: EvidenceParams | None = None
) -> tuple[Markers3D, NDArray[np.bool_]]:
    """Drop located stickers that are farther from others than the flat napkin allows.

    Returns
    -------
    markers : Markers3D
        Without the dropped stickers.
    dropped : ndarray of bool, shape (16,)
    """
    p = params or EvidenceParams()
    pts = markers.points.copy()
    found = markers.found.copy()
    uv = layout.sticker_uv
    flat_mm = np.linalg.norm(uv[:, None] - uv[None], axis=2)
    dropped = np.zeros(len(pts), dtype=bool)
    while found.sum() > 2:
        d3 = np.linalg.norm(pts[:, None] - pts[None], axis=2) * 1e3
        bad = (d3 > flat_mm + p.stretch_tolerance_mm) & found[:, None] & found[None]
        counts = bad.sum(axis=1)
        if counts.max() == 0:
            break
        worst = int(np.argmax(counts))
        found[worst] = False
        dropped[worst] = True
        pts[worst] = np.nan
    return Markers3D(pts), dropped


def _kabsch(src: NDArray, dst: NDArray) -> tuple[NDArray, NDArray]:
    """Rotations R (..., 3, 3) and translations t (..., 3) with dst ~ src @ R.T + t, in
    the least-squares sense, for stacks of point sets src, dst (..., k, 3)."""
    cs, cd = src.mean(axis=-2, keepdims=True), dst.mean(axis=-2, keepdims=True)
    cov = np.swapaxes(src - cs, -1, -2) @ (dst - cd)
    u, _, vt = np.linalg.svd(cov)
    d = np.sign(np.linalg.det(u @ vt))
    fix = np.ones(u.shape[:-1])
    fix[..., -1] = d
    r = np.swapaxes((u * fix[..., None, :]) @ vt, -1, -2)
    t = cd[..., 0, :] - (cs @ np.swapaxes(r, -1, -2))[..., 0, :]
    return r, t


def _rigid_prediction(
    uv_m: NDArray, pts: NDArray, use: NDArray[np.bool_], tol_m: float
) -> tuple[NDArray, NDArray[np.bool_]] | None:
    """Best rigid map of the material points of ``use`` onto their 3D points (all
    triples tried at once, RANSAC-style); returns (predicted 3D points of every sticker,
    inliers) or None."""
    ids = np.flatnonzero(use)
    if ids.size < 3:
        return None
    triples = np.array(list(combinations(ids, 3)))  # (T, 3)
    a, b, c = (uv_m[triples[:, k]] for k in range(3))
    area = np.abs(np.cross(b - a, c - a)[:, 2])
    triples = triples[area > 1e-4]  # not nearly collinear (m^2)
    if len(triples) == 0:
        return None
    r, t = _kabsch(uv_m[triples], pts[triples])  # (T, 3, 3), (T, 3)
    pred = np.einsum("tij,nj->tni", r, uv_m[ids]) + t[:, None, :]
    inl = np.linalg.norm(pred - pts[ids][None], axis=2) < tol_m  # (T, n)
    best = inl[int(np.argmax(inl.sum(axis=1)))]
    if best.sum() < 3:
        return None
    r1, t1 = _kabsch(uv_m[ids[best]], pts[ids[best]])
    mask = np.zeros(len(pts), dtype=bool)
    mask[ids[best]] = True
    return uv_m @ r1.T + t1, mask


def _without_stickers(
    napkin: NapkinView, located: NDArray, intrinsics: Intrinsics, radius_px: float
) -> NapkinView:
    """The napkin view with the located stickers taken out of its object mask: a
    sticker on a flap held up is a raised, coloured patch, not an object."""
    import dataclasses

    if not napkin.occluder.any() or not len(located):
        return napkin
    hh, ww = napkin.occluder.shape
    vs, us = np.mgrid[0:hh, 0:ww] * napkin.stride
    mine = np.zeros((hh, ww), dtype=bool)
    for u, v in intrinsics.project(located):
        mine |= np.hypot(us - u, vs - v) <= radius_px + napkin.stride
    return dataclasses.replace(napkin, occluder=napkin.occluder & ~mine)


def _over_napkin(
    napkin: NapkinView, margin_mm: float, located: NDArray, intrinsics: Intrinsics
) -> bool:
    """Does an object above the table touch the napkin in the image (or stand within
    the outline of the located stickers)?"""
    import cv2

    if not napkin.occluder.any():
        return False
    if napkin.cloth is not None:
        z = float(np.nanmedian(located[:, 2])) if len(located) else 0.6
        reach = max(1, round(margin_mm * 1e-3 * intrinsics.fx / z / napkin.stride))
        kernel = np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)
        near_cloth = cv2.dilate(napkin.cloth.astype(np.uint8), kernel).astype(bool)
        if (near_cloth & napkin.occluder).any():
            return True
    if len(located) < 3:
        return False
    hull = cv2.convexHull(intrinsics.project(located).astype(np.float32))
    vs, us = np.nonzero(napkin.occluder)
    return any(
        cv2.pointPolygonTest(hull, (float(u * napkin.stride), float(v * napkin.stride)), False)
        >= 0
        for u, v in zip(us, vs)
    )


def _sample_height(napkin: NapkinView, uv: NDArray) -> NDArray[np.float64]:
    """Median height above the table (mm) of the 3 x 3 mask samples around pixels
    ``uv`` (n, 2); NaN where there is no reading."""
    assert napkin.height_mm is not None
    hgt = napkin.height_mm
    out = np.full(len(uv), np.nan)
    for k, (u, v) in enumerate(np.asarray(uv, dtype=np.float64)):
        if not (np.isfinite(u) and np.isfinite(v)):
            continue
        i, j = round(v / napkin.stride), round(u / napkin.stride)
        win = hgt[max(i - 1, 0) : i + 2, max(j - 1, 0) : j + 2]
        if win.size and np.isfinite(win).any():
            out[k] = float(np.nanmedian(win))
    return out


def _covered_from_above(
    napkin: NapkinView,
    flat: NDArray,
    up: NDArray,
    intrinsics: Intrinsics,
    min_mm: float,
    top_mm: float,
) -> NDArray[np.bool_]:
    """Which 3D points ``flat`` (n, 3) on the table have cloth straight above them,
    higher than ``min_mm``: some height sample where a point ``H`` above them images
    reads ``H`` (to half a step). A flap standing beside the point, in front of it for
    the camera, reads another height there."""
    out = np.zeros(len(flat), dtype=bool)
    ok = np.isfinite(flat).all(axis=1)
    step = 10.0
    for height in np.arange(min_mm, top_mm + step, step):
        above = flat[ok] + height * 1e-3 * up
        seen = _sample_height(napkin, intrinsics.project(above))
        out[ok] |= np.isfinite(seen) & (np.abs(seen - height) <= step / 2)
    return out


def _held_up(
    napkin: NapkinView | None,
    predicted: NDArray,
    missing: NDArray,
    located: NDArray,
    steep: NDArray[np.bool_],
    intrinsics: Intrinsics,
    layout: NapkinLayout,
    p: EvidenceParams,
    z_typ: float,
    flat3d: NDArray | None = None,
    up: NDArray | None = None,
) -> NDArray[np.bool_]:
    """Which missing stickers may be on a flap held up steeply, seen edge-on.

    A patch of cloth held up above the table is *steep* when a sticker seen on it is
    strongly foreshortened, or when no sticker is seen on it at all (a flap edge-on
    shows none). A missing sticker near a steep patch, whose flat place has no layer
    hovering over it, may have gone up with its flap: unknown. A flap lying at a gentle
    angle over the napkin shows its stickers face-on, and what is missing under it is
    hidden.

    Parameters
    ----------
    located : ndarray, shape (k, 3)
        The located stickers, camera frame.
    steep : ndarray of bool, shape (k,)
        Which of them are seen strongly foreshortened.
    flat3d : ndarray, shape (16, 3), optional
        Where each sticker would lie flat, camera frame (NaN where not known).
    up : ndarray, shape (3,), optional
        Table normal. With ``flat3d``, a layer over a sticker's flat place is looked for
        straight above it; without, along the camera's ray (where a flap standing in
        front of the place, its own, would count).
    """
    import cv2

    out = np.zeros(len(missing), dtype=bool)
    if napkin is None or napkin.raised is None or not napkin.raised.any():
        return out
    n_parts, parts = cv2.connectedComponents(napkin.raised.astype(np.uint8), connectivity=8)
    steep_parts = np.ones(n_parts, dtype=bool)
    steep_parts[0] = False
    if len(located):
        px = intrinsics.project(located)
        ij = np.rint(px[:, ::-1] / napkin.stride).astype(int)
        gentle = np.zeros(n_parts, dtype=bool)
        for (i, j), is_steep in zip(ij, steep):
            win = parts[max(i - 3, 0) : i + 4, max(j - 3, 0) : j + 4]  # past the sticker
            for lab in np.unique(win[win > 0]):
                if is_steep:
                    gentle[lab] = False
                    steep_parts[lab] = True
                elif steep_parts[lab]:
                    gentle[lab] = True
        steep_parts &= ~gentle
    if not steep_parts.any():
        return out
    steep_mask = steep_parts[parts]
    reach_px = p.held_up_reach * min(layout.width_mm, layout.height_mm) * 1e-3
    reach_px *= intrinsics.fx / z_typ
    where = predicted[missing]
    unplaced = ~np.isfinite(where[:, 0])
    out = napkin.near(steep_mask, where, reach_px) | unplaced
    if napkin.height_mm is not None and len(located):
        base = _sample_height(napkin, intrinsics.project(located))
        ground = float(np.nanmedian(base)) if np.isfinite(base).any() else 0.0
        if flat3d is not None and up is not None:
            top = max(layout.width_mm, layout.height_mm) / 2
            out &= ~_covered_from_above(
                napkin, flat3d[missing], up, intrinsics, ground + p.cover_mm, top
            )
        else:
            over = _sample_height(napkin, where)
            out &= ~(np.isfinite(over) & (over > ground + p.cover_mm))
    return out


def assess_stickers(
    markers: Markers3D,
    intrinsics: Intrinsics,
    layout: NapkinLayout,
    napkin: NapkinView | None,
    *,
    dropped: NDArray[np.bool_] | None = None,
    params: EvidenceParams | None = None,
    foreshortening: NDArray[np.float64] | None = None,
    up: NDArray[np.float64] | None = None,
    pale_colours: tuple[str, ...] = (),
) -> StickerEvidence:
    """Decide, for each sticker, seen, hidden by cloth, or unknown.

    Parameters
    ----------
    markers : Markers3D
        Located stickers (after :func:`drop_inconsistent`).
    intrinsics : Intrinsics
    layout : NapkinLayout
    napkin : NapkinView or None
        Highlights and objects above the table; None: nothing is ever unknown.
    dropped : ndarray of bool, shape (16,), keyword-only, optional
        Stickers dropped as false detections.
    params : EvidenceParams, keyword-only, optional
    foreshortening : ndarray, shape (16,), keyword-only, optional
        How foreshortened each located sticker is (detector); tells a flap held up
        steeply from one lying over the napkin.
    up : ndarray, shape (3,), keyword-only, optional
        Table normal towards the camera: a layer over a missing sticker's flat place is
        then looked for straight above it (see :func:`_held_up`).
    pale_colours : tuple of str, keyword-only
        Sticker colours seen pastel on the napkin where no sticker could be read (the
        detector's ``pale_colours``): a missing sticker with such a disc colour may be
        washed out by a sheen, so it is unknown, not hidden, wherever the rigid
        prediction puts it (a flap moves its stickers).

    Returns
    -------
    StickerEvidence
    """
    p = params or EvidenceParams()
    n = len(markers.points)
    seen = markers.found
    status = np.where(seen, SEEN, HIDDEN).astype(np.int8)
    reasons: list[str | None] = [None] * n
    predicted = np.full((n, 2), np.nan)
    if seen.all():
        return StickerEvidence(status, tuple(reasons), predicted)
    uv_m = np.column_stack([layout.sticker_uv * 1e-3, np.zeros(n)])
    pts = markers.points
    tol = p.fit_tolerance_mm * 1e-3
    corner_of = np.argmin(
        np.linalg.norm(layout.sticker_uv[:, None] - layout.corner_uv[None], axis=2), axis=1
    )
    pred3 = np.full((n, 3), np.nan)
    group_support = np.zeros(n, dtype=int)
    for corner in range(len(layout.corner_uv)):
        group = corner_of == corner
        group_support[group] = int((group & seen).sum())
        if (group & ~seen).any():  # only where something is missing
            fit = _rigid_prediction(uv_m, pts, group & seen, tol)
            if fit is not None:
                pred3[group] = fit[0][group]
    todo = np.isnan(pred3[:, 0]) & ~seen
    if todo.any():
        overall = _rigid_prediction(uv_m, pts, seen, tol)
        # only a flat part that spans corners says where another corner would lie
        if overall is not None and len(set(corner_of[overall[1]])) >= 2:
            pred3[todo] = overall[0][todo]
    ok = np.isfinite(pred3[:, 0]) & (pred3[:, 2] > 0)
    predicted[ok] = intrinsics.project(pred3[ok])
    z_typ = float(np.nanmedian(pts[seen, 2])) if seen.any() else 0.6
    radius_px = p.near_radii * layout.disc_diameter_mm / 2 * 1e-3 * intrinsics.fx / z_typ
    if napkin is not None:
        napkin = _without_stickers(napkin, pts[seen], intrinsics, radius_px)
    occluded = napkin is not None and _over_napkin(
        napkin, p.napkin_margin_mm, pts[seen], intrinsics
    )
    missing = np.flatnonzero(~seen)
    if napkin is not None:
        near_occ = napkin.near(napkin.occluder, predicted[missing], radius_px)
        near_hl = napkin.near(napkin.highlight, predicted[missing], radius_px)
        reach_px = p.flap_reach_mm * 1e-3 * intrinsics.fx / z_typ
        near_flap = napkin.near(napkin.occluder, predicted[missing], reach_px)
        near_flap |= ~np.isfinite(predicted[missing]).all(axis=1)
    else:
        near_occ = near_hl = near_flap = np.zeros(len(missing), dtype=bool)
    fore = foreshortening if foreshortening is not None else np.ones(n)
    steep = np.nan_to_num(fore[seen], nan=1.0) < p.steep_foreshortening
    held_up = _held_up(
        napkin, predicted, missing, pts[seen], steep, intrinsics, layout, p, z_typ,
        pred3 if up is not None else None, up,
    )
    near_object = np.zeros(n, dtype=bool)
    w, h = intrinsics.width, intrinsics.height
    for k, sid in enumerate(missing):
        u, v = predicted[sid]
        poorly_seen = occluded and group_support[sid] < p.min_corner_support
        why = None
        if np.isfinite(u) and not (
            -radius_px <= u <= w - 1 + radius_px and -radius_px <= v <= h - 1 + radius_px
        ):
            why = "out of view"
        elif held_up[k]:  # a flap held up by the object over it tells its lean
            why = HELD_UP
            near_object[sid] = bool(near_occ[k] or (poorly_seen and near_flap[k]))
        elif near_occ[k] or (poorly_seen and near_flap[k]):
            why = "possibly under an object above the napkin"
            near_object[sid] = True
        elif near_hl[k]:
            why = "in a highlight"
        elif layout.sticker_disc[sid] in pale_colours:
            why = WASHED_OUT
        elif dropped is not None and dropped[sid] and np.isnan(u):
            why = "found where the napkin cannot be"
        if why:
            status[sid] = UNKNOWN
            reasons[sid] = why
    return StickerEvidence(status, tuple(reasons), predicted, occluded, near_object)
