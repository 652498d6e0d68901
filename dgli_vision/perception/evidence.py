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
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ..core.camera import Intrinsics
from ..core.layout import NapkinLayout
from ..core.order_stats import nanmedian
from .lift import Markers3D
from .napkin import NapkinMasks, NapkinView
from .params import EvidenceParams
from .rigid import fit_rigid, flat_points_m

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

    @property
    def held_up(self) -> NDArray[np.bool_]:
        """Unknown stickers that may be on cloth held up (:data:`HELD_UP`), shape (16,)."""
        return self.unknown & np.array([why == HELD_UP for why in self.reasons])

    def summary(self) -> str:
        """``"2 stickers under an object above the napkin, 1 in a highlight"`` or ``""``."""
        counts: dict[str, int] = {}
        for st, why in zip(self.status, self.reasons):
            if st == UNKNOWN and why:
                counts[why] = counts.get(why, 0) + 1
        return ", ".join(f"{k} sticker{'s' if k > 1 else ''} {why}" for why, k in counts.items())


@lru_cache(maxsize=32)
def _flat_distances_mm(layout: NapkinLayout) -> NDArray[np.float64]:
    """Distances between every two stickers on the flat napkin, mm, shape (16, 16);
    read-only, once per layout."""
    uv = layout.sticker_uv
    out = np.linalg.norm(uv[:, None] - uv[None], axis=2)
    out.flags.writeable = False
    return out


@lru_cache(maxsize=32)
def _stretch_limit_mm(layout: NapkinLayout, tolerance_mm: float) -> NDArray[np.float64]:
    """The farthest two stickers may lie apart, mm, shape (16, 16): their distance on the
    flat napkin plus ``tolerance_mm``; read-only, once per layout."""
    out = _flat_distances_mm(layout) + tolerance_mm
    out.flags.writeable = False
    return out


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
    limit = _stretch_limit_mm(layout, p.stretch_tolerance_mm)
    dropped = np.zeros(len(pts), dtype=bool)
    while found.sum() > 2:
        diff = pts[:, None] - pts[None]
        d3 = np.sqrt(np.add.reduce(diff * diff, axis=2)) * 1e3  # as np.linalg.norm takes it
        # (a sticker not located has NaN distances, which compare False)
        counts = np.count_nonzero(d3 > limit, axis=1)
        if counts.max() == 0:
            break
        worst = int(np.argmax(counts))
        found[worst] = False
        dropped[worst] = True
        pts[worst] = np.nan
    return Markers3D(pts), dropped


@dataclass(frozen=True, eq=False)
class _Seen:
    """The located stickers, as the judging of the missing ones uses them.

    Attributes
    ----------
    points : ndarray, shape (k, 3)
        Camera frame, metres.
    pixels : ndarray, shape (k, 2)
        Where they image.
    steep : ndarray of bool, shape (k,)
        Seen strongly foreshortened (on cloth held up steeply).
    z_typ : float
        Their median depth, metres (0.6 without any).
    radius_px : float
        ``near_radii`` sticker radii at ``z_typ``, pixels.
    """

    points: NDArray[np.float64]
    pixels: NDArray[np.float64]
    steep: NDArray[np.bool_]
    z_typ: float
    radius_px: float


@dataclass(frozen=True)
class _Near:
    """For each missing sticker (m,), what its predicted place is near: an object (within
    ``radius_px``), a highlight, an object within ``flap_reach_mm`` (or no place)."""

    occluder: NDArray[np.bool_]
    highlight: NDArray[np.bool_]
    flap_reach: NDArray[np.bool_]


def _seen_stickers(
    markers: Markers3D,
    intrinsics: Intrinsics,
    layout: NapkinLayout,
    p: EvidenceParams,
    foreshortening: NDArray[np.float64] | None,
) -> _Seen:
    seen = markers.found
    pts = markers.points[seen]
    z_typ = nanmedian(pts[:, 2]) if seen.any() else 0.6
    radius_px = p.near_radii * layout.disc_diameter_mm / 2 * 1e-3 * intrinsics.fx / z_typ
    fore = foreshortening if foreshortening is not None else np.ones(len(seen))
    steep = np.nan_to_num(fore[seen], nan=1.0) < p.steep_foreshortening
    pixels = intrinsics.project(pts) if len(pts) else np.zeros((0, 2))
    return _Seen(pts, pixels, steep, z_typ, radius_px)


