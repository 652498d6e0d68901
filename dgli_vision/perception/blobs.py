"""Judging one blob of the colour mask: a candidate sticker, or a rejection and why.

A blob (an outer contour of the labelled pixels, :mod:`.labels`) is judged in the steps
below, each a function; the first that fails gives the :class:`~.detections.Rejection`:

1. its depth (the median of its own pixels), which gives the disc size expected there;
2. its foreshortening: an elongated blob whose own depth says it is tilted as much is a
   disc on a tilted flap; an elongated blob on flat cloth is a disc cut by an edge;
3. highlight repair: the washed-out pixels of a glossy sticker's highlight next to it
   are joined to it;
4. its size against the expected disc, and its shape (solidity, elongation);
5. its fill of the expected disc centred on it, and white cloth around it;
6. its disc colour (the majority label of an outer band) and dot colour (of the inner
   part), which name the sticker.

Everything the steps share for one frame is a :class:`SearchImage`. Steps 1-4 run blob
by blob (:func:`judge_blobs`; a blob's depth is one partial sort of its own pixels,
cheaper than any batch when one blob is large); steps 5 and 6 for every blob left at
once, on the pixels within 1.8 radii of each (:class:`_DiscPixels`: counts and medians
per blob), which gives each blob exactly what judging it alone gives
(:func:`judge_blob`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property, lru_cache

import numpy as np
from numpy.typing import NDArray

from ..core.camera import Intrinsics
from ..core.colour import srgb_lut
from ..core.order_stats import median, quantile
from .detections import DetectorParams, Rejection, RejectionKind
from .params import DiscBands, disc_bands

__all__ = [
    "Candidate", "SearchImage", "judge_blob", "judge_blobs", "least_area", "window_pad",
]

#: A 3 x 3 square: erosion by one pixel.
_SQUARE3 = np.ones((3, 3), np.uint8)
_SQUARE3.flags.writeable = False

#: A failed check: its kind and the values it measured (a :class:`Rejection` less where).
_Problem = tuple[RejectionKind, dict[str, float]]

def _default_bands() -> DiscBands:
    """The packaged layout's :class:`~.params.DiscBands`."""
    from ..core.layout import default_layout

    return disc_bands(default_layout())


#: The ring around a blob whose whiteness says it lies on the napkin, in disc radii.
_RING_INNER, _RING_OUTER = 1.3, 1.8


@dataclass(frozen=True, eq=False)
class SearchImage:
    """The image stickers are searched in (the frame, or the frame halved), and what
    every blob of it is judged against.

    Attributes
    ----------
    color : ndarray of uint8, shape (h, w, 3)
        RGB as taken (halved by pixel-area averaging when ``halved``).
    norm : ndarray of uint8, shape (h, w, 3)
        ``color`` balanced to the napkin's white (``NapkinView.lut``).
    hsv : ndarray of uint8, shape (h, w, 3)
        HSV of ``norm``.
    labels : ndarray of uint8, shape (h, w)
        Colour label of every pixel: 0 none, k + 1 colour k (:func:`.labels.colour_labels`).
    depth_mm : ndarray of uint16, shape (h, w)
        Depth, mm (0 = no reading), sampled to the search image.
    intrinsics : Intrinsics
        Of the search image.
    median_depth_mm : float
        Median depth of the frame, mm; NaN without readings.
    disc_radius_mm : float
        Radius of a sticker's disc.
    min_area_px : float
        Blobs smaller than this (and than 12 pixels) are specks, not judged.
    halved : bool
        The search image is the frame halved.
    halo_px : int
        Width of a highlight's pale halo in the search image, pixels.
    repair_highlights : bool
        The napkin itself is not blown out, so highlights can be told from cloth.
    n_colours : int
        Number of sticker colours.
    params : DetectorParams
    within : (int, int, int, int), optional
        (x0, y0, x1, y1): the box stickers are searched in (near the napkin); only the
        blobs lying wholly within it are judged, each as in a search of the whole
        image (the images are computed as far beyond it as their windows reach).
        None: everywhere.
    traced : (ndarray, list), optional
        The ``labels`` array and the outer contours of its blobs to judge, specks left
        out (:func:`least_area`), as :func:`.detect.search_image` traced them (read
        only while ``labels`` is that array); None: traced when judged.
    palette : ndarray, shape (n_colours, 3), optional
        The sticker colours, linear RGB in label order: a small sticker's dot blurred
        into its disc is read by the colour it adds (:func:`_dots_by_difference`).
        None: dots are read by their labels only.
    bands : DiscBands
        Where a disc's and a dot's colours are read, in radii (the layout's:
        :func:`.params.disc_bands`).
    """

    color: NDArray[np.uint8]
    norm: NDArray[np.uint8]
    hsv: NDArray[np.uint8]
    labels: NDArray[np.uint8]
    depth_mm: NDArray[np.uint16]
    intrinsics: Intrinsics
    median_depth_mm: float
    disc_radius_mm: float
    min_area_px: float
    halved: bool
    halo_px: int
    repair_highlights: bool
    n_colours: int
    params: DetectorParams
    within: tuple[int, int, int, int] | None = None
    traced: tuple[NDArray[np.uint8], list[NDArray[np.int32]]] | None = None
    palette: NDArray[np.float64] | None = None
    bands: DiscBands = field(default_factory=_default_bands)

    def any_blown(self, window: tuple[int, int, int, int]) -> bool:
        """Whether a pixel of ``window`` (x0, y0, x1, y1) is washed out: blown out as
        taken (every channel at least ``highlight_min``), or near-white once balanced
        (HSV value at least that, saturation at most 10).

        Each test runs only where the window's largest value reaches ``highlight_min``
        (no pixel can pass it otherwise; one reduction is cheaper, and near every
        sticker the largest value falls short)."""
        import cv2

        x0, y0, x1, y1 = window
        least = self.params.highlight_min
        color, hsv = self.color[y0:y1, x0:x1], self.hsv[y0:y1, x0:x1]
        if not color.size:
            return False
        return bool(
            (
                color.max() >= least
                and cv2.countNonZero(cv2.inRange(color, (least,) * 3, (255,) * 3))
            )
            or (
                hsv.max() >= least
                and cv2.countNonZero(cv2.inRange(hsv, (0, 0, least), (180, 10, 255)))
            )
        )


