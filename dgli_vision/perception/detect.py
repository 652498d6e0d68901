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
from ..colour import srgb_lut
from ..layout import NapkinLayout
from .footprint import FootprintParams, cloth_cells
from .napkin import NapkinView, balance_lut, find_napkin

__all__ = [
    "DetectorParams",
    "Rejection",
    "StickerDetections",
    "detect_all_stickers",
    "detect_stickers",
    "find_washed_out",
    "hue_of",
]


@dataclass(frozen=True)
class DetectorParams:
    """How stickers are found. Every field has a unit and a default.

    Attributes
    ----------
    min_saturation : int
        Minimum HSV saturation (0-255) of a sticker pixel, in the image balanced to the
        napkin's white (:mod:`.napkin`). Default 115 (0.45): the printed colours keep
        over 0.6 even at their blurred rims, a light-wood table or a tinted surround
        stays near 0.3.
    min_value : int
        Minimum HSV value (0-255) in the balanced image, where the napkin's white is at
        ``NapkinParams.target_level`` (225): so this is relative to the napkin. Default
        30 (0.13 of the napkin): a blue sticker in a deep shadow of a dim image keeps
        about 0.25.
    min_chroma : int
        Minimum max - min channel (0-255) in the balanced image. Default 40 (0.18 of the
        napkin's level): dark noisy pixels can reach a high HSV saturation with a small
        chroma; a sticker in shadow keeps over 70.
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
    min_surround : float
        Minimum ratio of the surround's whiteness (median of the smallest linear channel
        on a ring 1.3-1.8 radii out) to the blob's brightness (median of its largest
        linear channel). Default 0.55: a sticker sits on white cloth (0.8 against at most
        0.83, so about 1 or more in any light), a cap or a box on a table does not (a
        grey table reflects at most 0.35 against 0.6 for a saturated object; a wood
        table's blue channel much less).
    min_dot_seen : float
        Minimum fraction of the dot area that is labelled with a colour (not washed out
        by a highlight) for the dot colour to be read. Default 0.35.
    highlight_min : int
        Smallest channel (0-255) of a washed-out pixel, in the image as taken or balanced
        to the napkin. Default 250: blown out, or brighter than white cloth can be.
    highlight_halo_px : int
        Width of the pale halo around a blown-out highlight counted with it, pixels
        (pale: bright and below ``min_saturation``). Default 8: a mirror highlight fades
        into the sticker's colour over a few pixels, pale but not white.
    halo_min_saturation : int
        Smallest HSV saturation (0-255, balanced image) of a halo pixel. Default 30: the
        white napkin around a sticker stays below 20 once balanced, so the halo never
        spreads over the cloth.
    halo_min_value : int
        Smallest HSV value (0-255, balanced image) of a halo pixel; near-white pixels
        (every channel at least ``halo_min_value + 80``) count as halo whatever their
        saturation. Default 150: the halo is brighter than the sticker's own colour.
    highlight_reach : float
        How far from a blob's centre, in expected disc radii, washed-out pixels may be
        counted with it. Default 1.6: a highlight lies on the sticker, so within one
        radius of its true centre, and the centre of what is left of the colour lies
        at most about 0.6 radii off.
    napkin_blown_level : int
        8-bit level of the napkin's white at or above which highlights cannot be told
        from cloth, and none are recovered. Default 240.
    search_radius_px : float
        Stickers are searched in the image halved while a sticker at the median depth
        keeps at least this radius there, pixels; their centres are then measured at
        full resolution. Default 6: the dot (0.4 radii) keeps a core of a few clean
        pixels, and a 1280 x 720 frame from up to 750 mm is searched at 640 x 360.
    tilt_agreement : float
        Largest difference between the foreshortening read from a blob's shape (minor /
        major axis) and from the tilt of its own depth for it to be taken as a tilted
        disc. Default 0.25: the depth of a sticker's few hundred pixels gives the tilt
        to about 10 degrees; a half disc on flat cloth (shape 0.53, depth 1.0) fails.
    flat_foreshortening : float
        Above this cosine of the angle between the surface and the line of sight, a
        sticker is taken as seen face-on (the checks above apply unchanged). Default
        0.85 (32 degrees): SPEC's tilted cameras and wrinkles stay within it.
    min_foreshortening : float
        Below this cosine a sticker is seen too obliquely to be read (its dot shrinks
        to a line). Default 0.25 (75 degrees): the 12 mm dot keeps about 3 mm.
    washed_saturation : int
        ``min_saturation`` of the second search (:func:`find_washed_out`) for stickers a
        broad sheen washed to pastel. Default 25 (0.1): a semi-gloss sticker under a
        softbox keeps 0.1-0.3 and its hue, while the napkin once balanced stays below
        about 0.05.
    washed_surround : float
        ``min_surround`` of that search. Default 0.35: a semi-gloss sticker in the lobe
        of a large light reflects about twice what the matte cloth around it does.
    washed_level : int
        8-bit level the napkin's white is balanced to for that search. Default 150: a
        sticker under a sheen is brighter than the napkin, and at the usual 225 it would
        clip to white.
    washed_chroma : int
        ``min_chroma`` of that search. Default 20: a pastel sticker keeps the chroma of
        its own colour under added white light (in linear light exactly; 8-bit levels
        compress it), the napkin's noise stays below 10.
    """

    min_saturation: int = 115
    min_value: int = 30
    min_chroma: int = 40
    max_hue_distance: int = 22
    min_area_ratio: float = 0.55
    max_area_ratio: float = 2.0
    min_fill: float = 0.6
    min_solidity: float = 0.8
    max_elongation: float = 2.5
    min_purity: float = 0.5
    min_surround: float = 0.55
    min_dot_seen: float = 0.35
    highlight_min: int = 250
    highlight_halo_px: int = 8
    halo_min_saturation: int = 30
    halo_min_value: int = 150
    highlight_reach: float = 1.6
    napkin_blown_level: int = 240
    search_radius_px: float = 6.0
    tilt_agreement: float = 0.25
    flat_foreshortening: float = 0.85
    min_foreshortening: float = 0.25
    washed_saturation: int = 25
    washed_chroma: int = 20
    washed_level: int = 150
    washed_surround: float = 0.35


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
    foreshortening : ndarray, shape (16,), optional
        Minor / major axis of each sticker's image (1 face-on; lower on a tilted
        flap); NaN where not found.
    pale_px : ndarray, shape (k, 2), optional
        Pixels (x, y) of pastel sticker colour left away from every sticker found: a
        broad sheen's washed-out stickers that no search could read (see
        :func:`find_washed_out`).
    pale_colours : tuple of str
        The sticker colours (names) of two or more of those samples.
    """

    centroids: NDArray[np.float64]
    areas: NDArray[np.float64]
    scores: NDArray[np.float64]
    depth_mm: NDArray[np.float64]
    rejected: tuple[Rejection, ...] = field(default_factory=tuple)
    foreshortening: NDArray[np.float64] | None = None
    pale_px: NDArray[np.float64] | None = None
    pale_colours: tuple[str, ...] = ()

    @property
    def found(self) -> NDArray[np.bool_]:
        """Which sticker ids were detected, shape (16,)."""
        return ~np.isnan(self.centroids[:, 0])


def hue_of(rgb: tuple[int, int, int]) -> int:
    """OpenCV 8-bit hue (0-179) of an sRGB colour."""
    import cv2

    return int(cv2.cvtColor(np.uint8([[rgb]]), cv2.COLOR_RGB2HSV)[0, 0, 0])


def _hue_lut(
    layout: NapkinLayout, params: DetectorParams, colours: dict[str, tuple[int, int, int]] | None
) -> tuple[NDArray[np.uint8], list[str]]:
    """Lookup table hue -> colour label (0 none, k + 1 for colour k) and colour names.

    ``colours`` (calibrated sRGB of each colour name, as the balanced image shows them)
    replaces the layout's nominal colours.
    """
    names = list(layout.colours_srgb)
    source = {**layout.colours_srgb, **(colours or {})}
    hues = np.array([hue_of(source[n]) for n in names])
    h = np.arange(180)
    dist = np.abs(h[:, None] - hues[None, :])
    dist = np.minimum(dist, 180 - dist)  # hue is circular
    lut = (np.argmin(dist, axis=1) + 1).astype(np.uint8)
    lut[dist.min(axis=1) > params.max_hue_distance] = 0
    return lut, names


def _washed_out(
    color: NDArray[np.uint8],
    norm: NDArray[np.uint8],
    hsv: NDArray[np.uint8],
    params: DetectorParams,
    disc_radius_px: float,
    halo_px: int,
) -> NDArray[np.bool_]:
    """Pixels a glossy sticker's highlight washed out, in a window around a blob: small
    blown-out spots (in the image as taken, or brighter than white cloth once balanced),
    grown into the pale, tinted halo around them. Shape (h, w) of the window."""
    import cv2

    core = cv2.min(cv2.min(color[..., 0], color[..., 1]), color[..., 2]) >= params.highlight_min
    norm_min = cv2.min(cv2.min(norm[..., 0], norm[..., 1]), norm[..., 2])
    core |= norm_min >= params.highlight_min
    if not core.any():
        return core
    # A highlight is smaller than a sticker; a large blown-out area is cloth.
    _, lab, stats, _ = cv2.connectedComponentsWithStats(core.astype(np.uint8), connectivity=8)
    small = stats[:, cv2.CC_STAT_AREA] <= 1.5 * np.pi * disc_radius_px**2
    small[0] = False
    core = small[lab]
    if not core.any():
        return core
    sat = hsv[..., 1]
    allowed = (
        (
            (sat >= params.halo_min_saturation)
            & (sat < params.min_saturation)
            & (hsv[..., 2] >= params.halo_min_value)
        )
        | (norm_min >= params.halo_min_value + 80)
        | core
    )
    grown = core.astype(np.uint8)
    allowed_u8 = allowed.astype(np.uint8)
    cross = np.ones((3, 3), np.uint8)
    for _ in range(halo_px):
        grown = cv2.dilate(grown, cross) & allowed_u8
    return grown.astype(bool)


@dataclass
class _Candidate:
    score: float
    where: tuple[float, float]
    area: float
    z_mm: float
    disc: int
    dot: int | None  # None: the dot is washed out
    origin: tuple[int, int] = (0, 0)  # (x0, y0) of the window below, search image
    region: NDArray[np.bool_] | None = None  # the blob in its window, search image
    recovered: bool = False  # washed-out pixels were added to it
    foreshortening: float = 1.0  # minor / major axis expected from the surface's tilt


def _foreshortening(
    depth_roi: NDArray, mask: NDArray[np.bool_], x0: int, y0: int, intrinsics: Intrinsics
) -> float:
    """How much the surface of a blob is tilted against the optical axis, from the
    depth of the blob's own pixels: ``|n_z|`` of the plane fitted to them (1.0 when too
    little depth is read).

    Under a pinhole camera a disc parallel to the image plane images as a circle
    wherever it is in the view; tilted, it images as (nearly) an ellipse whose minor /
    major axis ratio is this cosine. Only the sticker's own pixels are used: around a
    sticker partly under an object or a flap lies another surface.
    """
    h, w = depth_roi.shape
    yy, xx = np.mgrid[y0 : y0 + h, x0 : x0 + w]
    near = mask & (depth_roi > 0)
    if near.sum() < 12:
        return 1.0
    z = depth_roi[near].astype(np.float64)
    pts = np.column_stack(
        [
            (xx[near] - intrinsics.cx) / intrinsics.fx * z,
            (yy[near] - intrinsics.cy) / intrinsics.fy * z,
            z,
        ]
    )
    normal = _plane_normal(pts)
    if abs(normal[2]) > 0.95:  # face-on, as nearly every sticker on a lying napkin is
        return float(abs(normal[2]))
    # drop flying pixels at the blob's rim, then fit again
    off = np.abs((pts - pts.mean(axis=0)) @ normal)
    keep = off < max(3.0, 2.5 * _median(off))
    if keep.sum() < 12:
        return 1.0
    return float(abs(_plane_normal(pts[keep])[2]))


def _plane_normal(pts: NDArray) -> NDArray:
    """Unit normal of the least-squares plane through points (n, 3)."""
    centred = pts - pts.mean(axis=0)
    return np.linalg.eigh(centred.T @ centred)[1][:, 0]


def _ellipse_of(m: dict) -> tuple[float, float]:
    """Minor / major axis ratio of a blob's moment ellipse and the image angle of its
    minor axis (radians)."""
    mu20, mu02, mu11 = m["mu20"], m["mu02"], m["mu11"]
    common = np.sqrt(4 * mu11**2 + (mu20 - mu02) ** 2)
    major, minor = mu20 + mu02 + common, max(mu20 + mu02 - common, 1e-9)
    major_angle = 0.5 * np.arctan2(2 * mu11, mu20 - mu02)
    return float(np.sqrt(minor / major)), float(major_angle + np.pi / 2)


def _median(values: NDArray) -> float:
    """Median of a non-empty 1-d array (the upper one for an even count): np.median
    without its overhead, for the many small arrays of the candidate loop."""
    k = len(values) // 2
    return float(np.partition(values, k)[k])


def _halved(intrinsics: Intrinsics) -> Intrinsics:
    """Intrinsics of the image halved with pixel-area averaging (pixel-centre convention:
    full-resolution u is 2 u' + 0.5)."""
    return Intrinsics(
        intrinsics.width // 2,
        intrinsics.height // 2,
        intrinsics.fx / 2,
        intrinsics.fy / 2,
        (intrinsics.cx - 0.5) / 2,
        (intrinsics.cy - 0.5) / 2,
    )


def _sticker_mask(
    norm: NDArray[np.uint8], hue_lut: NDArray[np.uint8], params: DetectorParams
) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """Colour label (0 none, k + 1 colour k) of every pixel of a balanced RGB image, and
    its HSV. Shapes (h, w) and (h, w, 3)."""
    import cv2

    hsv = cv2.cvtColor(norm, cv2.COLOR_RGB2HSV)
    coloured = cv2.inRange(hsv, (0, params.min_saturation, params.min_value), (180, 255, 255))
    # chroma = S * V / 255 >= min_chroma: only binding where V is low (dark, noisy pixels)
    v_limit = int(np.ceil(params.min_chroma * 255 / max(params.min_saturation, 1)))
    dark_mask = cv2.bitwise_and(
        coloured, cv2.inRange(hsv, (0, 0, 0), (180, 255, max(v_limit - 1, 0)))
    )
    if cv2.countNonZero(dark_mask):
        dv, du = np.nonzero(dark_mask)
        faint = hsv[dv, du, 1].astype(np.int32) * hsv[dv, du, 2] < params.min_chroma * 255
        coloured[dv[faint], du[faint]] = 0
    labels = cv2.LUT(hsv[..., 0], np.concatenate([hue_lut, np.zeros(76, np.uint8)]))
    return cv2.bitwise_and(labels, coloured), hsv


def _refine(
    color: NDArray[np.uint8],
    lut: NDArray[np.uint8],
    hue_lut: NDArray[np.uint8],
    params: DetectorParams,
    c: _Candidate,
) -> tuple[tuple[float, float], float]:
    """Centre and area of a blob found in the halved image, measured at full resolution:
    its sticker-coloured (or blown-out) pixels within the blob, grown by two pixels. A
    blob completed with a highlight's pale halo keeps its centre from the halved image
    (the halo is no sticker colour)."""
    import cv2

    if c.recovered or c.region is None:
        return (2 * c.where[0] + 0.5, 2 * c.where[1] + 0.5), 4 * c.area
    h, w = c.region.shape
    x0, y0 = 2 * c.origin[0], 2 * c.origin[1]
    x1, y1 = min(x0 + 2 * w, color.shape[1]), min(y0 + 2 * h, color.shape[0])
    up = cv2.resize(c.region.astype(np.uint8), (2 * w, 2 * h), interpolation=cv2.INTER_NEAREST)
    up = cv2.dilate(up, np.ones((5, 5), np.uint8))[: y1 - y0, : x1 - x0]
    win = color[y0:y1, x0:x1]
    labels, _ = _sticker_mask(cv2.LUT(win, lut), hue_lut, params)
    blown = cv2.inRange(win, (params.highlight_min,) * 3, (255, 255, 255))
    region = cv2.bitwise_and(up, cv2.bitwise_or((labels > 0).astype(np.uint8), blown // 255))
    contours, _ = cv2.findContours(region, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not contours:
        return (2 * c.where[0] + 0.5, 2 * c.where[1] + 0.5), 4 * c.area
    contour = max(contours, key=cv2.contourArea)
    m = cv2.moments(contour)
    if m["m00"] <= 0:
        return (2 * c.where[0] + 0.5, 2 * c.where[1] + 0.5), 4 * c.area
    return (m["m10"] / m["m00"] + x0, m["m01"] / m["m00"] + y0), float(m["m00"])


def detect_stickers(
    color: NDArray[np.uint8],
    depth_mm: NDArray[np.uint16],
    intrinsics: Intrinsics,
    layout: NapkinLayout,
    params: DetectorParams | None = None,
    *,
    napkin: NapkinView | None = None,
    colours: dict[str, tuple[int, int, int]] | None = None,
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
    napkin : NapkinView, keyword-only, optional
        The napkin's white and highlights (default: :func:`.napkin.find_napkin`).
    colours : dict, keyword-only, optional
        Calibrated sticker colours (``dgli calibrate``), sRGB per colour name.

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
    if napkin is None:
        napkin = find_napkin(color, depth_mm, intrinsics)
    n = layout.n_stickers
    hue_lut, names = _hue_lut(layout, params, colours)
    coarse = depth_mm[::8, ::8]
    med_depth = float(np.median(coarse[coarse > 0])) if (coarse > 0).any() else np.nan
    disc_r_mm = layout.disc_diameter_mm / 2
    # Search at half resolution while stickers stay large enough there.
    full_color, full_fx = color, intrinsics.fx
    halve = (
        bool(med_depth > 0)
        and (disc_r_mm * intrinsics.fx / med_depth >= 2 * params.search_radius_px)
        and min(color.shape[:2]) >= 200
    )
    if halve:
        h2, w2 = color.shape[0] // 2, color.shape[1] // 2
        color = cv2.resize(color[: 2 * h2, : 2 * w2], (w2, h2), interpolation=cv2.INTER_AREA)
        depth_mm = depth_mm[: 2 * h2 : 2, : 2 * w2 : 2]
        intrinsics = _halved(intrinsics)
    norm = cv2.LUT(color, napkin.lut)  # the napkin neutral at a fixed level
    labels, hsv = _sticker_mask(norm, hue_lut, params)
    mask = cv2.threshold(labels, 0, 1, cv2.THRESH_BINARY)[1]
    halo_px = max(params.highlight_halo_px // (2 if halve else 1), 1)
    # Outer boundaries of every component, also those inside holes of others (a
    # saturated surround never hides what lies inside it).
    contours, hierarchy = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    if hierarchy is None:
        contours, hierarchy = (), np.zeros((1, 0, 4), int)
    outer = [c for c, h in zip(contours, hierarchy[0]) if h[3] < 0]
    lin = srgb_lut()
    napkin_not_blown = napkin.white_rgb.max() < lin[params.napkin_blown_level]
    blown = (
        cv2.bitwise_or(
            cv2.inRange(color, (params.highlight_min,) * 3, (255, 255, 255)),
            cv2.inRange(hsv, (0, 0, params.highlight_min), (180, 10, 255)),
        )
        > 0
    )
    # A sticker cannot be smaller than the smallest accepted area at the farthest depth.
    min_px = 0.3 * np.pi * (disc_r_mm * intrinsics.fx / (2.0 * max(med_depth, 1.0))) ** 2
    h_img, w_img = mask.shape
    candidates: list[_Candidate] = []
    rejected = []
    for contour in outer:
        area0 = cv2.contourArea(contour)
        if area0 < max(min_px, 12.0):
            continue
        m = cv2.moments(contour)
        if m["m00"] <= 0:
            continue
        cu, cv = m["m10"] / m["m00"], m["m01"] / m["m00"]
        x, y, w, h = cv2.boundingRect(contour)
        roi = np.zeros((h, w), np.uint8)
        cv2.drawContours(roi, [contour - [x, y]], -1, 1, thickness=-1)
        depth_roi = depth_mm[y : y + h, x : x + w]
        inner_depth = depth_roi[cv2.erode(roi, np.ones((3, 3), np.uint8)).astype(bool)]
        inner_depth = inner_depth[inner_depth > 0]
        if inner_depth.size == 0:
            inner_depth = depth_roi[roi.astype(bool) & (depth_roi > 0)]
        z_mm = _median(inner_depth) if inner_depth.size else med_depth
        where = (float(cu), float(cv))
        if not (z_mm > 0):
            rejected.append(Rejection(where, area0, "no depth to judge its size"))
            continue
        r_exp = disc_r_mm * intrinsics.fx / z_mm
        # A window around the blob, one expected diameter wider on each side.
        pad = int(np.ceil(2 * r_exp)) + 2
        x0, y0 = max(x - pad, 0), max(y - pad, 0)
        x1, y1 = min(x + w + pad, w_img), min(y + h + pad, h_img)
        # A sticker on a flap held up at an angle images as an ellipse: its minor axis is
        # shortened by the tilt read from the depth around it.
        fore, minor_angle = 1.0, 0.0
        q, angle = _ellipse_of(m)
        if q <= params.flat_foreshortening:  # elongated: tilted, or cut by an edge?
            # The sticker's own depth says whether it is tilted; how much, its shape says
            # more precisely than a plane fitted to a few noisy millimetres of depth. The
            # two must agree: a disc cut by an edge is also elongated, but flat.
            tilt = _foreshortening(depth_roi, roi.astype(bool), x, y, intrinsics)
            if tilt <= params.flat_foreshortening and abs(q - tilt) <= params.tilt_agreement:
                fore, minor_angle = q, angle
        if fore < params.min_foreshortening:
            rejected.append(
                Rejection(
                    (float(cu), float(cv)), area0, f"seen too obliquely (foreshortened {fore:.2f})"
                )
            )
            continue
        expected = np.pi * r_exp**2 * fore
        inside = np.zeros((y1 - y0, x1 - x0), bool)
        inside[y - y0 : y - y0 + h, x - x0 : x - x0 + w] = roi.astype(bool)
        win = norm[y0:y1, x0:x1]
        yy, xx = np.mgrid[y0:y1, x0:x1]
        # Washed-out pixels (a glossy sticker's highlight) next to the blob are part of
        # it, unless the napkin itself is blown out.
        washed = np.zeros(inside.shape, dtype=bool)
        if napkin_not_blown and blown[y0:y1, x0:x1].any():
            washed = _washed_out(
                color[y0:y1, x0:x1], win, hsv[y0:y1, x0:x1], params, r_exp, halo_px
            ) & (np.hypot(xx - cu, yy - cv) < params.highlight_reach * r_exp)
        recovered = bool((washed & ~inside).any())
        if recovered:
            union = (inside | washed).astype(np.uint8)
            _, lab_img, _, _ = cv2.connectedComponentsWithStats(union, connectivity=8)
            keep = lab_img == lab_img[inside][0] if inside.any() else union.astype(bool)
            inside = keep
            mu = cv2.moments(inside.astype(np.uint8), binaryImage=True)
            cu, cv = mu["m10"] / mu["m00"] + x0, mu["m01"] / mu["m00"] + y0
            cs, _ = cv2.findContours(
                inside.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE
            )
            contour = max(cs, key=cv2.contourArea)
            m = cv2.moments(contour)
            area0 = float(inside.sum())
            where = (float(cu), float(cv))
        inside_colour = inside & (labels[y0:y1, x0:x1] > 0)
        area = area0
        # Halved, a blob loses about half a pixel of its rim to blending with the cloth;
        # its area is judged again at full resolution (see ``take``).
        rim = 0.5 if halve else 0.0
        ratio = area / (np.pi * max(r_exp - rim, 1.0) * max(fore * r_exp - rim, 1.0))
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
        solidity = min(area / hull_area, 1.0) if hull_area > 0 else 0.0
        mu20, mu02, mu11 = m["mu20"], m["mu02"], m["mu11"]
        common = np.sqrt(4 * mu11**2 + (mu20 - mu02) ** 2)
        elongation = np.sqrt((mu20 + mu02 + common) / max(mu20 + mu02 - common, 1e-9))
        if solidity < params.min_solidity or elongation * fore > params.max_elongation:
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
        radius = np.sqrt(max(area, expected) / (np.pi * fore))  # the major semi-axis
        if fore < 1.0:  # elliptic radius: the minor axis along the normal's projection
            ca, sa = np.cos(minor_angle), np.sin(minor_angle)
            along, across = (xx - cu) * ca + (yy - cv) * sa, -(xx - cu) * sa + (yy - cv) * ca
            r = np.hypot(along / fore, across) / radius
        else:
            r = np.hypot(xx - cu, yy - cv) / radius
        fill = inside[r < 1.0].sum() / (np.pi * radius**2 * fore)
        if fill < params.min_fill:
            rejected.append(Rejection(where, area, f"not a whole disc (covers {fill:.2f} of one)"))
            continue
        # The surround: a sticker lies on white cloth, an object on a table does not.
        ring = (r > 1.3) & (r < 1.8) & ~inside
        disc_px = win[inside_colour & (r < 0.95)]
        if ring.any() and disc_px.size:
            ring_px = win[ring]
            white = _median(
                lin[np.minimum(np.minimum(ring_px[:, 0], ring_px[:, 1]), ring_px[:, 2])]
            )
            own = _median(lin[np.maximum(np.maximum(disc_px[:, 0], disc_px[:, 1]), disc_px[:, 2])])
            if white < params.min_surround * own:
                rejected.append(
                    Rejection(
                        where,
                        area,
                        f"not on the napkin (surround {white / max(own, 1e-6):.2f} as bright "
                        "as the blob)",
                    )
                )
                continue
        lab = labels[y0:y1, x0:x1]
        outer_band = lab[inside & (r > 0.6) & (r < 0.95) & (lab > 0)]
        inner_area = r < 0.28
        inner = lab[inside & inner_area & (lab > 0)]
        if outer_band.size == 0:
            rejected.append(Rejection(where, area, "no disc colour inside"))
            continue
        disc_counts = np.bincount(outer_band, minlength=len(names) + 1)
        disc = int(np.argmax(disc_counts))
        purity = disc_counts[disc] / outer_band.size
        dot: int | None = None
        if inner.size >= params.min_dot_seen * inner_area.sum():
            dot_counts = np.bincount(inner, minlength=len(names) + 1)
            dot = int(np.argmax(dot_counts))
            purity = min(purity, dot_counts[dot] / inner.size)
        elif not (washed & inner_area).any():
            rejected.append(Rejection(where, area, "no dot colour inside"))
            continue
        if purity < params.min_purity:
            rejected.append(Rejection(where, area, f"mixed colours (purity {purity:.2f})"))
            continue
        score = float(purity * min(ratio, 1 / ratio) * solidity)
        score *= 0.8 if recovered else 1.0
        candidates.append(
            _Candidate(score, where, area, z_mm, disc, dot, (x0, y0), inside, recovered, fore)
        )
    centroids = np.full((n, 2), np.nan)
    areas = np.full(n, np.nan)
    scores = np.zeros(n)
    depths = np.full(n, np.nan)
    fores = np.full(n, np.nan)

    def take(sid: int, c: _Candidate, score: float) -> bool:
        where, area = c.where, c.area
        if halve:
            where, area = _refine(full_color, napkin.lut, hue_lut, params, c)
            expected = np.pi * (disc_r_mm * full_fx / c.z_mm) ** 2 * c.foreshortening
            if area < params.min_area_ratio * expected:
                rejected.append(
                    Rejection(
                        ((where[0] - 0.5) / 2, (where[1] - 0.5) / 2),
                        area / 4,
                        f"too small for a sticker at {c.z_mm:.0f} mm "
                        f"({area / expected:.2f} of a disc at full resolution)",
                    )
                )
                return False
        centroids[sid], areas[sid] = where, area
        scores[sid] = score
        depths[sid] = c.z_mm
        fores[sid] = c.foreshortening
        return True

    pending = []
    for c in sorted(candidates, key=lambda c: -c.score):
        if c.dot is None:
            pending.append(c)
            continue
        sid = layout.sticker_id(names[c.disc - 1], names[c.dot - 1])
        if sid is None:
            rejected.append(
                Rejection(
                    c.where,
                    c.area,
                    f"no sticker is {names[c.disc - 1]} with a {names[c.dot - 1]} dot",
                )
            )
            continue
        if scores[sid] > 0:
            rejected.append(
                Rejection(c.where, c.area, f"second blob for sticker {sid} (lower score)")
            )
            continue
        take(sid, c, c.score)
    # A dot lost to a highlight: the disc colour leaves four stickers; if only one of
    # them is still unaccounted for, it is that one.
    for c in pending:
        disc_name = names[c.disc - 1]
        free = [
            sid for sid in range(n) if layout.sticker_disc[sid] == disc_name and scores[sid] == 0
        ]
        if len(free) == 1:
            take(free[0], c, 0.5 * c.score)
        else:
            rejected.append(
                Rejection(
                    c.where,
                    c.area,
                    f"{disc_name} disc with its dot washed out; {len(free)} stickers possible",
                )
            )
    if halve:  # report rejections in full-resolution pixels
        rejected = [
            Rejection((2 * r.centroid[0] + 0.5, 2 * r.centroid[1] + 0.5), 4 * r.area_px, why)
            for r, why in ((r, r.reason) for r in rejected)
        ]
    return StickerDetections(centroids, areas, scores, depths, tuple(rejected), fores)


def find_washed_out(
    color: NDArray[np.uint8],
    depth_mm: NDArray[np.uint16],
    intrinsics: Intrinsics,
    layout: NapkinLayout,
    found: StickerDetections,
    params: DetectorParams | None = None,
    *,
    napkin: NapkinView,
    colours: dict[str, tuple[int, int, int]] | None = None,
) -> StickerDetections:
    """Search again, for the stickers not found, as a broad sheen leaves them: pastel.

    A semi-gloss sticker under a large light (a softbox, a window) reflects white light
    over its whole disc: its saturation falls to 0.1-0.3 while its hue survives, and
    nothing is blown out. The search runs :func:`detect_stickers` again with
    ``washed_saturation`` and ``washed_chroma`` (every other check unchanged: size,
    shape, disc and dot colours, white cloth around) and keeps what it finds of the
    stickers ``found`` lacks, away from the stickers found (a disc's distance).

    Parameters
    ----------
    color, depth_mm, intrinsics, layout, params, napkin, colours
        As for :func:`detect_stickers`.
    found : StickerDetections
        The first search's result.

    Returns
    -------
    StickerDetections
        ``found`` with the washed-out stickers added (their scores halved, so that a
        person reading them sees which they are); its rejections are the first search's.
    """
    from dataclasses import replace

    params = params or DetectorParams()
    missing = ~found.found
    if not missing.any():
        return found
    pale = replace(
        params,
        min_saturation=params.washed_saturation,
        min_chroma=params.washed_chroma,
        min_surround=params.washed_surround,
    )
    lower = replace(napkin, lut=balance_lut(napkin.white_rgb, params.washed_level))
    def unread(d: StickerDetections) -> StickerDetections:
        """``d`` with the pastel patches on the napkin that no search could read."""
        left = _pale_samples(color, d, layout, params, lower, colours, edge_cells=1)
        return _washed(d, left, lower.stride)

    if len(_pale_samples(color, found, layout, params, lower, colours)[0]) < 2:
        return found  # no pastel patch anywhere: nothing to search, nothing left unread
    again = detect_stickers(
        color, depth_mm, intrinsics, layout, pale, napkin=lower, colours=colours
    )
    new = missing & again.found
    if not new.any():
        return unread(found)
    seen = found.centroids[found.found]
    if len(seen):
        d_px = np.linalg.norm(again.centroids[:, None] - seen[None], axis=2).min(axis=1)
        radius = np.sqrt(np.where(again.found, again.areas, 0.0) / np.pi)
        new &= ~(d_px < 2 * radius)
    n = len(found.centroids)
    keys = ("centroids", "areas", "scores", "depth_mm", "foreshortening")
    out = {k: np.array(getattr(found, k) if getattr(found, k) is not None else np.ones(n))
           for k in keys}
    for k in keys:
        if getattr(again, k) is not None:
            out[k][new] = getattr(again, k)[new]
    out["scores"][new] *= 0.5
    merged = StickerDetections(
        out["centroids"], out["areas"], out["scores"], out["depth_mm"], found.rejected,
        out["foreshortening"],
    )
    return unread(merged)


def _pale_samples(
    color: NDArray[np.uint8],
    found: StickerDetections,
    layout: NapkinLayout,
    params: DetectorParams,
    lower: NapkinView,
    colours: dict[str, tuple[int, int, int]] | None,
    *,
    edge_cells: int = 0,
) -> tuple[NDArray[np.float64], tuple[str, ...]]:
    """Pixels (x, y), shape (k, 2), and colour names of pastel samples of a sticker hue
    away from the
    stickers found, on the napkin's sampling grid (``lower.stride``): a cheap look before
    the second search, and what it leaves unread.

    Pastel: HSV saturation from ``washed_saturation`` to below ``min_saturation`` in the
    image balanced by ``lower.lut``, on the napkin and ``edge_cells`` cells in from its
    edge (cells across the edge mix white with the table, and a tinted or wood table is
    pale too); anywhere when the napkin is not told from the table. The rims of the
    stickers found are pastel too (their pixels mix with the cloth), so samples within
    two disc radii of them do not count.
    """
    import cv2

    s = lower.stride
    h, w = color.shape[0] // s, color.shape[1] // s
    # cells of s x s pixels averaged: a sensor's noise tints single pixels, not cells
    sub = cv2.resize(color[: h * s, : w * s], (w, h), interpolation=cv2.INTER_AREA)
    hsv = cv2.cvtColor(cv2.LUT(sub, lower.lut), cv2.COLOR_RGB2HSV)
    pale = cv2.inRange(
        hsv,
        (0, params.washed_saturation, params.min_value),
        (180, max(params.min_saturation - 1, 0), 255),
    ).astype(bool)
    hue_lut, _ = _hue_lut(layout, params, colours)
    sticker_hue = hue_lut[np.minimum(hsv[..., 0], 179)] > 0
    pale &= sticker_hue
    # a sheen washes whole discs: pale cells next to vivid ones are the rim of a sticker
    # partly under a flap, not a washed-out one
    vivid = cv2.inRange(hsv, (0, params.min_saturation, params.min_value), (180, 255, 255))
    vivid = cv2.dilate(vivid & sticker_hue.astype(np.uint8) * 255, np.ones((5, 5), np.uint8))
    pale &= vivid == 0
    if found.found.any() and pale.any():  # (with nothing found, look anywhere)
        cloth = cloth_cells(color, lower, found.centroids, FootprintParams(cell_px=s))
        if cloth is not None:  # (else the napkin is not told from the table: anywhere)
            edge = np.ones((2 * edge_cells + 1,) * 2, np.uint8)
            pale &= cv2.erode(cloth.astype(np.uint8), edge).astype(bool)
    ys, xs = np.nonzero(pale)
    pts = (np.column_stack([xs, ys]).astype(np.float64) + 0.5) * s
    names = [_hue_lut(layout, params, colours)[1][k - 1] for k in hue_lut[hsv[ys, xs, 0]]]
    if not len(pts) or not found.found.any():
        return pts, tuple(names)
    radius = float(np.sqrt(np.nanmedian(found.areas[found.found]) / np.pi))
    seen = found.centroids[found.found]
    far = np.linalg.norm(pts[:, None] - seen[None], axis=2).min(axis=1) >= 2 * radius
    return pts[far], tuple(n for n, f in zip(names, far) if f)


def _washed(
    found: StickerDetections, left: tuple[NDArray, tuple[str, ...]], stride: int
) -> StickerDetections:
    """``found`` with the pastel samples left unread, and the colours of those that clump
    like a sticker: a connected patch (on the sampling grid of ``stride`` pixels) of at
    least a third of a sticker's area (that of the stickers found; 3 samples at least).
    Sensor noise in a dim image tints single samples, never a patch."""
    from dataclasses import replace

    import cv2

    pts, names = left
    colours = []
    if len(pts):
        cells = (pts // stride).astype(int)
        disc = np.nanmedian(found.areas[found.found]) if found.found.any() else np.nan
        least = max(3.0, np.nan_to_num(disc / stride**2 / 3, nan=3.0))
        grid = np.zeros((cells[:, 1].max() + 1, cells[:, 0].max() + 1), np.uint8)
        for name in sorted(set(names)):
            grid[:] = 0
            mine = np.array([n == name for n in names])
            grid[cells[mine, 1], cells[mine, 0]] = 1
            _, _, stats, _ = cv2.connectedComponentsWithStats(grid, connectivity=8)
            if (stats[1:, cv2.CC_STAT_AREA] >= least).any():
                colours.append(name)
    return replace(found, pale_px=pts, pale_colours=tuple(colours))


def detect_all_stickers(
    color: NDArray[np.uint8],
    depth_mm: NDArray[np.uint16],
    intrinsics: Intrinsics,
    layout: NapkinLayout,
    params: DetectorParams | None = None,
    *,
    source: str,
    purpose: str,
) -> tuple[StickerDetections, NapkinView]:
    """Detect every sticker of the flat napkin, as a calibration needs them.

    Parameters
    ----------
    color, depth_mm, intrinsics, layout, params
        As for :func:`detect_stickers`.
    source : str, keyword-only
        Name of the image, for messages.
    purpose : str, keyword-only
        What needs them (``"lens calibration"``), for messages.

    Returns
    -------
    StickerDetections, NapkinView
        The 16 stickers, and the napkin they were found on.

    Raises
    ------
    CalibrationError
        With fewer than all the stickers found, naming the missing ones.
    """
    from ..errors import CalibrationError

    napkin = find_napkin(color, depth_mm, intrinsics)
    det = detect_stickers(color, depth_mm, intrinsics, layout, params, napkin=napkin)
    if not det.found.all():
        missing = np.flatnonzero(~det.found).tolist()
        raise CalibrationError(
            f"'{source}': found {int(det.found.sum())} of {layout.n_stickers} stickers "
            f"(missing {missing}); {purpose} needs the flat napkin with all "
            f"{layout.n_stickers} stickers in view"
        )
    return det, napkin
