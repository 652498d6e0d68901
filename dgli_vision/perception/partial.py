"""Stickers partly under an object: the part of the disc left at the object's edge.

A gripper over a corner of the napkin cuts its stickers to crescents, which the search
rightly refuses (their centroids would lie far from the centres). Yet a crescent of
the right colour exactly where the sticker would lie if its part of the cloth lay as
the rest (the evidence stage's rigid prediction) says that it does lie there: the
corner is not folded, whatever the object hides. Such a sticker is taken as seen, at
its predicted place on the cloth.
"""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
from numpy.typing import NDArray

from ..core.camera import Intrinsics
from ..core.classes import LIFTED_MM
from ..core.layout import NapkinLayout
from ..core.order_stats import median, nanmedian
from .detections import DetectorParams, StickerDetections
from .evidence import SEEN, StickerEvidence
from .labels import colour_labels, hue_lut
from .lift import Markers3D
from .napkin import NapkinView
from .params import PartialParams
from .rigid import fit_rigid, flat_points_m

__all__ = ["PartialParams", "confirm_at_place", "confirm_partly_hidden"]


def confirm_partly_hidden(
    color: NDArray[np.uint8],
    balance: NDArray[np.uint8],
    detections: StickerDetections,
    markers: Markers3D,
    evidence: StickerEvidence,
    intrinsics: Intrinsics,
    table: tuple[NDArray[np.float64], float],
    layout: NapkinLayout,
    detector: DetectorParams | None = None,
    params: PartialParams | None = None,
    colours: dict[str, tuple[int, int, int]] | None = None,
) -> tuple[StickerDetections, Markers3D, StickerEvidence]:
    """Take as seen the stickers possibly under an object whose disc colour shows at
    their predicted place.

    Parameters
    ----------
    color : ndarray of uint8, shape (H, W, 3)
        The RGB image.
    balance : ndarray of uint8, shape (256, 1, 3)
        The napkin's white balance (``NapkinView.lut``).
    detections, markers, evidence
        The search's, the lift's and the evidence stage's results.
    intrinsics : Intrinsics
    table : (ndarray, float)
        The table plane (``up``, ``offset``): ``p @ up == offset`` on it.
    layout : NapkinLayout
    detector : DetectorParams, optional
        The colour thresholds (the search's).
    params : PartialParams, optional
    colours : dict, optional
        Calibrated sticker colours, as the search takes them.

    Returns
    -------
    (StickerDetections, Markers3D, StickerEvidence)
        The same, with each confirmed sticker found at its predicted pixel and 3D
        place (on the cloth at the height of the stickers lying around it).
    """
    ids = np.flatnonzero(
        evidence.near_object & evidence.unknown & np.isfinite(evidence.predicted_px).all(1)
    )
    if not len(ids) or not markers.found.any():  # (most frames: nothing to confirm)
        return detections, markers, evidence
    p = params or PartialParams()
    dp = detector or DetectorParams()
    up, offset = table
    lying = _lying_height(markers, up, offset)
    z = nanmedian(markers.points[markers.found, 2])
    radius = 0.5e-3 * layout.disc_diameter_mm * intrinsics.fx / z
    lut, names = hue_lut(layout, dp, colours)
    confirmed = [
        int(s) for s in ids
        if _shows_disc(color, balance, evidence.predicted_px[s], radius, lut, dp, p,
                       names.index(layout.sticker_disc[s]) + 1)
        and _apart(s, evidence.predicted_px[s], detections, layout, radius * p.min_apart)
    ]
    if not confirmed:
        return detections, markers, evidence
    px = evidence.predicted_px[confirmed]
    points = _on_cloth(px, intrinsics, up, offset + lying)
    return _taken(detections, markers, evidence, confirmed, px, points)