@dataclass(frozen=True, eq=False)
class Candidate:
    """A blob taken as a sticker, its identity still to be given.

    ``disc`` and ``dot`` are colour labels (k + 1 for colour k); ``dot`` is None where a
    highlight washed the dot out. ``origin`` is the (x0, y0) of the window ``region``
    (the blob) is cut from, in the search image. ``recovered``: washed-out pixels were
    joined to it. ``foreshortening``: minor / major axis expected from its tilt.
    """

    score: float
    where: tuple[float, float]
    area: float
    z_mm: float
    disc: int
    dot: int | None
    origin: tuple[int, int] = (0, 0)
    region: NDArray[np.bool_] | None = None
    recovered: bool = False
    foreshortening: float = 1.0


@dataclass(frozen=True, eq=False)
class _Blob:
    """One blob in its window of the search image.

    Attributes
    ----------
    where : (float, float)
        Centroid (u, v), search-image pixels.
    area : float
        Pixels.
    contour : ndarray
        Its outer contour; ``moments`` are the contour's.
    box : (int, int, int, int)
        Bounding box (x, y, w, h) of the contour as found.
    window : (int, int, int, int)
        (x0, y0, x1, y1): the box grown by an expected diameter on each side.
    inside : ndarray of bool, shape (y1 - y0, x1 - x0)
        The blob in its window.
    z_mm, r_exp : float
        Its depth, and the radius of a face-on disc there (pixels).
    washed : ndarray of bool, same shape as ``inside``, optional
        Washed-out pixels near it (after :func:`_repair_highlight`); None where the
        window has none.
    recovered : bool
        Washed-out pixels were joined to it.
    """

    where: tuple[float, float]
    area: float
    contour: NDArray
    moments: dict
    box: tuple[int, int, int, int]
    window: tuple[int, int, int, int]
    inside: NDArray[np.bool_]
    z_mm: float
    r_exp: float
    washed: NDArray[np.bool_] | None = None
    recovered: bool = False

    @property
    def grid(self) -> tuple[NDArray, NDArray]:
        """Pixel rows and columns (yy, xx) of the window, search image, as an open grid
        (shapes (h, 1) and (1, w): they broadcast to the window)."""
        x0, y0, x1, y1 = self.window
        return np.ogrid[y0:y1, x0:x1]


@dataclass(frozen=True)
class _Colours:
    """Disc and dot colour labels of a blob (dot None: washed out) and their purity."""

    disc: int
    dot: int | None
    purity: float


def judge_blob(contour: NDArray, image: SearchImage) -> Candidate | Rejection | None:
    """Judge one outer contour of the colour mask (:func:`judge_blobs` of one).

    Returns
    -------
    Candidate, Rejection or None
        A candidate sticker; the first check it fails, with the reason; or None for a
        speck too small to report.
    """
    return judge_blobs([contour], image)[0]


def judge_blobs(
    contours: Sequence[NDArray], image: SearchImage
) -> list[Candidate | Rejection | None]:
    """Judge outer contours of the colour mask, each as :func:`judge_blob` would.

    The checks up to the blob's shape run blob by blob; those on the disc centred on
    each blob (fill, surround, disc and dot colours) run for every blob left at once,
    on the pixels of all their windows together (:class:`_DiscPixels`).

    Returns
    -------
    list
        Per contour, in order: a candidate, the first check it fails (a rejection with
        the reason), or None for a speck too small to report.
    """
    judged: list[Candidate | Rejection | _Shaped | None] = [
        _judge_shape(c, image) for c in contours
    ]
    shaped = [j for j in judged if isinstance(j, _Shaped)]
    if not shaped:
        return [j for j in judged if not isinstance(j, _Shaped)]  # (all of them)
    discs = _DiscPixels.of(shaped, image)
    verdicts = iter([_judge_disc(s, k, discs, image) for k, s in enumerate(shaped)])
    return [next(verdicts) if isinstance(j, _Shaped) else j for j in judged]


@dataclass(frozen=True, eq=False)
class _Shaped:
    """A blob that passed the checks up to its shape: its tilt (``fore``, minor axis
    angle), area ratio to the expected disc, solidity, and the radius (pixels, the major
    semi-axis) of the disc its remaining checks are centred on."""

    blob: _Blob
    fore: float
    minor_angle: float
    ratio: float
    solidity: float
    radius: float


def _judge_shape(contour: NDArray, image: SearchImage) -> _Shaped | Rejection | None:
    """The checks of one blob up to its shape: depth, tilt, highlight repair, size,
    shape. The blob left, or the first check it fails (None: a speck)."""
    blob = _measure_blob(contour, image)
    if blob is None or isinstance(blob, Rejection):
        return blob
    if blob.area < image.params.min_area_ratio * np.pi * blob.r_exp**2:
        blob = _grown_to_its_rim(blob, image)
    fore, minor_angle = _tilt(blob, image)
    if fore < image.params.min_foreshortening:
        oblique = {"foreshortening": float(fore)}
        return Rejection(blob.where, blob.area, RejectionKind.OBLIQUE, oblique)
    blob = _repair_highlight(blob, image)
    p = image.params
    ratio = _area_ratio(blob, fore, image.halved)
    why = _size_problem(ratio, blob.z_mm, fore, p)
    if why:
        return Rejection(blob.where, blob.area, *why)
    solidity, elongation = _shape_of(blob)
    why = _shape_problem(solidity, elongation, fore, p)
    if why:
        return Rejection(blob.where, blob.area, *why)
    return _Shaped(blob, fore, minor_angle, ratio, solidity, _radius(blob, fore))


def _judge_disc(
    s: _Shaped, k: int, discs: _DiscPixels, image: SearchImage
) -> Candidate | Rejection:
    """The checks of the ``k``-th shaped blob on the disc centred on it (fill, surround,
    colours, from ``discs``): the candidate, or the first check it fails."""
    blob, p = s.blob, image.params
    why = _fill_problem(discs, k, s, p) or _surround_problem(discs, k, p)
    if why:
        return Rejection(blob.where, blob.area, *why)
    colours = _read_colours(s, k, discs, image)
    if not isinstance(colours, _Colours):
        return Rejection(blob.where, blob.area, *colours)
    score = float(colours.purity * min(s.ratio, 1 / s.ratio) * s.solidity)
    score *= 0.8 if blob.recovered else 1.0
    x0, y0 = blob.window[:2]
    return Candidate(
        score, blob.where, blob.area, blob.z_mm, colours.disc, colours.dot, (x0, y0),
        blob.inside, blob.recovered, s.fore,
    )