def _predict_missing(
    markers: Markers3D,
    layout: NapkinLayout,
    p: EvidenceParams,
    turns: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Where each missing sticker would be if its part of the cloth lay as the rest
    (camera frame, (16, 3), NaN where that cannot be told), and how many stickers of its
    corner were seen (16,).

    A rigid fit of the stickers seen of its corner, where three or more lie as one;
    else of all the stickers seen, when they span corners (only a flat part that spans
    corners says where another corner would lie), leaving out the corners whose
    ``turns`` say they show their back face (on a flap).
    """
    n = len(markers.points)
    seen = markers.found
    uv_m = flat_points_m(layout)
    pts = markers.points
    tol = p.fit_tolerance_mm * 1e-3
    corner_of = layout.sticker_corners
    pred3 = np.full((n, 3), np.nan)
    group_support = np.zeros(n, dtype=int)
    for corner in range(len(layout.corner_uv)):
        group = corner_of == corner
        group_support[group] = int((group & seen).sum())
        if (group & ~seen).any():  # only where something is missing
            fit = fit_rigid(uv_m, pts, group & seen, tol)
            if fit is not None:
                pred3[group] = fit.predicted[group]
    todo = np.isnan(pred3[:, 0]) & ~seen
    if todo.any():
        # a corner showing its back face lies on a flap: it says nothing of where the
        # napkin's other corners lie flat
        base = seen if turns is None else seen & (np.asarray(turns)[corner_of] >= 0)
        overall = fit_rigid(uv_m, pts, base, tol)
        if overall is not None and overall.corners_spanned(corner_of) >= 2:
            pred3[todo] = overall.predicted[todo]
    return pred3, group_support


def _over_napkin(masks: NapkinMasks, margin_mm: float, seen: _Seen, fx: float) -> bool:
    """Does an object above the table touch the napkin in the image (or stand within
    the outline of the located stickers)?"""
    import cv2

    if not masks.occluder.any():
        return False
    if masks.cloth is not None:
        reach = max(1, round(margin_mm * 1e-3 * fx / seen.z_typ / masks.stride))
        kernel = np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)
        near_cloth = cv2.dilate(masks.cloth.astype(np.uint8), kernel).astype(bool)
        if (near_cloth & masks.occluder).any():
            return True
    if len(seen.points) < 3:
        return False
    hull = cv2.convexHull(seen.pixels.astype(np.float32))
    vs, us = np.nonzero(masks.occluder)
    return any(
        cv2.pointPolygonTest(hull, (float(u * masks.stride), float(v * masks.stride)), False)
        >= 0
        for u, v in zip(us, vs)
    )


def _nearness(
    masks: NapkinMasks | None, where: NDArray, radius_px: float, flap_reach_px: float
) -> _Near:
    """What the predicted places ``where`` (m, 2) of the missing stickers are near."""
    if masks is None:
        none = np.zeros(len(where), dtype=bool)
        return _Near(none, none, none)
    near_flap = masks.near(masks.occluder, where, flap_reach_px)
    near_flap |= ~np.isfinite(where).all(axis=1)
    return _Near(
        masks.near(masks.occluder, where, radius_px),
        masks.near(masks.highlight, where, radius_px),
        near_flap,
    )


def _covered_from_above(
    masks: NapkinMasks,
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
    heights = np.arange(min_mm, top_mm + step, step)
    if not ok.any() or not len(heights):
        return out
    # every height at once: (heights, points) places above the points, projected and
    # read in one call each (point by point, as one height at a time would)
    above = flat[ok][None] + (heights * 1e-3)[:, None, None] * up
    seen = masks.height_at(intrinsics.project(above.reshape(-1, 3))).reshape(above.shape[:2])
    hit = np.isfinite(seen) & (np.abs(seen - heights[:, None]) <= step / 2)
    out[ok] = hit.any(axis=0)
    return out


def _steep_cloth(
    masks: NapkinMasks, seen: _Seen, band: int = 0, min_beyond: int = 1
) -> NDArray[np.bool_] | None:
    """The samples of cloth held up steeply (None if none): the parts of ``raised``
    where a sticker is seen strongly foreshortened, or none is seen at all (a flap
    edge-on shows none). Parts with fewer than ``min_beyond`` samples farther than
    ``band`` samples from an object are left out."""
    import cv2

    assert masks.raised is not None
    n_parts, parts = cv2.connectedComponents(masks.raised.astype(np.uint8), connectivity=8)
    steep_parts = np.ones(n_parts, dtype=bool)
    steep_parts[0] = False
    if masks.occluder.any() and band > 0:
        # raised "cloth" along an object's outline is the depth of its edge blended with
        # the cloth's (flying pixels), or the object's own lit faces, not a flap: a flap
        # reaches well beyond the object that holds it
        k = np.ones((2 * band + 1, 2 * band + 1), np.uint8)
        rim = cv2.dilate(masks.occluder.astype(np.uint8), k).astype(bool)
        beyond = np.bincount(parts[~rim].ravel(), minlength=n_parts)
        steep_parts &= beyond >= min_beyond
    if len(seen.points):
        ij = np.rint(seen.pixels[:, ::-1] / masks.stride).astype(int)
        gentle = np.zeros(n_parts, dtype=bool)
        for (i, j), is_steep in zip(ij, seen.steep):
            win = parts[max(i - 3, 0) : i + 4, max(j - 3, 0) : j + 4]  # past the sticker
            for lab in np.unique(win[win > 0]):
                if is_steep:
                    gentle[lab] = False
                    steep_parts[lab] = True
                elif steep_parts[lab]:
                    gentle[lab] = True
        steep_parts &= ~gentle
    return steep_parts[parts] if steep_parts.any() else None


def _layer_over(
    masks: NapkinMasks,
    where: NDArray,
    flat3d: NDArray | None,
    up: NDArray | None,
    seen: _Seen,
    intrinsics: Intrinsics,
    layout: NapkinLayout,
    p: EvidenceParams,
) -> NDArray[np.bool_]:
    """Which missing stickers' flat places (pixels ``where`` (m, 2); 3D ``flat3d``
    (m, 3)) have a layer hovering over them, ``cover_mm`` above the napkin around: they
    are under it, not up on the flap. With ``flat3d`` and the table normal ``up`` the
    layer is looked for straight above the place; without, along the camera's ray."""
    base = masks.height_at(seen.pixels)
    ground = nanmedian(base) if np.isfinite(base).any() else 0.0
    if flat3d is not None and up is not None:
        top = max(layout.width_mm, layout.height_mm) / 2
        return _covered_from_above(masks, flat3d, up, intrinsics, ground + p.cover_mm, top)
    over = masks.height_at(where)
    return np.isfinite(over) & (over > ground + p.cover_mm)