def _lying_height(markers: Markers3D, up: NDArray, offset: float) -> float:
    """Median height of the stickers found lying on the table (below ``LIFTED_MM``),
    metres."""
    h = markers.points[markers.found] @ up - offset
    low = h[h < LIFTED_MM / 1e3]
    return median(low) if len(low) else 0.0


def _shows_disc(
    color: NDArray[np.uint8],
    balance: NDArray[np.uint8],
    uv: NDArray[np.float64],
    radius: float,
    lut: NDArray[np.uint8],
    dp: DetectorParams,
    p: PartialParams,
    label: int,
) -> bool:
    """Whether at least ``min_colour`` of the disc around ``uv`` shows colour ``label``."""
    h, w = color.shape[:2]
    r = int(np.ceil(radius)) + 1
    u, v = int(round(uv[0])), int(round(uv[1]))
    y0, y1, x0, x1 = max(v - r, 0), min(v + r + 1, h), max(u - r, 0), min(u + r + 1, w)
    if y1 <= y0 or x1 <= x0:
        return False
    labels, _ = colour_labels(cv2.LUT(color[y0:y1, x0:x1], balance), lut, dp)
    yy, xx = np.mgrid[y0:y1, x0:x1]
    disc = np.hypot(xx - uv[0], yy - uv[1]) <= p.disc_share * radius
    if not disc.any():
        return False
    return float((labels[disc] == label).mean()) >= p.min_colour


def _apart(
    sid: int, uv: NDArray[np.float64], detections: StickerDetections, layout: NapkinLayout,
    reach: float,
) -> bool:
    """No sticker found with ``sid``'s disc colour lies within ``reach`` pixels of ``uv``
    (the colour there would be that sticker's)."""
    same = np.array([c == layout.sticker_disc[sid] for c in layout.sticker_disc])
    found = same & detections.found
    if not found.any():
        return True
    return bool(np.linalg.norm(detections.centroids[found] - uv, axis=1).min() > reach)


def _on_cloth(
    px: NDArray[np.float64], intrinsics: Intrinsics, up: NDArray, level: float
) -> NDArray[np.float64]:
    """Camera-frame points (n, 3) where the rays of pixels ``px`` meet the plane
    ``p @ up == level``."""
    ideal = intrinsics.undistort_pixels(px)
    rays = intrinsics.deproject(ideal, np.ones(len(ideal)))
    return rays * (level / (rays @ up))[:, None]


def _taken(
    detections: StickerDetections,
    markers: Markers3D,
    evidence: StickerEvidence,
    ids: list[int],
    px: NDArray[np.float64],
    points: NDArray[np.float64],
) -> tuple[StickerDetections, Markers3D, StickerEvidence]:
    """The three results with stickers ``ids`` found at ``px`` and ``points``."""
    centroids, depth = detections.centroids.copy(), detections.depth_mm.copy()
    centroids[ids], depth[ids] = px, points[:, 2] * 1e3
    pts = markers.points.copy()
    pts[ids] = points
    status, near = evidence.status.copy(), evidence.near_object.copy()
    status[ids], near[ids] = SEEN, False
    reasons = tuple(None if k in ids else r for k, r in enumerate(evidence.reasons))
    return (
        replace(detections, centroids=centroids, depth_mm=depth),
        Markers3D(pts),
        replace(evidence, status=status, reasons=reasons, near_object=near),
    )