def _measure_blob(contour: NDArray, image: SearchImage) -> _Blob | Rejection | None:
    """The blob of ``contour``: centroid, area, depth and window; None for a speck, a
    rejection without depth to judge its size."""
    import cv2

    area = cv2.contourArea(contour)
    if area < least_area(image.min_area_px):
        return None
    m = cv2.moments(contour)
    if m["m00"] <= 0:
        return None
    where = (float(m["m10"] / m["m00"]), float(m["m01"] / m["m00"]))
    x, y, w, h = cv2.boundingRect(contour)
    roi = np.zeros((h, w), np.uint8)
    cv2.drawContours(roi, [contour], -1, 1, thickness=-1, offset=(-x, -y))
    z_mm = _blob_depth(image.depth_mm[y : y + h, x : x + w], roi, image.median_depth_mm)
    if not (z_mm > 0):
        return Rejection(where, area, RejectionKind.NO_DEPTH)
    r_exp = image.disc_radius_mm * image.intrinsics.fx / z_mm
    pad = window_pad(r_exp)
    h_img, w_img = image.labels.shape
    x0, y0 = max(x - pad, 0), max(y - pad, 0)
    x1, y1 = min(x + w + pad, w_img), min(y + h + pad, h_img)
    inside = np.zeros((y1 - y0, x1 - x0), bool)
    inside[y - y0 : y - y0 + h, x - x0 : x - x0 + w] = roi
    return _Blob(where, area, contour, m, (x, y, w, h), (x0, y0, x1, y1), inside, z_mm, r_exp)


def least_area(min_area_px: float) -> float:
    """The least contour area (pixels) of a blob that is judged, for a search image's
    ``min_area_px``: a smaller one is a speck, neither judged nor reported (no pixel of
    its window is read)."""
    return max(min_area_px, 12.0)


def window_pad(r_exp_px: float) -> int:
    """How far (pixels) a blob's window reaches beyond its bounding box, for a disc of
    radius ``r_exp_px`` expected there: one diameter and two pixels. Every check of the
    blob reads the search image within its window only."""
    return math.ceil(2 * r_exp_px) + 2


def _blob_depth(depth_roi: NDArray, roi: NDArray[np.uint8], fallback_mm: float) -> float:
    """Median depth (mm) of a blob's inner pixels (its mask ``roi`` eroded by one), of
    all its pixels when none of those has a reading, else ``fallback_mm``."""
    import cv2

    inner_depth = depth_roi[cv2.erode(roi, _SQUARE3).view(bool)]  # (0 or 1: as bool)
    inner_depth = inner_depth[inner_depth > 0]
    if inner_depth.size == 0:
        inner_depth = depth_roi[roi.view(bool) & (depth_roi > 0)]
    return _median(inner_depth) if inner_depth.size else fallback_mm


def _tilt(blob: _Blob, image: SearchImage) -> tuple[float, float]:
    """The blob's foreshortening (minor / major axis; 1.0 face-on) and the image angle of
    its minor axis (radians).

    A sticker on a flap held up at an angle images as an ellipse. The sticker's own depth
    says whether it is tilted; how much, its shape says more precisely than a plane
    fitted to a few noisy millimetres of depth. The two must agree: a disc cut by an
    edge is also elongated, but flat.
    """
    p = image.params
    q = _axis_ratio(blob.moments)
    if q > p.flat_foreshortening:  # round enough: face-on
        return 1.0, 0.0
    x, y, w, h = blob.box
    x0, y0 = blob.window[:2]
    roi = blob.inside[y - y0 : y - y0 + h, x - x0 : x - x0 + w]
    tilt = _foreshortening(image.depth_mm[y : y + h, x : x + w], roi, x, y, image.intrinsics)
    if tilt <= p.flat_foreshortening and abs(q - tilt) <= p.tilt_agreement:
        return q, _minor_angle(blob.moments)
    return 1.0, 0.0


