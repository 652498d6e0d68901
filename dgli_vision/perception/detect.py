"""Sticker detection: HSV thresholding, connected blobs, and the disc + dot reading.

What to look for (the layout: colours and the (disc, dot) pair of each sticker id) is
separate from how to find it (:class:`DetectorParams`) and from the detector.

Every saturated pixel is labelled with the nearest of the four nominal hues (OpenCV's
8-bit hue runs 0-179 and red wraps around 0). The outer contours of the saturated mask
are the candidate stickers (a dot inside its disc belongs to it, even where blur leaves
an unsaturated ring between them). A candidate's disc colour is the majority label of
an outer band of its equivalent circle, its dot colour the majority of the inner part;
the pair names the sticker. Candidates are rejected for their size (against the disc
size expected at their depth), their shape, or colour impurity; an identity is never
given twice (the better-scoring candidate keeps it).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..camera import Intrinsics
from ..layout import NapkinLayout

__all__ = ["DetectorParams", "Rejection", "StickerDetections", "detect_stickers", "hue_of"]


@dataclass(frozen=True)
class DetectorParams:
    """How stickers are found. Every field has a unit and a default.

    Attributes
    ----------
    min_saturation : int
        Minimum HSV saturation (0-255) of a sticker pixel. Default 90: the napkin and
        the table are much less saturated.
    min_value : int
        Minimum HSV value (0-255). Default 35.
    max_hue_distance : int
        Largest distance (OpenCV hue units, 2 degrees each) from a nominal hue. Default 22.
    min_area_ratio, max_area_ratio : float
        Accepted blob area relative to the disc area expected at the blob's depth.
        Defaults 0.55 and 2.0: a whole sticker seen at up to 15 degrees of tilt and on
        wrinkles keeps over 0.8; a sliver of a sticker mostly under a flap would give a
        centroid far from the sticker's centre, so it is better left out; two merged
        stickers are larger.
    min_fill : float
        Minimum fraction of the expected disc, centred at the blob's centroid, that the
        blob covers. Default 0.6 (rejects crescents and slivers).
    min_solidity : float
        Minimum area / convex-hull area. Default 0.8.
    max_elongation : float
        Maximum ratio of the blob's principal axes. Default 2.5.
    min_purity : float
        Minimum fraction of the outer band with the disc colour, and of the inner part
        with the dot colour. Default 0.5.
    """

    min_saturation: int = 90
    min_value: int = 35
    max_hue_distance: int = 22
    min_area_ratio: float = 0.55
    max_area_ratio: float = 2.0
    min_fill: float = 0.6
    min_solidity: float = 0.8
    max_elongation: float = 2.5
    min_purity: float = 0.5


@dataclass(frozen=True)
class Rejection:
    """A blob that is not taken as a sticker: where, and why."""

    centroid: tuple[float, float]
    area_px: float
    reason: str


@dataclass(frozen=True, eq=False)
class StickerDetections:
    """What the detector found.

    Attributes
    ----------
    centroids : ndarray, shape (16, 2)
        Sub-pixel centroid (u, v) of each sticker id; NaN where not found.
    areas : ndarray, shape (16,)
        Blob area in pixels (NaN where not found).
    scores : ndarray, shape (16,)
        Colour purity times shape agreement in [0, 1] (0 where not found).
    depth_mm : ndarray, shape (16,)
        Median valid depth inside the blob, mm (NaN where none).
    rejected : tuple of Rejection
        Blobs that looked like candidates but were rejected, with the reason.
    """

    centroids: NDArray[np.float64]
    areas: NDArray[np.float64]
    scores: NDArray[np.float64]
    depth_mm: NDArray[np.float64]
    rejected: tuple[Rejection, ...] = field(default_factory=tuple)

    @property
    def found(self) -> NDArray[np.bool_]:
        """Which sticker ids were detected, shape (16,)."""
        return ~np.isnan(self.centroids[:, 0])


def hue_of(rgb: tuple[int, int, int]) -> int:
    """OpenCV 8-bit hue (0-179) of an sRGB colour."""
    import cv2

    return int(cv2.cvtColor(np.uint8([[rgb]]), cv2.COLOR_RGB2HSV)[0, 0, 0])


def _hue_lut(layout: NapkinLayout, params: DetectorParams) -> tuple[NDArray[np.uint8], list[str]]:
    """Lookup table hue -> colour label (0 none, k + 1 for colour k) and colour names."""
    names = list(layout.colours_srgb)
    hues = np.array([hue_of(layout.colours_srgb[n]) for n in names])
    h = np.arange(180)
    dist = np.abs(h[:, None] - hues[None, :])
    dist = np.minimum(dist, 180 - dist)  # hue is circular
    lut = (np.argmin(dist, axis=1) + 1).astype(np.uint8)
    lut[dist.min(axis=1) > params.max_hue_distance] = 0
    return lut, names


def detect_stickers(
    color: NDArray[np.uint8],
    depth_mm: NDArray[np.uint16],
    intrinsics: Intrinsics,
    layout: NapkinLayout,
    params: DetectorParams | None = None,
) -> StickerDetections:
    """Find the 16 stickers in an RGB image.

    Parameters
    ----------
    color : ndarray of uint8, shape (H, W, 3)
        RGB image.
    depth_mm : ndarray of uint16, shape (H, W)
        Registered depth in mm (0 = no reading), used for the expected sticker size.
    intrinsics : Intrinsics
    layout : NapkinLayout
        The stickers' colours and sizes.
    params : DetectorParams, optional

    Returns
    -------
    StickerDetections
    """
    import cv2

    params = params or DetectorParams()
    if color.ndim != 3 or color.shape[2] != 3 or color.dtype != np.uint8:
        raise ValueError(f"color must be (H, W, 3) uint8, got {color.shape} {color.dtype}")
    if depth_mm.shape != color.shape[:2]:
        raise ValueError(f"depth_mm must have shape {color.shape[:2]}, got {depth_mm.shape}")
    n = layout.n_stickers
    hsv = cv2.cvtColor(color, cv2.COLOR_RGB2HSV)
    lut, names = _hue_lut(layout, params)
    saturated = (hsv[..., 1] >= params.min_saturation) & (hsv[..., 2] >= params.min_value)
    labels = np.where(saturated, lut[hsv[..., 0]], 0).astype(np.uint8)
    mask = (labels > 0).astype(np.uint8)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    coarse = depth_mm[::8, ::8]
    med_depth = float(np.median(coarse[coarse > 0])) if (coarse > 0).any() else np.nan
    disc_r_mm = layout.disc_diameter_mm / 2
    # A sticker cannot be smaller than the smallest accepted area at the farthest depth.
    min_px = (
        params.min_area_ratio
        * np.pi
        * (disc_r_mm * intrinsics.fx / (2.0 * max(med_depth, 1.0))) ** 2
    )
    candidates = []
    rejected = []
    for contour in contours:
        area = cv2.contourArea(contour)
        if area < max(min_px, 12.0):
            continue
        m = cv2.moments(contour)
        cu, cv = m["m10"] / m["m00"], m["m01"] / m["m00"]
        x, y, w, h = cv2.boundingRect(contour)
        roi = np.zeros((h, w), np.uint8)
        cv2.drawContours(roi, [contour - [x, y]], -1, 1, thickness=-1)
        inside = roi.astype(bool)
        depth_roi = depth_mm[y : y + h, x : x + w]
        inner_depth = depth_roi[cv2.erode(roi, np.ones((3, 3), np.uint8)).astype(bool)]
        inner_depth = inner_depth[inner_depth > 0]
        if inner_depth.size == 0:
            inner_depth = depth_roi[inside & (depth_roi > 0)]
        z_mm = float(np.median(inner_depth)) if inner_depth.size else med_depth
        expected = np.pi * (disc_r_mm * intrinsics.fx / z_mm) ** 2 if z_mm > 0 else np.nan
        ratio = area / expected if expected > 0 else np.nan
        where = (float(cu), float(cv))
        if not np.isfinite(ratio):
            rejected.append(Rejection(where, area, "no depth to judge its size"))
            continue
        if ratio < params.min_area_ratio:
            rejected.append(
                Rejection(
                    where,
                    area,
                    f"too small for a sticker at {z_mm:.0f} mm ({ratio:.2f} of a disc)",
                )
            )
            continue
        if ratio > params.max_area_ratio:
            rejected.append(
                Rejection(
                    where, area, f"too large for a sticker at {z_mm:.0f} mm ({ratio:.2f} discs)"
                )
            )
            continue
        hull_area = cv2.contourArea(cv2.convexHull(contour))
        solidity = area / hull_area if hull_area > 0 else 0.0
        mu20, mu02, mu11 = m["mu20"], m["mu02"], m["mu11"]
        common = np.sqrt(4 * mu11**2 + (mu20 - mu02) ** 2)
        elongation = np.sqrt((mu20 + mu02 + common) / max(mu20 + mu02 - common, 1e-9))
        if solidity < params.min_solidity or elongation > params.max_elongation:
            rejected.append(
                Rejection(
                    where,
                    area,
                    f"not disc-shaped (solidity {solidity:.2f}, elongation {elongation:.2f})",
                )
            )
            continue
        # Disc and dot colours: majority labels of an outer band and the inner part of
        # the blob's equivalent circle (radius from the *expected* disc when the blob is
        # partly covered, so that the dot stays inside the inner part).
        radius = np.sqrt(max(area, expected) / np.pi)
        yy, xx = np.mgrid[y : y + h, x : x + w]
        r = np.hypot(xx - cu, yy - cv) / radius
        fill = inside[r < 1.0].sum() / (np.pi * radius**2)
        if fill < params.min_fill:
            rejected.append(Rejection(where, area, f"not a whole disc (covers {fill:.2f} of one)"))
            continue
        lab = labels[y : y + h, x : x + w]
        outer = lab[inside & (r > 0.6) & (r < 0.95) & (lab > 0)]
        inner = lab[inside & (r < 0.28) & (lab > 0)]
        if outer.size == 0 or inner.size == 0:
            rejected.append(Rejection(where, area, "no disc or no dot colour inside"))
            continue
        disc_counts = np.bincount(outer, minlength=len(names) + 1)
        dot_counts = np.bincount(inner, minlength=len(names) + 1)
        disc, dot = int(np.argmax(disc_counts)), int(np.argmax(dot_counts))
        purity = min(disc_counts[disc] / outer.size, dot_counts[dot] / inner.size)
        if purity < params.min_purity:
            rejected.append(Rejection(where, area, f"mixed colours (purity {purity:.2f})"))
            continue
        sid = layout.sticker_id(names[disc - 1], names[dot - 1])
        if sid is None:
            rejected.append(
                Rejection(
                    where, area, f"no sticker is {names[disc - 1]} with a {names[dot - 1]} dot"
                )
            )
            continue
        score = float(purity * min(ratio, 1 / ratio) * solidity)
        candidates.append((score, sid, where, area, z_mm))
    centroids = np.full((n, 2), np.nan)
    areas = np.full(n, np.nan)
    scores = np.zeros(n)
    depths = np.full(n, np.nan)
    for score, sid, where, area, z_mm in sorted(candidates, key=lambda c: -c[0]):
        if scores[sid] > 0:
            rejected.append(Rejection(where, area, f"second blob for sticker {sid} (lower score)"))
            continue
        centroids[sid] = where
        areas[sid] = area
        scores[sid] = score
        depths[sid] = z_mm
    return StickerDetections(centroids, areas, scores, depths, tuple(rejected))