def confirm_at_place(
    color: NDArray[np.uint8],
    depth_mm: NDArray[np.uint16],
    napkin: NapkinView,
    found: tuple[StickerDetections, Markers3D, StickerEvidence],
    intrinsics: Intrinsics,
    layout: NapkinLayout,
    detector: DetectorParams | None = None,
    params: PartialParams | None = None,
    colours: dict[str, tuple[int, int, int]] | None = None,
) -> tuple[StickerDetections, Markers3D, StickerEvidence]:
    """Take as seen the missing stickers whose own disc and dot show where the napkin's
    rigid layout of the stickers seen puts them.

    The search refuses a disc cut by a crease, blurred small at 1-2 m, or half taken by
    a lamp's streak in the laminate (its shape, size or fill fail), and the evidence
    stage then calls it hidden (a fold) or unknown. Yet where the rigid map of the
    stickers seen predicts it (``evidence.predicted_px``; where that is not told, a
    rigid fit of every sticker seen, when its inliers span two corners or more: a flap
    whose stickers run the other way lies as one too, as a place to look), the
    sticker's (disc, dot)
    colour pair, which names it alone, says that it lies there: its disc colour over
    ``min_colour`` of the ring and its dot colour over ``min_dot`` of the centre, read
    with the second search's pastel thresholds (``washed_saturation``,
    ``washed_chroma``), with the napkin's white around it: the median of the smallest
    channel on the ring 1.3-1.8 radii out reaches ``min_white`` of that around the
    stickers found (a table balanced to the napkin's white is darker, and shows pastel
    noise of every hue). Its identity is never guessed: the pair is this sticker's alone, no
    sticker found or confirmed lies within two radii (the pixels would be that one's),
    and a sticker whose dot has its disc's colour (which names no sticker by itself)
    is taken only when no sticker found nor another one predicted with that disc colour
    lies within ``min_apart`` radii. It is located at its dot's centre, at the depth
    read there.

    Parameters
    ----------
    color : ndarray of uint8, shape (H, W, 3)
    depth_mm : ndarray of uint16, shape (H, W)
        The registered depth (0: no reading).
    napkin : NapkinView
        The napkin found (its white balance).
    found : (StickerDetections, Markers3D, StickerEvidence)
        The search's, the lift's and the evidence stage's results.
    intrinsics, layout, detector, params, colours
        As for :func:`confirm_partly_hidden`.

    Returns
    -------
    (StickerDetections, Markers3D, StickerEvidence)
        The same, with each confirmed sticker found (scored as half the median of the
        stickers found, as the second search scores its own; its area the disc's
        face-on at the depth read, its foreshortening 1) and seen.
    """
    detections, markers, evidence = found
    if markers.found.sum() < 3 or markers.found.all():
        return found
    p = params or PartialParams()
    z_m = nanmedian(markers.points[markers.found, 2])
    if not (layout.disc_diameter_mm * intrinsics.fx / (z_m * 1e3) >= p.min_sticker_px):
        return found  # (smaller, identities are guesses: the classifier says so)
    pred = _places(markers, evidence, layout, intrinsics, p.fit_tolerance_mm * 1e-3)
    ids = np.flatnonzero(~markers.found & ~detections.found & np.isfinite(pred).all(1))
    if not len(ids):
        return found
    dp = detector or DetectorParams()
    pastel = replace(dp, min_saturation=dp.washed_saturation, min_chroma=dp.washed_chroma)
    radius = 0.5e-3 * layout.disc_diameter_mm * intrinsics.fx / z_m
    lut, names = hue_lut(layout, dp, colours)
    white: list[float] = []  # the napkin's white around the stickers found, when first asked
    taken: dict[int, NDArray[np.float64]] = {}
    for s in ids.tolist():
        pair = (names.index(layout.sticker_disc[s]) + 1, names.index(layout.sticker_dot[s]) + 1)
        if pair[0] == pair[1] and not _alone(
            s, pred, ids, detections, layout, radius * p.min_apart
        ):
            continue  # (its colour alone names no sticker where another may lie)
        where = _pair_shows(
            color, napkin.lut, pred[s], radius, lut, pastel, p, pair,
            layout.dot_diameter_mm / layout.disc_diameter_mm,
        )
        taken_px = np.array(list(taken.values())).reshape(-1, 2)
        if where is None or not _free(where, detections, taken_px, 2 * radius):
            continue
        if not white:
            white.append(median(np.array([
                _white_around(color, napkin.lut, uv, radius)
                for uv in detections.centroids[detections.found]
            ])))
        if _white_around(color, napkin.lut, where, radius) >= p.min_white * white[0]:
            taken[s] = where
    if not taken:
        return found
    return _as_seen(found, taken, depth_mm, intrinsics, layout, radius)


