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
from .params import PartialParams

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
    balance: NDArray[np.uint8],
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
    stickers seen predicts it (``evidence.predicted_px``), the sticker's (disc, dot)
    colour pair, which names it alone, says that it lies there: its disc colour over
    ``min_colour`` of the ring and its dot colour over ``min_dot`` of the centre, read
    with the second search's pastel thresholds (``washed_saturation``,
    ``washed_chroma``). Its identity is never guessed: no sticker found nor another one
    predicted with the same disc colour may lie within ``min_apart`` radii. It is
    located at the centroid of its coloured pixels, at the depth read there.

    Parameters
    ----------
    color : ndarray of uint8, shape (H, W, 3)
    depth_mm : ndarray of uint16, shape (H, W)
        The registered depth (0: no reading).
    balance : ndarray of uint8, shape (256, 1, 3)
        The napkin's white balance (``NapkinView.lut``).
    found : (StickerDetections, Markers3D, StickerEvidence)
        The search's, the lift's and the evidence stage's results.
    intrinsics, layout, detector, params, colours
        As for :func:`confirm_partly_hidden`.

    Returns
    -------
    (StickerDetections, Markers3D, StickerEvidence)
        The same, with each confirmed sticker found (scored as half the median of the
        stickers found, as the second search scores its own) and seen.
    """
    detections, markers, evidence = found
    pred = evidence.predicted_px
    ids = np.flatnonzero(~markers.found & ~detections.found & np.isfinite(pred).all(1))
    if not len(ids) or markers.found.sum() < 3:
        return found
    p = params or PartialParams()
    dp = detector or DetectorParams()
    pastel = replace(dp, min_saturation=dp.washed_saturation, min_chroma=dp.washed_chroma)
    radius = 0.5e-3 * layout.disc_diameter_mm * intrinsics.fx / nanmedian(
        markers.points[markers.found, 2]
    )
    lut, names = hue_lut(layout, dp, colours)
    taken: dict[int, NDArray[np.float64]] = {}
    for s in ids.tolist():
        if not _alone(s, pred, ids, detections, layout, radius * p.min_apart):
            continue
        pair = (names.index(layout.sticker_disc[s]) + 1, names.index(layout.sticker_dot[s]) + 1)
        where = _pair_shows(
            color, balance, pred[s], radius, lut, pastel, p, pair,
            layout.dot_diameter_mm / layout.disc_diameter_mm,
        )
        if where is not None:
            taken[s] = where
    if not taken:
        return found
    confirmed = list(taken)
    px = np.array([taken[s] for s in confirmed])
    z_m = np.array([_depth_at(depth_mm, uv, radius) for uv in px]) * 1e-3
    z_m = np.where(np.isfinite(z_m), z_m, nanmedian(markers.points[markers.found, 2]))
    points = intrinsics.deproject(intrinsics.undistort_pixels(px), z_m)
    det, mk, ev = _taken(detections, markers, evidence, confirmed, px, points)
    scores, areas = det.scores.copy(), det.areas.copy()
    scores[confirmed] = 0.5 * float(np.median(detections.scores[detections.found]))
    areas[confirmed] = np.pi * radius**2
    return replace(det, scores=scores, areas=areas), mk, ev


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
    """Where the sticker of colour labels ``pair`` (disc, dot) lies near ``uv``: the
    centroid of its disc and dot pixels, when its disc colour covers ``min_colour`` of
    the ring and its dot colour ``min_dot`` of the centre (both around the centroid,
    looked for within ``disc_share`` radii of ``uv``); else None."""
    h, w = color.shape[:2]
    r = int(np.ceil(2 * radius)) + 1
    u, v = int(round(uv[0])), int(round(uv[1]))
    y0, y1, x0, x1 = max(v - r, 0), min(v + r + 1, h), max(u - r, 0), min(u + r + 1, w)
    if y1 <= y0 or x1 <= x0:
        return None
    labels, _ = colour_labels(cv2.LUT(color[y0:y1, x0:x1], balance), lut, dp)
    yy, xx = np.mgrid[y0:y1, x0:x1].astype(np.float64)
    mine = (labels == pair[0]) | (labels == pair[1])
    mine &= np.hypot(xx - uv[0], yy - uv[1]) <= (1.0 + p.disc_share) * radius
    if mine.sum() < 3:
        return None
    at = np.array([xx[mine].mean(), yy[mine].mean()])
    if np.hypot(*(at - uv)) > p.disc_share * radius:
        return None
    d = np.hypot(xx - at[0], yy - at[1])
    ring = (d > dot_share * radius) & (d <= radius)
    centre = d <= dot_share * radius
    if not ring.any() or not centre.any():
        return None
    disc_ok = float((labels[ring] == pair[0]).mean()) >= p.min_colour
    dot_ok = float((labels[centre] == pair[1]).mean()) >= p.min_dot
    return at if disc_ok and dot_ok else None


def _depth_at(depth_mm: NDArray[np.uint16], uv: NDArray[np.float64], radius: float) -> float:
    """Median depth reading (mm) within ``radius`` of ``uv``; NaN without any."""
    h, w = depth_mm.shape
    r = max(int(np.ceil(radius)), 1)
    u, v = int(round(uv[0])), int(round(uv[1]))
    win = depth_mm[max(v - r, 0) : min(v + r + 1, h), max(u - r, 0) : min(u + r + 1, w)]
    good = win[win > 0]
    return float(np.median(good)) if good.size else float("nan")