def _grown_to_its_rim(blob: _Blob, image: SearchImage) -> _Blob:
    """The blob grown over the blurred rim its colour threshold cut off (a small
    sticker in a real camera's image); the blob as it was where there is none.

    A lens, a sensor's anti-aliasing filter and demosaicing blur a disc's edge over a
    pixel or two; a saturation threshold on the 8-bit sRGB image keeps only the part of
    the rim that is mostly sticker (a dark green or blue mixed half and half with white
    cloth keeps a third of its saturation there), so a sticker 15 pixels across keeps
    0.35-0.55 of its area, whatever its distance. In linear light a pixel of the rim is
    the sticker's colour mixed with the napkin's white: its chroma (largest minus
    smallest channel) is the sticker's times the share of sticker in the pixel, and its
    chroma's direction (the channels less the smallest, over the chroma) is the
    sticker's own. The pixels with at least half the sticker's chroma and its
    direction, connected to the blob and within ``blur_rim_px`` of the disc expected
    at its centre, are the disc as a sharp camera would have shown it (a half-covered
    pixel lies on a blurred edge's true place). A sliver of a sticker under a flap
    stays a sliver; cloth and table around it have little chroma or another direction.
    """
    import cv2

    p = image.params
    x0, y0, x1, y1 = blob.window
    yy, xx = blob.grid
    reach = blob.r_exp + p.blur_rim_px
    near = (xx - blob.where[0]) ** 2 + (yy - blob.where[1]) ** 2 <= reach * reach
    # every figure below is read on the blob and the pixels within reach alone: those
    # pixels, in the window's row order (as a mask of the window orders them)
    at = np.flatnonzero(blob.inside | near)
    near_at, inside_at = near.ravel()[at], blob.inside.ravel()[at]
    lin = srgb_lut()[np.take(image.norm[y0:y1, x0:x1].reshape(-1, 3), at, axis=0)]  # linear
    low = _channel_min(lin)
    chroma = _channel_max(lin) - low
    # the disc's colour: that of the coloured pixels around the blob within reach (the
    # rim the threshold cut off, or the whole ring of a disc too pale to be labelled
    # around a dot that was), else of the blob itself
    coloured = chroma >= p.rim_min_chroma
    around = near_at & ~inside_at & coloured
    source = around if np.count_nonzero(around) >= 4 else inside_at & coloured
    if not source.any():
        return blob
    direction = (lin - low[:, None]) / np.maximum(chroma, 1e-6)[:, None]
    seen = direction[source]
    disc_dir = np.array([median(seen[:, c]) for c in range(3)])  # (np.median, axis 0)
    alike = _channel_max(np.abs(direction - disc_dir)) <= p.rim_direction
    # (every pixel read is the blob's or within reach: those alike are the disc's)
    pure = float(quantile(chroma[alike], 0.9)) if alike.any() else 0.0
    if pure <= 0:
        return blob
    rim = (chroma >= 0.5 * pure) & alike & near_at
    union = blob.inside.astype(np.uint8)
    union.ravel()[at[rim]] = 1
    _, lab, _, _ = cv2.connectedComponentsWithStats(union, connectivity=8)
    inside = lab == lab[blob.inside][0]
    if inside.sum() <= blob.area:
        return blob
    cs, _ = cv2.findContours(inside.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    contour = max(cs, key=cv2.contourArea) + np.array([x0, y0], dtype=np.int32)
    inside = np.zeros_like(inside)
    cv2.drawContours(inside.view(np.uint8), [contour], -1, 1, thickness=-1, offset=(-x0, -y0))
    m = cv2.moments(contour)
    if m["m00"] <= 0:
        return blob
    where = (float(m["m10"] / m["m00"]), float(m["m01"] / m["m00"]))
    return replace(
        blob, where=where, area=float(m["m00"]), contour=contour, moments=m,
        box=cv2.boundingRect(contour), inside=inside,
    )


def _repair_highlight(blob: _Blob, image: SearchImage) -> _Blob:
    """The blob with the washed-out pixels next to it (a glossy sticker's highlight)
    joined to it, unless the napkin itself is blown out; ``washed`` is set where a
    pixel of the window is washed out (else it stays None)."""
    import cv2

    p = image.params
    x0, y0, x1, y1 = blob.window
    if not (image.repair_highlights and image.any_blown(blob.window)):
        return blob  # (washed None: nothing washed out near it)
    yy, xx = blob.grid
    cu, cv = blob.where
    washed = _highlight_pixels(
        image.color[y0:y1, x0:x1], image.norm[y0:y1, x0:x1], image.hsv[y0:y1, x0:x1], p,
        blob.r_exp, image.halo_px,
    ) & (np.hypot(xx - cu, yy - cv) < p.highlight_reach * blob.r_exp)
    if not (washed & ~blob.inside).any():
        return replace(blob, washed=washed)
    inside = blob.inside
    union = (inside | washed).astype(np.uint8)
    _, lab_img, _, _ = cv2.connectedComponentsWithStats(union, connectivity=8)
    inside = lab_img == lab_img[inside][0] if inside.any() else union.astype(bool)
    mu = cv2.moments(inside.astype(np.uint8), binaryImage=True)
    cu, cv = mu["m10"] / mu["m00"] + x0, mu["m01"] / mu["m00"] + y0
    cs, _ = cv2.findContours(inside.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    contour = max(cs, key=cv2.contourArea)  # (in window coordinates)
    return replace(
        blob, where=(float(cu), float(cv)), area=float(inside.sum()), contour=contour,
        moments=cv2.moments(contour), inside=inside, washed=washed, recovered=True,
    )


def _area_ratio(blob: _Blob, fore: float, halved: bool) -> float:
    """The blob's area over that of the disc expected at its depth and tilt. Halved, a
    blob loses about half a pixel of its rim to blending with the cloth (its area is
    judged again at full resolution)."""
    rim = 0.5 if halved else 0.0
    return blob.area / (np.pi * max(blob.r_exp - rim, 1.0) * max(fore * blob.r_exp - rim, 1.0))


def _size_problem(ratio: float, z_mm: float, fore: float, p: DetectorParams) -> _Problem | None:
    values = {"z_mm": float(z_mm), "ratio": float(ratio), "foreshortening": float(fore)}
    if ratio < p.min_area_ratio:
        return RejectionKind.TOO_SMALL, values
    if ratio > p.max_area_ratio:
        return RejectionKind.TOO_LARGE, values
    return None


def _shape_of(blob: _Blob) -> tuple[float, float]:
    """Solidity (area / convex-hull area) and elongation (ratio of the principal axes)."""
    import cv2

    hull_area = cv2.contourArea(cv2.convexHull(blob.contour))
    solidity = min(blob.area / hull_area, 1.0) if hull_area > 0 else 0.0
    mu20, mu02, mu11 = blob.moments["mu20"], blob.moments["mu02"], blob.moments["mu11"]
    common = math.sqrt(4 * mu11**2 + (mu20 - mu02) ** 2)
    elongation = math.sqrt((mu20 + mu02 + common) / max(mu20 + mu02 - common, 1e-9))
    return solidity, elongation


def _shape_problem(
    solidity: float, elongation: float, fore: float, p: DetectorParams
) -> _Problem | None:
    if solidity < p.min_solidity or elongation * fore > p.max_elongation:
        shape = {"solidity": float(solidity), "elongation": float(elongation)}
        return RejectionKind.NOT_DISC_SHAPED, shape
    return None


def _radius(blob: _Blob, fore: float) -> float:
    """Radius (pixels, the major semi-axis when foreshortened) of the disc a blob's fill,
    surround and colours are judged on: its equivalent disc, or the expected disc when
    the blob is partly covered, so that the dot stays in the inner part."""
    expected = np.pi * blob.r_exp**2 * fore
    return math.sqrt(max(blob.area, expected) / (np.pi * fore))


@dataclass(frozen=True, eq=False)
class _DiscPixels:
    """The pixels of the windows of several blobs, one after the other, with what the
    checks on the disc centred on each blob need, per pixel and per blob.

    Attributes
    ----------
    blob : ndarray of int, shape (n,)
        Which blob's window each pixel is in (0, 1, ...).
    r : ndarray of float, shape (n,)
        Distance from the blob's centre in radii of its disc (elliptic when
        foreshortened: the minor axis along its minor angle).
    inside, washed : ndarray of bool, shape (n,)
        The pixel is the blob's; washed out near it (:func:`_repair_highlight`).
    labels : ndarray of uint8, shape (n,)
        Colour labels.
    norm : ndarray of uint8, shape (n, 3)
        The balanced colour.
    n_blobs, n_labels : int
        Number of blobs, and of label values (colours + 1).
    palette : ndarray, shape (n_colours, 3), optional
        The search image's sticker colours (``SearchImage.palette``).
    params : DetectorParams, optional
        The search image's thresholds (needed with ``palette``).
    bands : DiscBands
        Where the disc's and the dot's colours are read (``SearchImage.bands``).
    """

    blob: NDArray[np.intp]
    r: NDArray[np.float64]
    inside: NDArray[np.bool_]
    washed: NDArray[np.bool_]
    labels: NDArray[np.uint8]
    norm: NDArray[np.uint8]
    n_blobs: int
    n_labels: int
    palette: NDArray[np.float64] | None = None
    params: DetectorParams | None = None
    bands: DiscBands = field(default_factory=_default_bands)

    @classmethod
    def of(cls, shaped: list[_Shaped], image: SearchImage) -> _DiscPixels:
        """The pixels of the ``shaped`` blobs of ``image`` within 1.8 radii of each
        blob's centre (:func:`_disc_box`), row by row (each box written once, in place,
        into arrays made for all of them)."""
        boxes = [_disc_box(s) for s in shaped]
        counts = [(y1 - y0) * (x1 - x0) for x0, y0, x1, y1 in boxes]
        n = sum(counts)
        r, inside, washed = np.empty(n), np.empty(n, bool), np.zeros(n, bool)
        labels, norm = np.empty(n, np.uint8), np.empty((n, 3), np.uint8)
        at = 0
        for s, (x0, y0, x1, y1), m in zip(shaped, boxes, counts):
            b, hw = s.blob, (y1 - y0, x1 - x0)
            wx, wy = b.window[:2]
            in_window = np.s_[y0 - wy : y1 - wy, x0 - wx : x1 - wx]
            _radii(s, x0, y0, x1, y1, out=r[at : at + m].reshape(hw))
            labels[at : at + m].reshape(hw)[...] = image.labels[y0:y1, x0:x1]
            norm[at : at + m].reshape(*hw, 3)[...] = image.norm[y0:y1, x0:x1]
            inside[at : at + m].reshape(hw)[...] = b.inside[in_window]
            if b.washed is not None:
                washed[at : at + m].reshape(hw)[...] = b.washed[in_window]
            at += m
        blob = np.repeat(np.arange(len(shaped)), counts)
        return cls(
            blob, r, inside, washed, labels, norm, len(shaped), image.n_colours + 1,
            image.palette, image.params, image.bands,
        )

    def count(self, where: NDArray[np.bool_]) -> NDArray[np.intp]:
        """Number of pixels ``where`` holds, per blob, shape (n_blobs,)."""
        return np.bincount(self.blob[where], minlength=self.n_blobs)

    def label_counts(self, where: NDArray[np.bool_]) -> NDArray[np.intp]:
        """Pixels of each label ``where`` holds, per blob, shape (n_blobs, n_labels)."""
        keys = (self._by_label + self.labels)[where]
        return np.bincount(keys, minlength=self.n_blobs * self.n_labels).reshape(
            self.n_blobs, self.n_labels
        )

    @cached_property
    def _by_label(self) -> NDArray[np.uint32]:
        """Each pixel's blob times ``n_labels``: plus its label, a key per (blob, label)
        for one count (uint32: narrow integers are added and gathered faster)."""
        return self.blob.astype(np.uint32) * np.uint32(self.n_labels)

    @cached_property
    def _by_level(self) -> NDArray[np.uint32]:
        """Each pixel's blob times 256: plus an 8-bit value, a key per (blob, value)."""
        return self.blob.astype(np.uint32) << np.uint32(8)

    def upper_medians(self, values: NDArray[np.uint8], at: NDArray[np.intp]) -> NDArray:
        """Per blob, the upper median of the 8-bit ``values`` of the pixels ``at`` (an
        index, one value each; as :func:`_median`: the (n // 2)-th smallest of n); -1
        for a blob with none. Shape (n_blobs,)."""
        counts = np.bincount(
            np.take(self._by_level, at) + values, minlength=self.n_blobs * 256
        ).reshape(self.n_blobs, 256)
        at_most = np.cumsum(counts, axis=1)  # values <= each level, per blob
        n = at_most[:, -1]
        return np.where(n > 0, np.argmax(at_most > (n // 2)[:, None], axis=1), -1)

    @cached_property
    def covered(self) -> list[int]:
        """Per blob, its pixels within one radius of its centre.

        (This and the other per-blob figures are lists of Python numbers: each blob's
        checks read a few of them, and indexing a list is cheaper than an array.)"""
        return self.count(self.inside & (self.r < 1.0)).tolist()

    @cached_property
    def surround_levels(self) -> tuple[list[int], list[int]]:
        """Per blob, the median of the smallest channel on the ring (1.3-1.8 radii, off
        the blob) and of the largest channel of its coloured pixels within 0.95 radii
        (8-bit; -1 where there are none). The sRGB curve is increasing, so these are
        the medians in linear light too."""
        r, norm = self.r, self.norm
        ring = np.flatnonzero((r > _RING_INNER) & (r < _RING_OUTER) & ~self.inside)
        disc = np.flatnonzero(self.inside & (self.labels > 0) & (r < self.bands.band[1]))
        smallest = _channel_min(np.take(norm, ring, axis=0))
        largest = _channel_max(np.take(norm, disc, axis=0))
        return (
            self.upper_medians(smallest, ring).tolist(), self.upper_medians(largest, disc).tolist()
        )

    @cached_property
    def disc_and_dot(
        self,
    ) -> tuple[list[list[int]], list[list[int]], list[int], list[bool]]:
        """Per blob: label counts of the outer band (0.6-0.95 radii) and of the inner
        part (below 0.28 radii) of the blob's coloured pixels; pixels of the inner part
        of the window; whether a washed-out pixel lies there."""
        coloured = self.inside & (self.labels > 0)
        inner_area = self.r < self.bands.dot
        return (
            self._band_counts.tolist(),
            self.label_counts(coloured & inner_area).tolist(),
            self.count(inner_area).tolist(),
            (self.count(self.washed & inner_area) > 0).tolist(),
        )

    @cached_property
    def _band_counts(self) -> NDArray[np.intp]:
        """Label counts of each blob's coloured pixels in its outer band (0.6-0.95
        radii), shape (n_blobs, n_labels)."""
        r = self.r
        lo, hi = self.bands.band
        return self.label_counts(self.inside & (self.labels > 0) & (r > lo) & (r < hi))

    @cached_property
    def dots(self) -> list[_Colours | None]:
        """Per blob, its disc and dot colours read by the colour the dot adds at the
        centre, or None (:func:`_dots_by_difference`)."""
        return _dots_by_difference(self)

    @cached_property
    def unmixing(self) -> list[tuple[list[float], list[float]] | None]:
        """Per blob, what :func:`_dots_by_difference` unmixes a small sticker's dot from,
        in linear light: the disc as seen (per channel, the median of the most saturated
        quarter of the outer band, 0.6-0.95 radii, by chroma at or above its 0.75
        quantile) and what the centre (within 0.2 radii) adds to it (its mean less the
        disc); None for a blob with under 4 band pixels or none at the centre.

        Worked out for every blob at once, each figure to the bit what numpy gives
        blob by blob (``np.quantile``, ``np.median`` over rows, ``mean``). The sRGB
        curve is strictly increasing, so a pixel's largest and smallest linear channel
        are those of its 8-bit levels, and a median of linear values is read from the
        8-bit levels' counts (:func:`_grouped_level_medians`) without sorting floats;
        the sums run in pixel order."""
        disc_seen, added, ok = self._unmixed
        disc_seen, added, told = disc_seen.tolist(), added.tolist(), ok.tolist()
        return [(disc_seen[k], added[k]) if told[k] else None for k in range(self.n_blobs)]

    @cached_property
    def _unmixed(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
        """:attr:`unmixing` as arrays: the disc as seen and what the centre adds, shape
        (n_blobs, 3) each, and which blobs have them."""
        r, n, norm = self.r, self.n_blobs, self.norm
        lut = srgb_lut()
        # (an index and np.take gather rows several times faster than a boolean mask)
        lo, hi = self.bands.band
        band = np.flatnonzero((r > lo) & (r < hi))
        ring, group = np.take(norm, band, axis=0), np.take(self.blob, band)
        n_band = np.bincount(group, minlength=n)
        largest, smallest = _channel_max(ring), _channel_min(ring)
        chroma = lut[largest] - lut[smallest]
        ranks, chromas = _chroma_ranks()
        key = (group.astype(np.int64) << 16) + ranks[largest, smallest]
        ordered = chromas[np.sort(key) & 0xFFFF]  # each blob's chromas, in order
        high = np.flatnonzero(chroma >= _grouped_quantile(ordered, n_band, 0.75)[group])
        disc_seen = _grouped_level_medians(np.take(ring, high, axis=0), np.take(group, high), n)
        centre = np.flatnonzero(r < self.bands.centre)
        mid, mid_group = lut[np.take(norm, centre, axis=0)], np.take(self.blob, centre)
        n_mid = np.bincount(mid_group, minlength=n)
        sums = np.stack(
            [np.bincount(mid_group, weights=mid[:, c], minlength=n) for c in range(3)], axis=1
        )
        added = sums / np.maximum(n_mid, 1)[:, None] - disc_seen
        return disc_seen, added, (n_band >= 4) & (n_mid > 0)


def _radii(
    s: _Shaped, x0: int, y0: int, x1: int, y1: int, *, out: NDArray[np.float64] | None = None
) -> NDArray[np.float64]:
    """Distance of every pixel of the box (x0, y0, x1, y1) from the blob's centre, in
    radii of its disc (elliptic when foreshortened: the minor axis along its minor
    angle), shape (y1 - y0, x1 - x0), written into ``out`` when given.

    Face-on, the square root of the summed squares (a third of ``np.hypot``'s time; the
    two differ by a rounding, 1e-16 of a radius, which no threshold of the checks tells
    apart)."""
    cu, cv = s.blob.where
    dx, dy = np.arange(x0, x1) - cu, (np.arange(y0, y1) - cv)[:, None]
    if s.fore < 1.0:
        ca, sa = np.cos(s.minor_angle), np.sin(s.minor_angle)
        along, across = dx * ca + dy * sa, -dx * sa + dy * ca
        return np.divide(np.hypot(along / s.fore, across), s.radius, out=out)
    r = np.add(dx * dx, dy * dy, out=out)
    np.sqrt(r, out=r)
    return np.divide(r, s.radius, out=r)


def _disc_box(s: _Shaped) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1): the part of a blob's window within 1.8 radii of its centre (and
    a pixel more), where every pixel its disc checks look at lies (a foreshortened
    disc's radius is its major semi-axis, so its ring lies within it too)."""
    x0, y0, x1, y1 = s.blob.window
    cu, cv = s.blob.where
    reach = _RING_OUTER * s.radius
    return (
        max(x0, math.floor(cu - reach) - 1),
        max(y0, math.floor(cv - reach) - 1),
        min(x1, math.ceil(cu + reach) + 2),
        min(y1, math.ceil(cv + reach) + 2),
    )


def _fill_problem(
    discs: _DiscPixels, k: int, s: _Shaped, p: DetectorParams
) -> _Problem | None:
    """Rejects crescents and slivers: too little of the equivalent disc covered."""
    fill = discs.covered[k] / (np.pi * s.radius**2 * s.fore)
    if fill < p.min_fill:
        return RejectionKind.NOT_WHOLE_DISC, {"fill": float(fill)}
    return None


def _surround_problem(discs: _DiscPixels, k: int, p: DetectorParams) -> _Problem | None:
    """A sticker lies on white cloth, an object on a table does not: the whiteness of a
    ring around the blob (1.3-1.8 radii) against the blob's own brightness."""
    white, own = discs.surround_levels
    if white[k] < 0 or own[k] < 0:  # no ring, or no coloured pixel of the disc
        return None
    lin = srgb_lut()
    white_k, own_k = float(lin[white[k]]), float(lin[own[k]])
    if white_k < p.min_surround * own_k:
        return RejectionKind.NOT_ON_NAPKIN, {"surround": white_k / max(own_k, 1e-6)}
    return None


def _disc_and_dot(discs: _DiscPixels, k: int, p: DetectorParams) -> _Colours | _Problem:
    """Disc and dot colours of the ``k``-th blob: majority labels of an outer band and
    of the inner part of the equivalent disc; or why they cannot be read."""
    outer_counts, inner_counts, inner_area, washed_inner = discs.disc_and_dot
    disc_counts = outer_counts[k]
    outer = sum(disc_counts)
    if outer == 0:
        return RejectionKind.NO_DISC_COLOUR, {}
    disc = _first_largest(disc_counts)
    purity = disc_counts[disc] / outer
    dot: int | None = None
    inner = sum(inner_counts[k])
    if inner and inner >= p.min_dot_seen * inner_area[k]:
        dot_counts = inner_counts[k]
        dot = _first_largest(dot_counts)
        purity = min(purity, dot_counts[dot] / inner)
    elif not washed_inner[k]:
        return RejectionKind.NO_DOT_COLOUR, {}
    if purity < p.min_purity:
        return RejectionKind.MIXED_COLOURS, {"purity": float(purity)}
    return _Colours(disc, dot, purity)


def _read_colours(
    s: _Shaped, k: int, discs: _DiscPixels, image: SearchImage
) -> _Colours | _Problem:
    """Disc and dot colours of the ``k``-th shaped blob, or why they cannot be read.

    Large stickers are read by their labels (:func:`_disc_and_dot`). A small one (disc
    radius under ``small_radius_px`` in the search image) has its dot blurred into its
    disc: in a search at full resolution it is read by unmixing the dot's colour
    (:func:`_dots_by_difference`); in a halved search the labels are kept unless they
    cannot be read or the unmixing reads another dot colour without doubt.
    """
    p = image.params
    colours = _disc_and_dot(discs, k, p)
    if s.radius >= p.small_radius_px:
        return colours
    unmixed = discs.dots[k]  # (every blob's, read at once: _dots_by_difference)
    if unmixed is None:
        return colours
    if not image.halved or not isinstance(colours, _Colours):
        return unmixed
    if unmixed.dot is not None and unmixed.disc == colours.disc and unmixed.dot != colours.dot:
        return unmixed
    return colours


def _dots_by_difference(discs: _DiscPixels) -> list[_Colours | None]:
    """Disc and dot colours of every blob of ``discs`` read as those of a small sticker
    whose dot the blur mixed into its disc, by the colour the dot adds at the centre
    (None where that cannot be read), worked out for every blob at once.

    A 12 mm dot 4-6 pixels across, blurred over 1-1.6 pixels (demosaicing blurs the red
    and blue channels more than the green one), keeps no pixel of its own colour: the
    centre is the disc's colour mixed with the dot's. In linear light the disc is the
    median of the most saturated quarter of the outer band (0.6-0.95 radii: the rest is
    mixed with the cloth's white) and the centre the mean within 0.2 radii
    (:attr:`_DiscPixels.unmixing`); the dot's colour is unmixed from them (every
    sticker colour has a channel near 0), and its chroma direction compared with the
    palette's: the nearest (within ``dot_max_distance`` and ``dot_margin`` nearer than
    the next) is the dot, the disc's own colour meaning a plain disc; a dot two colours
    fit alike is left unread (dot None), which the identities may still settle.

    Each blob's figures are those of the same arithmetic on its own three channels (the
    same IEEE operations in the same order, on arrays of every blob).
    """
    n, palette, p = discs.n_blobs, discs.palette, discs.params
    out: list[_Colours | None] = [None] * n
    if palette is None or p is None or n == 0:
        return out
    outer = discs._band_counts  # (n, n_labels) label counts
    total = outer.sum(axis=1)
    disc = np.argmax(outer, axis=1)  # (the first of equal counts, as list.index(max))
    purity = outer[np.arange(n), disc] / np.maximum(total, 1)
    disc_seen, added, told = discs._unmixed
    ok = (total > 0) & (purity >= p.min_purity) & (disc != 0) & told
    rows = np.flatnonzero(ok).tolist()
    if not rows:
        return out
    disc_seen, added = disc_seen[rows], added[rows]  # (m, 3) linear
    # Unmix: centre = (1 - b) disc + b dot, both lit alike and with the same white light
    # w added; every sticker colour has a channel near 0, so the dot's smallest channel
    # is the disc's (w). The least share b that keeps every channel of the dot at or
    # above it is the share (at most 1: the centre is then the dot).
    above = disc_seen - disc_seen.min(axis=1, keepdims=True)
    # (the disc's own smallest channels carry noise only)
    falls = (added < 0) & (above > 0.05)
    need = np.where(falls, -added / np.maximum(above, 1e-6), 0.0).max(axis=1)
    # (nothing fell: the centre is the dot itself, sharp, or the disc's own colour)
    share = np.where(need > 0.1, np.minimum(np.maximum(need, p.dot_min_share), 1.0), 1.0)
    dot_seen = disc_seen + added / share[:, None]
    # a plain disc's dot is the disc as seen (a tint of the light or the laminate moves
    # it from the printed colour); another dot is a printed colour
    m = len(rows)
    targets = np.repeat(_directions(palette)[None], m, axis=0)  # (m, n_colours, 3)
    own = disc[rows] - 1
    targets[np.arange(m), own] = _directions(disc_seen)
    distances = np.abs(targets - _directions(dot_seen)[:, None, :]).max(axis=2)
    best = np.argmin(distances, axis=1)  # (the first of equal ones: a stable sort's)
    ranked = np.sort(distances, axis=1)
    read = (ranked[:, 0] <= p.dot_max_distance) & (ranked[:, 1] - ranked[:, 0] >= p.dot_margin)
    best, read = best.tolist(), read.tolist()
    discs_of, purities = disc.tolist(), purity.tolist()
    for i, k in enumerate(rows):
        # label best + 1 (the disc's own: plain); unread where two colours fit alike
        out[k] = _Colours(discs_of[k], best[i] + 1 if read[i] else None, purities[k])
    return out


def _grouped_quantile(
    ordered: NDArray[np.float64], counts: NDArray[np.intp], q: float
) -> NDArray[np.float64]:
    """Per group, ``np.quantile(values of the group, q)`` (linear method) to the bit, of
    values ``ordered`` within each group (groups one after another, ``counts`` values
    each); NaN for an empty group."""
    if not ordered.size:
        return np.full(len(counts), np.nan)
    starts = np.concatenate(([0], np.cumsum(counts)[:-1]))
    virtual = (counts - 1) * q
    lo = np.floor(np.maximum(virtual, 0.0)).astype(np.intp)
    hi = np.minimum(lo + 1, np.maximum(counts - 1, 0))
    gamma = virtual - lo
    last = ordered.size - 1
    a = ordered[np.minimum(starts + lo, last)]
    b = ordered[np.minimum(starts + hi, last)]
    diff = b - a
    out = np.where(gamma >= 0.5, b - diff * (1 - gamma), a + diff * gamma)
    return np.where(counts > 0, out, np.nan)


@lru_cache(maxsize=1)
def _chroma_ranks() -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The linear chroma of every (largest, smallest) pair of 8-bit levels as a rank
    among them all, shape (256, 256) (equal chromas share one), and the chroma of each
    rank: a 16-bit integer key that orders chromas exactly (distinct ones lie as close
    as 1e-19), read-only."""
    lut = srgb_lut()
    chromas, inverse = np.unique(lut[:, None] - lut[None, :], return_inverse=True)
    ranks = inverse.reshape(256, 256).astype(np.int64)
    ranks.flags.writeable = chromas.flags.writeable = False
    return ranks, chromas


def _channel_max(pixels: NDArray) -> NDArray:
    """The largest of the 3 channels of each pixel (one pass a channel: ``max`` over a
    trailing axis of 3 is many times slower)."""
    return np.maximum(np.maximum(pixels[..., 0], pixels[..., 1]), pixels[..., 2])


def _channel_min(pixels: NDArray) -> NDArray:
    """The smallest of the 3 channels of each pixel (as :func:`_channel_max`)."""
    return np.minimum(np.minimum(pixels[..., 0], pixels[..., 1]), pixels[..., 2])


def _grouped_level_medians(
    levels: NDArray[np.uint8], group: NDArray[np.intp], n_groups: int
) -> NDArray[np.float64]:
    """Per group and channel, ``np.median`` of the linear light of 8-bit ``levels``
    (m, 3) to the bit (the mean of the two middle values of an even count), shape
    (n_groups, 3); NaN for an empty group. The sRGB curve is strictly increasing, so
    the middle values are those of the middle levels: one sort of (group, channel,
    level) keys finds them all."""
    channels = levels.shape[1]
    if not levels.size:
        return np.full((n_groups, channels), np.nan)
    keys = (group.astype(np.int64) * channels)[:, None] + np.arange(channels)
    ordered = np.sort(((keys << 8) + levels).ravel()) & 0xFF  # by group, channel, level
    counts = np.bincount(group, minlength=n_groups)
    starts = (np.cumsum(counts) - counts)[:, None] * channels + (
        counts[:, None] * np.arange(channels)
    )
    half = (counts // 2)[:, None]
    last, lut = ordered.size - 1, srgb_lut()
    upper = lut[ordered[np.minimum(starts + half, last)]]
    lower = lut[ordered[np.minimum(starts + np.maximum(half - 1, 0), last)]]
    out = np.where((counts % 2 == 1)[:, None], upper, (lower + upper) / 2.0)
    return np.where((counts > 0)[:, None], out, np.nan)


def _directions(rgb: NDArray[np.float64]) -> NDArray[np.float64]:
    """The chroma direction of linear colours (..., 3): their channels less the
    smallest, over the chroma (white light added or the light's level leave it)."""
    low = rgb.min(axis=-1, keepdims=True)
    span = np.maximum(rgb.max(axis=-1, keepdims=True) - low, 1e-6)
    return (rgb - low) / span


def _first_largest(counts: list[int]) -> int:
    """Index of the largest count, the first of equal ones (``np.argmax`` of a list)."""
    return counts.index(max(counts))


def _highlight_pixels(
    color: NDArray[np.uint8],
    norm: NDArray[np.uint8],
    hsv: NDArray[np.uint8],
    params: DetectorParams,
    disc_radius_px: float,
    halo_px: int,
) -> NDArray[np.bool_]:
    """Pixels a glossy sticker's highlight washed out, in a window around a blob: small
    blown-out spots (in the image as taken, or, once balanced, brighter than white cloth
    can be and than the cloth around them: a specular lobe, not the brighter side of a
    napkin under a lamp's fall-off), grown into the pale, tinted halo around them.
    Shape (h, w) of the window."""
    import cv2

    core = cv2.min(cv2.min(color[..., 0], color[..., 1]), color[..., 2]) >= params.highlight_min
    norm_min = cv2.min(cv2.min(norm[..., 0], norm[..., 1]), norm[..., 2])
    sat = hsv[..., 1]
    # the cloth around: its near-neutral pixels (a quarter brighter than this level)
    cloth = (sat < params.halo_min_saturation) & ~core
    level = float(np.quantile(norm_min[cloth], 0.75)) if np.count_nonzero(cloth) >= 8 else 0.0
    core |= norm_min >= max(params.highlight_min, level + params.specular_margin)
    if not core.any():
        return core
    # A highlight is smaller than a sticker; a large blown-out area is cloth.
    _, lab, stats, _ = cv2.connectedComponentsWithStats(core.astype(np.uint8), connectivity=8)
    small = stats[:, cv2.CC_STAT_AREA] <= 1.5 * np.pi * disc_radius_px**2
    small[0] = False
    core = small[lab]
    if not core.any():
        return core
    near_white = max(params.halo_min_value + 80, level + params.specular_margin / 2)
    allowed = (
        (
            (sat >= params.halo_min_saturation)
            & (sat < params.min_saturation)
            & (hsv[..., 2] >= params.halo_min_value)
        )
        | (norm_min >= near_white)
        | core
    )
    grown = core.astype(np.uint8)
    allowed_u8 = allowed.astype(np.uint8)
    cross = np.ones((3, 3), np.uint8)
    for _ in range(halo_px):
        grown = cv2.dilate(grown, cross) & allowed_u8
    return grown.astype(bool)


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
    near = mask & (depth_roi > 0)
    rows, cols = np.nonzero(near)  # (row-major: the order of depth_roi[near])
    if len(rows) < 12:
        return 1.0
    z = depth_roi[rows, cols].astype(np.float64)
    pts = np.column_stack(
        [
            (cols + x0 - intrinsics.cx) / intrinsics.fx * z,
            (rows + y0 - intrinsics.cy) / intrinsics.fy * z,
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


def _axis_ratio(m: dict) -> float:
    """Minor / major axis ratio of a blob's moment ellipse (Python floats: ``math.sqrt``
    rounds as ``np.sqrt`` does, without making arrays)."""
    mu20, mu02, mu11 = m["mu20"], m["mu02"], m["mu11"]
    common = math.sqrt(4 * mu11**2 + (mu20 - mu02) ** 2)
    major, minor = mu20 + mu02 + common, max(mu20 + mu02 - common, 1e-9)
    return math.sqrt(minor / major)


def _minor_angle(m: dict) -> float:
    """The image angle (radians) of the minor axis of a blob's moment ellipse."""
    major_angle = 0.5 * np.arctan2(2 * m["mu11"], m["mu20"] - m["mu02"])
    return float(major_angle + np.pi / 2)


def _median(values: NDArray) -> float:
    """Median of a non-empty 1-d array (the upper one for an even count): np.median
    without its overhead, for the many small arrays of the candidate loop."""
    k = len(values) // 2
    return float(np.partition(values, k)[k])