def _as_seen(
    found: tuple[StickerDetections, Markers3D, StickerEvidence],
    taken: dict[int, NDArray[np.float64]],
    depth_mm: NDArray[np.uint16],
    intrinsics: Intrinsics,
    layout: NapkinLayout,
    radius: float,
) -> tuple[StickerDetections, Markers3D, StickerEvidence]:
    """``found`` with the stickers ``taken`` (id -> pixel) seen there, at the depth read
    around each (:func:`confirm_at_place`'s result)."""
    detections, markers, evidence = found
    confirmed = list(taken)
    px = np.array([taken[s] for s in confirmed])
    z_m = np.array([_depth_at(depth_mm, uv, radius) for uv in px]) * 1e-3
    z_m = np.where(np.isfinite(z_m), z_m, nanmedian(markers.points[markers.found, 2]))
    points = intrinsics.deproject(intrinsics.undistort_pixels(px), z_m)
    det, mk, ev = _taken(detections, markers, evidence, confirmed, px, points)
    scores, areas = det.scores.copy(), det.areas.copy()
    scores[confirmed] = 0.5 * float(np.median(detections.scores[detections.found]))
    # the disc's face-on area at the depth read there (what is left of it says nothing
    # of its size), so that the sticker size the classifier reads stays a size
    areas[confirmed] = np.pi * (0.5 * layout.disc_diameter_mm * intrinsics.fx / (z_m * 1e3)) ** 2
    fore = None
    if det.foreshortening is not None:
        fore = det.foreshortening.copy()
        fore[confirmed] = 1.0
    return replace(det, scores=scores, areas=areas, foreshortening=fore), mk, ev


def _places(
    markers: Markers3D, evidence: StickerEvidence, layout: NapkinLayout,
    intrinsics: Intrinsics, tol_m: float,
) -> NDArray[np.float64]:
    """Where to look for each missing sticker, pixels (16, 2), NaN where not told: the
    evidence stage's prediction, else the rigid fit of every sticker seen when its
    inliers span two corners or more (:func:`.rigid.fit_rigid`)."""
    pred = evidence.predicted_px.copy()
    todo = ~markers.found & ~np.isfinite(pred).all(1)
    if todo.any():
        fit = fit_rigid(flat_points_m(layout), markers.points, markers.found, tol_m)
        if fit is not None and fit.corners_spanned(layout.sticker_corners) >= 2:
            pred[todo] = intrinsics.project(fit.predicted[todo])
    return pred


def _white_around(
    color: NDArray[np.uint8], balance: NDArray[np.uint8], uv: NDArray[np.float64],
    radius: float,
) -> float:
    """Median of the smallest channel, once balanced, of the pixels 1.3-1.8 disc radii
    from ``uv`` (the ring the search's surround check reads; 0 outside the image)."""
    h, w = color.shape[:2]
    r = int(np.ceil(1.8 * radius)) + 1
    u, v = int(round(uv[0])), int(round(uv[1]))
    y0, y1, x0, x1 = max(v - r, 0), min(v + r + 1, h), max(u - r, 0), min(u + r + 1, w)
    if y1 <= y0 or x1 <= x0:
        return 0.0
    yy, xx = np.mgrid[y0:y1, x0:x1]
    d = np.hypot(xx - uv[0], yy - uv[1])
    ring = (d > 1.3 * radius) & (d < 1.8 * radius)
    if not ring.any():
        return 0.0
    return float(np.median(cv2.LUT(color[y0:y1, x0:x1], balance).min(axis=2)[ring]))