def _held_up(
    masks: NapkinMasks | None,
    where: NDArray,
    seen: _Seen,
    intrinsics: Intrinsics,
    layout: NapkinLayout,
    p: EvidenceParams,
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
    where : ndarray, shape (m, 2)
        Where each missing sticker would be lying flat, pixels (NaN where not known).
    seen : _Seen
        The located stickers.
    flat3d : ndarray, shape (m, 3), optional
        Where each missing sticker would lie flat, camera frame (NaN where not known).
    up : ndarray, shape (3,), optional
        Table normal. With ``flat3d``, a layer over a sticker's flat place is looked for
        straight above it; without, along the camera's ray (where a flap standing in
        front of the place, its own, would count).
    """
    out = np.zeros(len(where), dtype=bool)
    if masks is None or masks.raised is None or not masks.raised.any():
        return out
    steep_mask = _steep_cloth(masks, seen, p.object_band_samples, p.flap_beyond_samples)
    if steep_mask is None:
        return out
    reach_px = p.held_up_reach * min(layout.width_mm, layout.height_mm) * 1e-3
    reach_px *= intrinsics.fx / seen.z_typ
    out = masks.near(steep_mask, where, reach_px) | ~np.isfinite(where[:, 0])
    if masks.height_mm is not None and len(seen.points):
        out &= ~_layer_over(masks, where, flat3d, up, seen, intrinsics, layout, p)
    return out


def _out_of_view(uv: NDArray, radius_px: float, intrinsics: Intrinsics) -> bool:
    """A predicted place more than ``radius_px`` outside the image (NaN: not known)."""
    u, v = uv
    w, h = intrinsics.width, intrinsics.height
    return bool(np.isfinite(u)) and not (
        -radius_px <= u <= w - 1 + radius_px and -radius_px <= v <= h - 1 + radius_px
    )


@dataclass(frozen=True)
class _Missing:
    """What is known of each missing sticker, arrays of shape (m,): its predicted place
    out of view; near an object, a highlight, an object within ``flap_reach_mm`` (see
    :class:`_Near`); possibly held up; the stickers of its corner seen; its disc colour
    seen pastel; dropped as a false detection, with no place predicted."""

    out_of_view: NDArray[np.bool_]
    near: _Near
    held_up: NDArray[np.bool_]
    corner_support: NDArray[np.intp]
    pale: NDArray[np.bool_]
    dropped: NDArray[np.bool_]


def _why_unknown(
    k: int, m: _Missing, occluded: bool, p: EvidenceParams
) -> tuple[str | None, bool]:
    """Why the ``k``-th missing sticker is unknown, the first reason that holds (None
    where only cloth can hide it), and whether its place may lie under an object."""
    under = bool(
        m.near.occluder[k]
        or (occluded and m.corner_support[k] < p.min_corner_support and m.near.flap_reach[k])
    )
    if m.out_of_view[k]:
        return "out of view", False
    if m.held_up[k]:  # a flap held up by the object over it tells its lean
        return HELD_UP, under
    if under:
        return "possibly under an object above the napkin", True
    if m.near.highlight[k]:
        return "in a highlight", False
    if m.pale[k]:
        return WASHED_OUT, False
    if m.dropped[k]:
        return "found where the napkin cannot be", False
    return None, False


def _masks_of(napkin: NapkinMasks | NapkinView | None) -> NapkinMasks | None:
    return napkin.masks() if isinstance(napkin, NapkinView) else napkin


def assess_stickers(
    markers: Markers3D,
    intrinsics: Intrinsics,
    layout: NapkinLayout,
    napkin: NapkinMasks | NapkinView | None,
    *,
    dropped: NDArray[np.bool_] | None = None,
    params: EvidenceParams | None = None,
    foreshortening: NDArray[np.float64] | None = None,
    up: NDArray[np.float64] | None = None,
    pale_colours: tuple[str, ...] = (),
    turns: NDArray[np.float64] | None = None,
) -> StickerEvidence:
    """Decide, for each sticker, seen, hidden by cloth, or unknown.

    Parameters
    ----------
    markers : Markers3D
        Located stickers (after :func:`drop_inconsistent`).
    intrinsics : Intrinsics
    layout : NapkinLayout
    napkin : NapkinMasks or None
        The napkin stage's masks (:meth:`.napkin.NapkinView.masks`): highlights, objects
        above the table, cloth held up and heights; None: nothing is ever unknown. A
        :class:`~.napkin.NapkinView` is taken as its masks.
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
    turns : ndarray, shape (4,), keyword-only, optional
        Which face each corner shows (:func:`.handedness.image_turns`): the stickers of
        a corner showing its back face lie on a flap and do not place the others.

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
    pred3, support = _predict_missing(markers, layout, p, turns)
    ok = np.isfinite(pred3[:, 0]) & (pred3[:, 2] > 0)
    predicted[ok] = intrinsics.project(pred3[ok])
    located = _seen_stickers(markers, intrinsics, layout, p, foreshortening)
    masks = _masks_of(napkin)
    if masks is not None:
        masks = masks.without_objects_near(located.pixels, located.radius_px)
    fx = intrinsics.fx
    occluded = masks is not None and _over_napkin(masks, p.napkin_margin_mm, located, fx)
    missing = np.flatnonzero(~seen)
    where = predicted[missing]
    flap_reach_px = p.flap_reach_mm * 1e-3 * intrinsics.fx / located.z_typ
    flat3d = pred3[missing] if up is not None else None
    unplaced = np.isnan(where[:, 0])
    facts = _Missing(
        np.array([_out_of_view(uv, located.radius_px, intrinsics) for uv in where], bool),
        _nearness(masks, where, located.radius_px, flap_reach_px),
        _held_up(masks, where, located, intrinsics, layout, p, flat3d, up),
        support[missing],
        np.array([layout.sticker_disc[sid] in pale_colours for sid in missing], bool),
        np.zeros(len(missing), bool) if dropped is None else dropped[missing] & unplaced,
    )
    near_object = np.zeros(n, dtype=bool)
    for k, sid in enumerate(missing):
        why, near_object[sid] = _why_unknown(k, facts, occluded, p)
        if why:
            status[sid] = UNKNOWN
            reasons[sid] = why
    return StickerEvidence(status, tuple(reasons), predicted, occluded, near_object)