def _free(
    at: NDArray[np.float64], detections: StickerDetections, taken: NDArray[np.float64],
    reach: float,
) -> bool:
    """No sticker found nor confirmed (``taken``, (k, 2)) lies within ``reach`` pixels
    of ``at``: the pixels there are no other sticker's."""
    others = np.concatenate([detections.centroids[detections.found], taken])
    return not len(others) or bool(np.linalg.norm(others - at, axis=1).min() > reach)


def _alone(
    sid: int, pred: NDArray[np.float64], missing: NDArray[np.intp],
    detections: StickerDetections, layout: NapkinLayout, reach: float,
) -> bool:
    """No sticker found, nor another missing one predicted, with ``sid``'s disc colour
    within ``reach`` pixels of ``sid``'s predicted place: only one identity fits."""
    same = np.array([c == layout.sticker_disc[sid] for c in layout.sticker_disc])
    same[sid] = False
    near = np.zeros(len(same), dtype=bool)
    near[missing] = True
    where = np.where(
        (detections.found & same)[:, None], detections.centroids,
        np.where((near & same)[:, None], pred, np.nan),
    )
    d = np.linalg.norm(where - pred[sid], axis=1)
    return not bool((d[np.isfinite(d)] <= reach).any())


def _pair_shows(
    color: NDArray[np.uint8],
    balance: NDArray[np.uint8],
    uv: NDArray[np.float64],
    radius: float,
    lut: NDArray[np.uint8],
    dp: DetectorParams,
    p: PartialParams,
    pair: tuple[int, int],
    dot_share: float,
) -> NDArray[np.float64] | None:
    """The centre of the sticker of colour labels ``pair`` (disc, dot) near ``uv``, or
    None when it does not show there.

    The centre is the centroid of its dot's colour within ``disc_share`` radii of
    ``uv`` (a dot of the disc's own colour: of that colour within one radius, and then
    the whole ring must show it, ``min_whole``), where at least ``min_dot`` of a dot's
    area shows; the ring around that centre (dot to rim) must show the disc colour over
    ``min_colour`` of it. A crescent left by a fold keeps part of the ring but not the
    dot: it is not taken (its centroid is not the sticker's centre).
    """
    h, w = color.shape[:2]
    r = int(np.ceil(2 * radius)) + 1
    u, v = int(round(uv[0])), int(round(uv[1]))
    y0, y1, x0, x1 = max(v - r, 0), min(v + r + 1, h), max(u - r, 0), min(u + r + 1, w)
    if y1 <= y0 or x1 <= x0:
        return None
    labels, _ = colour_labels(cv2.LUT(color[y0:y1, x0:x1], balance), lut, dp)
    yy, xx = np.mgrid[y0:y1, x0:x1].astype(np.float64)
    disc, dot = pair
    same = disc == dot
    reach = (1.0 if same else p.disc_share) * radius
    core = (labels == dot) & (np.hypot(xx - uv[0], yy - uv[1]) <= reach)
    if core.sum() < max(2.0, p.min_dot * np.pi * (dot_share * radius) ** 2):
        return None
    at = np.array([xx[core].mean(), yy[core].mean()])
    d = np.hypot(xx - at[0], yy - at[1])
    ring = (d > dot_share * radius) & (d <= radius)
    if not ring.any():
        return None
    share = float((labels[ring] == disc).mean())
    return at if share >= (p.min_whole if same else p.min_colour) else None


def _depth_at(depth_mm: NDArray[np.uint16], uv: NDArray[np.float64], radius: float) -> float:
    """Median depth reading (mm) within ``radius`` of ``uv``; NaN without any."""
    h, w = depth_mm.shape
    r = max(int(np.ceil(radius)), 1)
    u, v = int(round(uv[0])), int(round(uv[1]))
    win = depth_mm[max(v - r, 0) : min(v + r + 1, h), max(u - r, 0) : min(u + r + 1, w)]
    good = win[win > 0]
    return float(np.median(good)) if good.size else float("nan")
