"""Sticker detection: colour labels, candidate blobs, identities, centres.

What to look for (the layout: colours and the (disc, dot) pair of each sticker id) is
separate from how to find it (:class:`DetectorParams`) and from the detector.

:func:`detect_stickers` is the pipeline of a few steps, each a function:

1. the search image (:func:`search_image`): the frame, halved while stickers stay large
   enough, balanced to the napkin's white; every saturated pixel labelled with the
   nearest of the four nominal hues (:mod:`.labels`);
2. candidate blobs (:func:`candidate_blobs`): the outer contours of the labelled mask (a
   dot inside its disc belongs to it, even where blur leaves an unsaturated ring
   between them), judged by :func:`.blobs.judge_blobs` (depth, foreshortening,
   highlight repair, size, shape, fill, surround, disc and dot colours): a candidate or
   a :class:`Rejection` with the check failed and its values;
3. identities (:func:`_identify`): the (disc, dot) pair names the sticker; an identity
   is never given twice (the better-scoring candidate keeps it), and a disc whose dot a
   highlight washed out takes the one sticker of its colour left;
4. centres at full resolution (:class:`_FullResolution`) when the search was halved,
   measured for every candidate at once (:func:`_refine_all`).

The work is in proportion to the blobs, not to the pixels, wherever it can be: the
image is converted once (balance, HSV, labels, one contour search) near the napkin only
(the box of its white cloth grown by ``DetectorParams.napkin_margin``; blobs beyond it
are things on the table, neither judged nor reported), and the checks of the blobs and
their centres run on small windows, batched across blobs.

A frame's detection is steps on one :class:`SearchFrame` (:func:`search_frame`: the
napkin found in stage 1, the halving, the depth and camera searched, the hue table and
palette, worked out once): :func:`first_search`, then :func:`washed_out_search`, which
searches again for the stickers a broad sheen left pastel (:mod:`.washed`) on the same
search frame and the frame's white regions (:mod:`.regions`), without a second pass
through :func:`detect_stickers`. :func:`detect_stickers` and :func:`find_washed_out`
are the same steps for a caller with the images alone (``detect_stickers`` finds the
napkin itself when not given it). The parameters and results live in
:mod:`.detections` and are re-exported here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from ..core.camera import Intrinsics
from ..core.colour import srgb_lut, srgb_to_linear
from ..core.errors import InvalidValueError
from ..core.layout import NapkinLayout
from .blobs import Candidate, SearchImage, judge_blobs, least_area, window_pad
from .detections import DetectorParams, Rejection, RejectionKind, StickerDetections
from .labels import colour_labels, hue_lut, hue_of
from .napkin import NapkinView, balance_lut, find_napkin
from .params import disc_bands
from .regions import ClothRegions, RegionParams, cloth_regions
from .washed import (
    PastelLooks,
    merge_second_search,
    pale_samples,
    pastel_params,
    with_unread,
)

__all__ = [
    "DetectorParams",
    "Rejection",
    "RejectionKind",
    "SearchFrame",
    "StickerDetections",
    "detect_all_stickers",
    "detect_stickers",
    "find_washed_out",
    "first_search",
    "hue_of",
    "search_frame",
    "swapped_discs_seen",
    "washed_out_search",
]


def detect_stickers(
    color: NDArray[np.uint8],
    depth_mm: NDArray[np.uint16],
    intrinsics: Intrinsics,
    layout: NapkinLayout,
    params: DetectorParams | None = None,
    *,
    napkin: NapkinView | None = None,
    colours: dict[str, tuple[int, int, int]] | None = None,
    roi: NDArray[np.bool_] | None = None,
    report: NDArray[np.bool_] | None = None,
    known: NDArray[np.float64] | None = None,
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
    roi : ndarray of bool, keyword-only, optional
        Where to look, on any grid over the image (scaled to it); default: everywhere.
    report : ndarray of bool, shape (16,), keyword-only, optional
        The sticker ids wanted (default: all). The others are given to blobs as ever (a
        blob taken for one keeps it from the rest), but they are reported as not found
        and their blobs' centres are measured at full resolution only where that can
        change a wanted id (see :func:`_to_measure`). Their rejections are not reported.
    known : ndarray, shape (16, 2), keyword-only, optional
        Centres (u, v; NaN: not found) of the stickers a search before found (with
        ``report``, for a search again): a blob covering one of them is that sticker,
        so it is not judged again, and those ids are taken before any blob is named.

    Returns
    -------
    StickerDetections
    """
    params = params or DetectorParams()
    _check_images(color, depth_mm)
    if napkin is None:  # (a caller with the napkin found passes it: :func:`search_frame`)
        napkin = find_napkin(color, depth_mm, intrinsics)
    frame = search_frame(color, depth_mm, intrinsics, layout, napkin, params, colours=colours)
    return _search(frame, params, napkin.lut, roi=roi, report=report, known=known)


@dataclass(frozen=True, eq=False)
class SearchFrame:
    """The frame as each sticker search of it sees it, worked out once
    (:func:`search_frame`) and read by every step of the detection: the first search
    (:func:`first_search`) and the search for stickers washed out by a sheen
    (:func:`washed_out_search`).

    Attributes
    ----------
    color, depth_mm, intrinsics
        The frame: RGB (H, W, 3) uint8, depth (H, W) uint16 mm, its camera.
    layout : NapkinLayout
    napkin : NapkinView
        The napkin found (stage 1): its white, the box around its cloth, highlights.
    params : DetectorParams
        How the first search looks (a later step derives its own from them).
    colours : dict or None
        Calibrated sticker colours.
    lut : ndarray of uint8, shape (180,)
        Hue -> colour label (:func:`.labels.hue_lut`); ``names`` the colours in label
        order and ``palette`` their linear RGB (n, 3).
    median_depth_mm : float
        The frame's median depth reading (NaN without any), from every 8th pixel.
    halved : bool
        Whether stickers are searched in the frame halved (see
        ``DetectorParams.search_radius_px``); ``search_depth_mm`` and
        ``search_intrinsics`` are the depth and camera of the image searched.
    """

    color: NDArray[np.uint8]
    depth_mm: NDArray[np.uint16]
    intrinsics: Intrinsics
    layout: NapkinLayout
    napkin: NapkinView
    params: DetectorParams
    colours: dict[str, tuple[int, int, int]] | None
    lut: NDArray[np.uint8]
    names: list[str]
    palette: NDArray[np.float64]
    median_depth_mm: float
    halved: bool
    search_depth_mm: NDArray[np.uint16]
    search_intrinsics: Intrinsics


def search_frame(
    color: NDArray[np.uint8],
    depth_mm: NDArray[np.uint16],
    intrinsics: Intrinsics,
    layout: NapkinLayout,
    napkin: NapkinView,
    params: DetectorParams | None = None,
    *,
    colours: dict[str, tuple[int, int, int]] | None = None,
) -> SearchFrame:
    """The :class:`SearchFrame` of a frame whose napkin is found (stage 1), for its
    sticker searches. ``color`` and ``depth_mm`` as for :func:`detect_stickers`."""
    params = params or DetectorParams()
    _check_images(color, depth_mm)
    lut, names = hue_lut(layout, params, colours)
    coarse = depth_mm[::8, ::8]
    read = coarse[coarse > 0]
    med_depth = _median_of(read) if read.size else np.nan  # (as np.median)
    disc_r_mm = layout.disc_diameter_mm / 2
    halve = (
        bool(med_depth > 0)
        and (disc_r_mm * intrinsics.fx / med_depth >= 2 * params.search_radius_px)
        and min(color.shape[:2]) >= 200
    )
    search_depth, search_intrinsics = depth_mm, intrinsics
    if halve:
        h2, w2 = color.shape[0] // 2, color.shape[1] // 2
        search_depth = depth_mm[: 2 * h2 : 2, : 2 * w2 : 2]
        search_intrinsics = _halved(intrinsics)
    return SearchFrame(
        color, depth_mm, intrinsics, layout, napkin, params, colours, lut, names,
        _palette(layout, names, colours), med_depth, bool(halve), search_depth,
        search_intrinsics,
    )


def first_search(frame: SearchFrame) -> StickerDetections:
    """The stickers of ``frame`` as :func:`detect_stickers` finds them with the frame's
    parameters, on the napkin the frame carries."""
    return _search(frame, frame.params, frame.napkin.lut)


def swapped_discs_seen(frame: SearchFrame, disc: str) -> bool:
    """Whether the frame, read with its red and blue channels swapped, shows a blob of
    the disc colour ``disc`` big enough to be judged, worked out without swapping it.

    Swapping red and blue mirrors every hue (red and blue trade places, green stays,
    yellow and cyan trade places) and keeps saturation and value, and the napkin's
    white swaps with the image, so the swapped frame's colour labels are the frame's
    own labelled by the palette with its red and blue swapped: one labelling of the
    search image near the napkin (no blob judged), against a whole classification of
    the frame swapped. A BGR array's yellow stickers are cyan, so they show here.
    """
    import cv2

    source = {**frame.layout.colours_srgb, **(frame.colours or {})}
    swapped = {name: (b, g, r) for name, (r, g, b) in source.items()}
    lut, names = hue_lut(frame.layout, frame.params, swapped)
    palette = _palette(frame.layout, names, swapped)
    mirrored = replace(frame, lut=lut, colours=swapped, palette=palette)
    image = _search_image(mirrored, frame.params, frame.napkin.lut)
    mask = cv2.compare(image.labels, names.index(disc) + 1, cv2.CMP_EQ)
    _, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    r_px = image.disc_radius_mm * image.intrinsics.fx / max(image.median_depth_mm, 1.0)
    least = max(SWAPPED_DISC_SHARE * np.pi * r_px**2, least_area(image.min_area_px))
    return bool((stats[1:, cv2.CC_STAT_AREA] >= least).any())


#: The least share of a disc's area (at the frame's median depth) that a blob of the
#: disc colour must cover for :func:`swapped_discs_seen`: a sticker's disc colour, less
#: its dot, covers 0.84 of it face-on, and a disc under half that is rejected as too
#: small (``DetectorParams.min_area_ratio`` 0.55, with its dot); 0.25 leaves room for a
#: disc half hidden or farther than the median, and leaves out the specks a gripper's
#: blue-grey or a shadow's tint make (0.1 of a disc or less).
SWAPPED_DISC_SHARE = 0.25


def _search(
    frame: SearchFrame,
    params: DetectorParams,
    balance: NDArray[np.uint8],
    *,
    roi: NDArray[np.bool_] | None = None,
    report: NDArray[np.bool_] | None = None,
    known: NDArray[np.float64] | None = None,
) -> StickerDetections:
    """One search of ``frame`` with ``params``, the image balanced by ``balance`` (a
    :meth:`.napkin.balance_lut` table); ``roi``, ``report`` and ``known`` as for
    :func:`detect_stickers`."""
    layout, names, lut = frame.layout, frame.names, frame.lut
    taken = None if known is None else np.isfinite(known).all(axis=1)
    image = _search_image(
        frame, params, balance, roi, known=None if known is None else known[taken]
    )
    candidates, rejected = candidate_blobs(image)
    full = None
    if image.halved:
        measured = candidates if report is None else _to_measure(candidates, layout, names, report)
        full = _FullResolution(
            _refine_all(frame.color, balance, lut, params, measured), params,
            frame.intrinsics.fx, image.disc_radius_mm,
        )
    ids = _identify(candidates, layout, names, full, taken=taken)
    rejected += ids.rejected
    if image.halved:  # report rejections in full-resolution pixels
        rejected = [_at_full_resolution(r) for r in rejected]
    if report is not None:
        return _reported(ids, report)
    return StickerDetections(
        ids.centroids, ids.areas, ids.scores, ids.depths, tuple(rejected), ids.fores
    )


def _palette(
    layout: NapkinLayout, names: list[str], colours: dict[str, tuple[int, int, int]] | None
) -> NDArray[np.float64]:
    """Linear RGB (n, 3) of the sticker colours in label order (calibrated where given)."""
    source = {**layout.colours_srgb, **(colours or {})}
    return srgb_to_linear(np.array([source[n] for n in names], dtype=np.float64) / 255.0)


def _to_measure(
    candidates: list[Candidate], layout: NapkinLayout, names: list[str],
    report: NDArray[np.bool_],
) -> list[Candidate]:
    """The candidates whose centres at full resolution can change the stickers
    ``report`` wants (:func:`_identify`): those named for a wanted sticker; every one
    whose dot is washed out (it takes the one sticker of its disc colour left); and
    those named for any sticker of such a disc colour (whether they keep it, or are too
    small at full resolution and leave it free, decides what is left). The others only
    keep unwanted stickers from each other."""
    pending = {names[c.disc - 1] for c in candidates if c.dot is None}
    out = []
    for c in candidates:
        if c.dot is None:
            out.append(c)
            continue
        sid = layout.sticker_id(names[c.disc - 1], names[c.dot - 1])
        if sid is not None and (report[sid] or layout.sticker_disc[sid] in pending):
            out.append(c)
    return out


def _reported(ids: _Identities, report: NDArray[np.bool_]) -> StickerDetections:
    """The stickers ``report`` wants of ``ids``; the others as not found."""
    centroids, areas, depths, fores = (
        np.where(report[:, None] if v.ndim == 2 else report, v, np.nan)
        for v in (ids.centroids, ids.areas, ids.depths, ids.fores)
    )
    scores = np.where(report & ~np.isnan(centroids[:, 0]), ids.scores, 0.0)
    return StickerDetections(centroids, areas, scores, depths, (), fores)


def _check_images(color: NDArray, depth_mm: NDArray) -> None:
    if color.ndim != 3 or color.shape[2] != 3 or color.dtype != np.uint8:
        raise InvalidValueError(f"color must be (H, W, 3) uint8, got {color.shape} {color.dtype}")
    if depth_mm.shape != color.shape[:2]:
        raise InvalidValueError(
            f"depth_mm must have shape {color.shape[:2]}, got {depth_mm.shape}"
        )


def search_image(
    color: NDArray[np.uint8],
    depth_mm: NDArray[np.uint16],
    intrinsics: Intrinsics,
    layout: NapkinLayout,
    params: DetectorParams,
    napkin: NapkinView,
    lut: NDArray[np.uint8],
    n_colours: int,
    roi: NDArray[np.bool_] | None = None,
    *,
    palette: NDArray[np.float64] | None = None,
    known: NDArray[np.float64] | None = None,
) -> SearchImage:
    """The image stickers are searched in, with its colour labels.

    It is the frame halved (pixel-area averaging) while a sticker at the median depth
    keeps ``search_radius_px`` there, balanced to the napkin's white by ``napkin.lut``;
    ``lut`` is :func:`.labels.hue_lut`'s table (of ``n_colours`` colours); ``palette``
    the sticker colours (linear RGB, in label order) that the dots of small stickers
    are read against (see :func:`.blobs.judge_blobs`). Outside ``roi`` (scaled to the
    search image) no pixel is labelled, and the images are computed only where judging
    the blobs within it reads them (elsewhere they are 0). Without ``roi``, stickers are
    searched near the napkin (:func:`_napkin_box`, ``SearchImage.within``): the images
    are computed only where judging the blobs within that box reads them.
    """
    frame = search_frame(color, depth_mm, intrinsics, layout, napkin, params)
    frame = replace(frame, lut=lut, names=frame.names[:n_colours], palette=palette)
    return _search_image(frame, params, napkin.lut, roi, known=known)


def _search_image(
    frame: SearchFrame,
    params: DetectorParams,
    balance: NDArray[np.uint8],
    roi: NDArray[np.bool_] | None = None,
    *,
    known: NDArray[np.float64] | None = None,
) -> SearchImage:
    """:func:`search_image` of a :class:`SearchFrame`: its halving, depth and camera
    as worked out once, the image balanced by ``balance``, labelled with ``params``."""
    import cv2

    color, napkin, med_depth = frame.color, frame.napkin, frame.median_depth_mm
    depth_mm, intrinsics, halve = frame.search_depth_mm, frame.search_intrinsics, frame.halved
    disc_r_mm = frame.layout.disc_diameter_mm / 2
    shape = depth_mm.shape
    disc_mm_px = disc_r_mm * intrinsics.fx
    inside, near = None, None
    if roi is not None:
        inside = cv2.resize(roi.astype(np.uint8), shape[::-1], interpolation=cv2.INTER_NEAREST)
        x, y, w, h = cv2.boundingRect(inside)
        box = (x, y, x + w, y + h)  # (no pixel beyond it is labelled)
    else:
        near = _napkin_box(napkin, shape, 0.5 if halve else 1.0, disc_mm_px, med_depth, params)
        box = (0, 0, shape[1], shape[0]) if near is None else _grown(near, 1, shape)
    # A sticker cannot be smaller than the smallest accepted area at the farthest depth.
    min_px = 0.3 * np.pi * (disc_mm_px / (2.0 * max(med_depth, 1.0))) ** 2
    label_params = _label_params(params, disc_mm_px, med_depth, halve)
    planes = _Planes(color, halve, balance, frame.lut, label_params, box)
    labels = planes.labels if inside is None else planes.labels * inside
    least = least_area(min_px)  # (smaller blobs are specks: not judged, no window read)
    outer = [c for c in _judged_contours(labels, near, box) if cv2.contourArea(c) >= least]
    if known is not None and len(known) and outer:
        outer = _not_covering(outer, (known - 0.5) / 2 if halve else known)
    if box != (0, 0, shape[1], shape[0]):  # the rest of the box judging the blobs reads
        rect = cv2.boundingRect(np.concatenate(outer)) if outer else (0, 0, 0, 0)
        planes.extend(_judged_box(rect, depth_mm, disc_mm_px, med_depth))
    return SearchImage(
        planes.color, planes.norm, planes.hsv, labels, depth_mm, intrinsics, med_depth,
        disc_r_mm, min_px, bool(halve), max(params.highlight_halo_px // (2 if halve else 1), 1),
        bool(napkin.white_rgb.max() < srgb_lut()[params.napkin_blown_level]),
        len(frame.names), params, near, (labels, outer), frame.palette,
        disc_bands(frame.layout),
    )


def _label_params(
    params: DetectorParams, disc_mm_px: float, median_depth_mm: float, halved: bool
) -> DetectorParams:
    """The thresholds pixels are labelled with: ``params``, or for small stickers (a
    full-resolution search whose disc at the median depth is under ``small_radius_px``)
    saturation and chroma lowered to ``small_saturation`` and ``small_chroma``: a real
    camera's blur mixes a thin ring around a dot of another colour with white cloth and
    with the dot, and at the usual thresholds it breaks into specks."""
    if halved or not (disc_mm_px / max(median_depth_mm, 1.0) < params.small_radius_px):
        return params
    return replace(
        params,
        min_saturation=min(params.min_saturation, params.small_saturation),
        min_chroma=min(params.min_chroma, params.small_chroma),
    )


def _median_of(values: NDArray) -> float:
    """``np.median`` of a non-empty 1-d array (the mean of the two middle values of an
    even count), by one partial sort for integers."""
    if not np.issubdtype(values.dtype, np.integer):
        return float(np.median(values))
    k = values.size // 2
    part = np.partition(values, k)
    if values.size % 2:
        return float(part[k])
    return (float(part[:k].max()) + float(part[k])) / 2


def _grown(
    box: tuple[int, int, int, int], by: int, shape: tuple[int, int]
) -> tuple[int, int, int, int]:
    """``box`` (x0, y0, x1, y1) grown by ``by`` pixels, cut to an image of ``shape``."""
    x0, y0, x1, y1 = box
    return max(x0 - by, 0), max(y0 - by, 0), min(x1 + by, shape[1]), min(y1 + by, shape[0])


def _judged_contours(
    labels: NDArray[np.uint8], near: tuple[int, int, int, int] | None,
    box: tuple[int, int, int, int] | None = None,
) -> list[NDArray[np.int32]]:
    """The outer contours of the labelled pixels (:func:`outer_contours`) whose blobs
    are judged: those lying wholly within ``near`` (x0, y0, x1, y1; None: all).
    ``box`` (x0, y0, x1, y1): where pixels may be labelled (0 elsewhere; None: anywhere);
    only the box and a pixel around it are traced.

    Labelled within ``near`` grown by one pixel, they are those of the whole image: a
    blob within ``near`` is the same blob, and one reaching beyond it has a pixel in
    that one-pixel ring."""
    import cv2

    x0, y0, x1, y1 = _grown(box, 1, labels.shape) if box else (0, 0, *labels.shape[::-1])
    if x1 <= x0 or y1 <= y0:
        return []
    mask = cv2.threshold(labels[y0:y1, x0:x1], 0, 1, cv2.THRESH_BINARY)[1]
    # Outer boundaries of every component, also those inside holes of others (a
    # saturated surround never hides what lies inside it).
    outer = outer_contours(mask, offset=(x0, y0))
    if near is not None:  # (blobs not wholly within it are not judged)
        outer = [c for c in outer if _lies_within(cv2.boundingRect(c), near)]
    return outer


class _Planes:
    """The search image's planes (RGB, balanced RGB, HSV, colour labels), computed in
    ``box`` (x0, y0, x1, y1) and extended as needed (:meth:`extend`); 0 elsewhere.
    Every pixel is computed on its own (its 2 x 2 block averaged when ``halve``, looked
    up in ``balance``, converted, labelled by ``lut``), so it is the same whichever box
    it is computed in."""

    def __init__(
        self, color: NDArray[np.uint8], halve: bool, balance: NDArray[np.uint8],
        lut: NDArray[np.uint8], params: DetectorParams, box: tuple[int, int, int, int],
    ) -> None:
        self.frame, self.halve = color, halve
        self.balance, self.lut, self.params, self.box = balance, lut, params, box
        self.color = _halved_within(color, box) if halve else color
        self.norm, self.labels, self.hsv = _labelled_within(
            self.color, balance, lut, params, box
        )

    def extend(self, box: tuple[int, int, int, int]) -> None:
        """Compute the pixels of ``box`` (x0, y0, x1, y1) not computed yet: the part of
        it outside the box computed, at most four strips."""
        x0, y0, x1, y1 = box
        bx0, by0, bx1, by1 = self.box
        if x1 <= x0 or y1 <= y0:
            return
        my0, my1 = max(y0, by0), min(y1, by1)
        strips = [
            (x0, y0, x1, min(by0, y1)), (x0, max(by1, y0), x1, y1),  # above, below
            (x0, my0, min(bx0, x1), my1), (max(bx1, x0), my0, x1, my1),  # left, right
        ]
        for sx0, sy0, sx1, sy1 in strips:
            if sx1 > sx0 and sy1 > sy0:
                self._compute(np.s_[sy0:sy1, sx0:sx1], (sx0, sy0, sx1, sy1))

    def _compute(self, inner: tuple[slice, slice], box: tuple[int, int, int, int]) -> None:
        import cv2

        if self.halve:
            _halved_within(self.frame, box, out=self.color)
        norm = cv2.LUT(self.color[inner], self.balance, dst=self.norm[inner])
        colour_labels(norm, self.lut, self.params, out=(self.labels[inner], self.hsv[inner]))


def _judged_box(
    rect: tuple[int, int, int, int], depth_mm: NDArray[np.uint16], disc_mm_px: float,
    fallback_mm: float,
) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1): the box of the search image that judging the blobs within
    ``rect`` (x, y, w, h) reads: ``rect`` grown by the widest window such a blob can
    have (:func:`.blobs.window_pad` of the disc expected at the nearest depth read in
    it, or at ``fallback_mm`` where a blob has no depth; and a pixel more).
    ``disc_mm_px``: the disc radius (mm) times the focal length (px)."""
    h_img, w_img = depth_mm.shape
    x, y, w, h = (int(v) for v in rect)
    if w == 0:
        return 0, 0, 0, 0
    depths = _depths_in(depth_mm, (x, y, x + w, y + h), fallback_mm)
    if not depths:
        return 0, 0, w_img, h_img
    pad = window_pad(disc_mm_px / min(depths)) + 1
    return max(x - pad, 0), max(y - pad, 0), min(x + w + pad, w_img), min(y + h + pad, h_img)


def _depths_in(
    depth_mm: NDArray[np.uint16], box: tuple[int, int, int, int], fallback_mm: float
) -> list[float]:
    """The nearest depth read in ``box`` (x0, y0, x1, y1) and ``fallback_mm``, those
    that are readings (> 0)."""
    x0, y0, x1, y1 = box
    read = depth_mm[y0:y1, x0:x1]
    if read.dtype == np.uint16:
        # (0, no reading, wraps round to the largest value: the least of the rest is read)
        least = int((read - np.uint16(1)).min()) + 1 if read.size else 0
        nearest = float(least) if 0 < least <= np.iinfo(np.uint16).max else np.nan
    else:
        read = read[read > 0]
        nearest = float(read.min()) if read.size else np.nan
    return [d for d in (nearest, fallback_mm) if d > 0]


def _napkin_box(
    napkin: NapkinView, shape: tuple[int, int], scale: float, disc_mm_px: float,
    median_mm: float, params: DetectorParams,
) -> tuple[int, int, int, int] | None:
    """(x0, y0, x1, y1): the box of the search image (``shape``, rows and columns;
    ``scale`` of the frame's pixels) where stickers are searched: the box around the
    napkin's cloth samples grown by ``params.napkin_margin`` sticker diameters at the
    frame's median depth ``median_mm`` (at least 4 sampling strides). None: the whole
    image (no margin set, no cloth seen, no depth read, or the box covers it)."""
    import cv2

    cloth = napkin.cloth
    if params.napkin_margin is None or cloth is None or not cloth.any():
        return None
    if not (median_mm > 0):
        return None
    h_img, w_img = shape
    x, y, w, h = cv2.boundingRect(cloth.astype(np.uint8))
    s = napkin.stride * scale  # (a sample is at pixel stride * k of the frame)
    margin = max(params.napkin_margin * 2 * disc_mm_px / median_mm, 4 * s)
    box = (
        max(math.floor(x * s - margin), 0), max(math.floor(y * s - margin), 0),
        min(math.ceil((x + w) * s + margin), w_img), min(math.ceil((y + h) * s + margin), h_img),
    )
    return None if box == (0, 0, w_img, h_img) else box


def _halved_within(
    color: NDArray[np.uint8], box: tuple[int, int, int, int],
    out: NDArray[np.uint8] | None = None,
) -> NDArray[np.uint8]:
    """The frame halved by pixel-area averaging (each pixel the mean of a 2 x 2 block),
    within ``box`` (x0, y0, x1, y1, halved pixels); 0 elsewhere (``out``: the halved
    image to write the box into, the rest left as it is)."""
    import cv2

    h2, w2 = color.shape[0] // 2, color.shape[1] // 2
    x0, y0, x1, y1 = box
    if box == (0, 0, w2, h2) and out is None:
        return cv2.resize(color[: 2 * h2, : 2 * w2], (w2, h2), interpolation=cv2.INTER_AREA)
    if out is None:
        out = np.zeros((h2, w2, 3), np.uint8)
    if x1 > x0 and y1 > y0:  # (written in place, into the box of ``out``)
        cv2.resize(
            color[2 * y0 : 2 * y1, 2 * x0 : 2 * x1], (x1 - x0, y1 - y0),
            dst=out[y0:y1, x0:x1], interpolation=cv2.INTER_AREA,
        )
    return out


def _labelled_within(
    color: NDArray[np.uint8],
    balance: NDArray[np.uint8],
    lut: NDArray[np.uint8],
    params: DetectorParams,
    box: tuple[int, int, int, int],
) -> tuple[NDArray[np.uint8], NDArray[np.uint8], NDArray[np.uint8]]:
    """The image balanced by ``balance``, its colour labels and HSV
    (:func:`.labels.colour_labels`) within ``box`` (x0, y0, x1, y1); 0 elsewhere."""
    import cv2

    x0, y0, x1, y1 = box
    if box == (0, 0, color.shape[1], color.shape[0]):
        norm = cv2.LUT(color, balance)
        return (norm, *colour_labels(norm, lut, params))
    # (np.zeros, not zeros_like: the pages outside the box are never written)
    norm, hsv = np.zeros(color.shape, np.uint8), np.zeros(color.shape, np.uint8)
    labels = np.zeros(color.shape[:2], np.uint8)
    if x1 > x0 and y1 > y0:  # (written in place, into the box of each)
        inner = np.s_[y0:y1, x0:x1]
        cv2.LUT(color[inner], balance, dst=norm[inner])
        colour_labels(norm[inner], lut, params, out=(labels[inner], hsv[inner]))
    return norm, labels, hsv


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


def candidate_blobs(image: SearchImage) -> tuple[list[Candidate], list[Rejection]]:
    """Every blob of the colour mask judged (:func:`.blobs.judge_blobs`): the candidate
    stickers, and the rejected blobs with the reason, search-image pixels."""
    traced = image.traced
    if traced is not None and traced[0] is image.labels:
        outer = traced[1]
    else:  # (labels changed since they were traced)
        outer = _judged_contours(image.labels, image.within)
    candidates: list[Candidate] = []
    rejected: list[Rejection] = []
    for judged in judge_blobs(outer, image):
        if isinstance(judged, Candidate):
            candidates.append(judged)
        elif judged is not None:
            rejected.append(judged)
    return candidates, rejected


#: Above this many pixels in a mask, :func:`outer_contours` traces it level by level.
_MANY_PIXELS = 8000


def outer_contours(
    mask: NDArray[np.uint8], *, by_level: bool | None = None,
    offset: tuple[int, int] = (0, 0),
) -> list[NDArray[np.int32]]:
    """The outer contour of every 8-connected component of a 0/1 ``mask``, also of
    those inside holes of others: ``cv2.findContours``' (``RETR_CCOMP``, all points)
    outer contours, in its order (their first points, each a component's first pixel,
    in reverse raster order).

    A mask of many pixels (the second search's pastel labels, with thousands of holes)
    is traced level by level instead: the outermost components' outer contours
    (``RETR_EXTERNAL``, no hole traced), those components removed (flood-filled), the
    components that were inside their holes next: the same contours.
    ``by_level`` forces either way. ``offset`` (x, y) is added to every point.
    """
    import cv2

    if by_level is None:
        by_level = cv2.countNonZero(mask) > _MANY_PIXELS
    if not by_level:
        contours, hierarchy = cv2.findContours(
            mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE, offset=offset
        )
        if hierarchy is None:
            return []
        return [contours[k] for k in np.flatnonzero(hierarchy[0][:, 3] < 0).tolist()]
    out: list[NDArray[np.int32]] = []
    rest = mask.copy()
    filled = np.zeros((mask.shape[0] + 2, mask.shape[1] + 2), np.uint8)  # (one for all)
    while True:
        level, _ = cv2.findContours(rest, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        if not level:
            break
        out.extend(level)
        for contour in level:  # (its first point is a pixel of its component)
            seed = (int(contour[0, 0, 0]), int(contour[0, 0, 1]))
            cv2.floodFill(rest, filled, seed, 0, flags=8)
    out.sort(key=lambda c: (int(c[0, 0, 1]), int(c[0, 0, 0])), reverse=True)
    if offset != (0, 0):
        for contour in out:
            contour += np.array(offset, contour.dtype)
    return out


def _lies_within(rect: tuple[int, int, int, int], box: tuple[int, int, int, int]) -> bool:
    """Whether ``rect`` (x, y, w, h) lies within ``box`` (x0, y0, x1, y1)."""
    x, y, w, h = rect
    return x >= box[0] and y >= box[1] and x + w <= box[2] and y + h <= box[3]


def _not_covering(
    contours: list[NDArray[np.int32]], points: NDArray[np.float64]
) -> list[NDArray[np.int32]]:
    """The contours that cover none of ``points`` (k, 2), on or within them."""
    import cv2

    rects = np.array([cv2.boundingRect(c) for c in contours], dtype=np.float64)
    x, y = points[:, 0][None], points[:, 1][None]
    near = (
        (x >= rects[:, :1]) & (x <= rects[:, :1] + rects[:, 2:3])
        & (y >= rects[:, 1:2]) & (y <= rects[:, 1:2] + rects[:, 3:4])
    )
    out = []
    for c, row in zip(contours, near.tolist()):
        if any(row) and any(
            cv2.pointPolygonTest(c, (float(p[0]), float(p[1])), False) >= 0
            for p, hit in zip(points.tolist(), row) if hit
        ):
            continue
        out.append(c)
    return out


@dataclass(frozen=True, eq=False)
class _FullResolution:
    """What measuring a candidate's centre at full resolution needs, after a search of
    the frame halved: every candidate's centre and area measured there
    (:func:`_refine_all`), and the focal length and disc radius that give the disc size
    expected (full-resolution pixels)."""

    refined: dict[Candidate, tuple[tuple[float, float], float]]
    params: DetectorParams
    fx: float
    disc_radius_mm: float

    def measure(self, c: Candidate) -> tuple[tuple[float, float], float] | Rejection:
        """Centre (u, v) and area of ``c`` at full resolution, or its rejection
        (search-image pixels) as too small there."""
        where, area = self.refined[c]  # (KeyError: not measured, see _Identities.take)
        # a threshold cuts a blurred rim of about a pixel off the disc (see
        # DetectorParams.full_rim_px): the disc expected is that much smaller
        radius = max(self.disc_radius_mm * self.fx / c.z_mm - self.params.full_rim_px, 1.0)
        expected = np.pi * radius**2 * c.foreshortening
        if area < self.params.min_area_ratio * expected:
            return Rejection(
                ((where[0] - 0.5) / 2, (where[1] - 0.5) / 2),
                area / 4,
                RejectionKind.TOO_SMALL,
                {"z_mm": float(c.z_mm), "ratio": float(area / expected), "full_resolution": True},
            )
        return where, area


class _Identities:
    """The sticker ids given so far, and the candidates refused one.

    An id is never given twice: candidates come best score first (:func:`_identify`).
    With ``full``, centres and areas are measured at full resolution as ids are given.
    """

    def __init__(
        self, layout: NapkinLayout, names: list[str], full: _FullResolution | None,
        taken: NDArray[np.bool_] | None = None,
    ) -> None:
        n = layout.n_stickers
        self.layout, self.names, self.full = layout, names, full
        self.centroids = np.full((n, 2), np.nan)
        self.areas = np.full(n, np.nan)
        self.scores = np.zeros(n)
        if taken is not None:  # (given before: no blob is named for them, none located)
            self.scores[taken] = 1.0
        self.depths = np.full(n, np.nan)
        self.fores = np.full(n, np.nan)
        self.rejected: list[Rejection] = []

    def by_colours(self, c: Candidate) -> None:
        """Give ``c`` the sticker its disc and dot colours name, if free."""
        disc, dot = self.names[c.disc - 1], self.names[c.dot - 1]
        sid = self.layout.sticker_id(disc, dot)
        if sid is None:
            named = {"disc": disc, "dot": dot}
            self.rejected.append(Rejection(c.where, c.area, RejectionKind.NO_SUCH_STICKER, named))
        elif self.scores[sid] > 0:
            held = {"sticker": sid}
            self.rejected.append(Rejection(c.where, c.area, RejectionKind.SECOND_BLOB, held))
        else:
            self.take(sid, c, c.score)

    def by_disc(self, c: Candidate) -> None:
        """A dot lost to a highlight: the disc colour leaves four stickers; if only one
        of them is still unaccounted for, it is that one (at half the score)."""
        disc_name = self.names[c.disc - 1]
        free = [
            sid
            for sid in range(self.layout.n_stickers)
            if self.layout.sticker_disc[sid] == disc_name and self.scores[sid] == 0
        ]
        if len(free) == 1:
            self.take(free[0], c, 0.5 * c.score)
        else:
            left = {"disc": disc_name, "possible": len(free)}
            self.rejected.append(Rejection(c.where, c.area, RejectionKind.DOT_WASHED_OUT, left))

    def take(self, sid: int, c: Candidate, score: float) -> None:
        """Give sticker ``sid`` to ``c`` (unless too small at full resolution). A
        candidate left unmeasured (:func:`_to_measure`) only keeps ``sid`` from the
        others: no centre is given."""
        where, area = c.where, c.area
        if self.full is not None:
            if c not in self.full.refined:
                self.scores[sid] = score
                return
            measured = self.full.measure(c)
            if isinstance(measured, Rejection):
                self.rejected.append(measured)
                return
            where, area = measured
        self.centroids[sid], self.areas[sid] = where, area
        self.scores[sid] = score
        self.depths[sid] = c.z_mm
        self.fores[sid] = c.foreshortening


def _identify(
    candidates: list[Candidate],
    layout: NapkinLayout,
    names: list[str],
    full: _FullResolution | None,
    *,
    taken: NDArray[np.bool_] | None = None,
) -> _Identities:
    """Sticker ids of the candidates, best score first; those whose dot is washed out
    come last and take what is left of their disc colour. ``taken`` (16,): ids given
    before (a search before found them), which no candidate is given."""
    ids = _Identities(layout, names, full, taken)
    pending = []
    for c in sorted(candidates, key=lambda c: -c.score):
        if c.dot is None:
            pending.append(c)
        else:
            ids.by_colours(c)
    for c in pending:
        ids.by_disc(c)
    return ids


def _at_full_resolution(r: Rejection) -> Rejection:
    """A rejection of the halved search, in full-resolution pixels."""
    return replace(
        r, centroid=(2 * r.centroid[0] + 0.5, 2 * r.centroid[1] + 0.5), area_px=4 * r.area_px
    )


def _refine_all(
    color: NDArray[np.uint8],
    lut: NDArray[np.uint8],
    hue_lut: NDArray[np.uint8],
    params: DetectorParams,
    candidates: list[Candidate],
) -> dict[Candidate, tuple[tuple[float, float], float]]:
    """Centre and area of every blob found in the halved image, measured at full
    resolution: its sticker-coloured (or blown-out) pixels within the blob, grown by two
    pixels. A blob completed with a highlight's pale halo keeps its centre from the
    halved image (the halo is no sticker colour).

    The boxes around the grown blobs are laid side by side in one image and labelled in
    one call (labels are per pixel: the same as labelling each box; side by side, the
    image's rows are long, which OpenCV's row loops run fastest).
    """
    out: dict[Candidate, tuple[tuple[float, float], float]] = {}
    grown = []
    for c in candidates:
        if c.recovered or c.region is None:
            out[c] = (2 * c.where[0] + 0.5, 2 * c.where[1] + 0.5), 4 * c.area
        else:
            grown.append((c, _GrownBlob.of(c, color.shape[:2])))
    if not grown:
        return out
    boxes = _side_by_side([g.box_of(color) for _, g in grown])
    hits = _sticker_or_blown(boxes, lut, hue_lut, params)
    left = 0
    for c, g in grown:
        h, w = g.up.shape
        out[c] = _centre_of(g.within(hits[:h, left : left + w]), g, c)
        left += w
    return out


#: A 5 x 5 square: dilation by two pixels.
_SQUARE5 = np.ones((5, 5), np.uint8)
_SQUARE5.flags.writeable = False


@dataclass(frozen=True, eq=False)
class _GrownBlob:
    """A candidate's blob at full resolution, grown by two pixels: ``up`` (bool), the
    mask in its box at ``corner`` (x, y) of the frame, and the ``origin`` (x, y) and
    ``shape`` (rows, columns) of the candidate's whole window there, cut to the frame."""

    up: NDArray[np.bool_]
    corner: tuple[int, int]
    origin: tuple[int, int]
    shape: tuple[int, int]

    @classmethod
    def of(cls, c: Candidate, frame_shape: tuple[int, int]) -> _GrownBlob:
        """The blob of ``c`` (region of the halved search) in a frame of
        ``frame_shape`` (rows, columns): pixels doubled, then dilated by a 5 x 5 square,
        within the blob's bounding box grown by one search pixel (all the dilation
        reaches)."""
        import cv2

        region = np.asarray(c.region, dtype=bool).view(np.uint8)  # (0 or 1)
        h, w = region.shape
        bx, by, bw, bh = cv2.boundingRect(region)
        ax0, ay0 = max(bx - 1, 0), max(by - 1, 0)
        ax1, ay1 = min(bx + bw + 1, w), min(by + bh + 1, h)
        cut = region[ay0:ay1, ax0:ax1]  # (doubled by nearest neighbour: each pixel 2 x 2)
        doubled = cv2.resize(
            cut, (2 * cut.shape[1], 2 * cut.shape[0]), interpolation=cv2.INTER_NEAREST
        )
        up = cv2.dilate(doubled, _SQUARE5)
        x0, y0 = 2 * c.origin[0], 2 * c.origin[1]
        shape = (min(2 * h, frame_shape[0] - y0), min(2 * w, frame_shape[1] - x0))
        up = up[: shape[0] - 2 * ay0, : shape[1] - 2 * ax0]
        return cls(up.view(bool), (x0 + 2 * ax0, y0 + 2 * ay0), (x0, y0), shape)

    def box_of(self, color: NDArray[np.uint8]) -> NDArray[np.uint8]:
        """The pixels of ``color`` in the box of ``up``."""
        (x, y), (h, w) = self.corner, self.up.shape
        return color[y : y + h, x : x + w]

    def within(self, hits: NDArray[np.uint8]) -> NDArray[np.uint8]:
        """The grown blob's pixels among ``hits`` (0/1, the box's shape), in its box."""
        return hits * self.up


def _side_by_side(boxes: list[NDArray[np.uint8]]) -> NDArray[np.uint8]:
    """Images (h_i, w_i, 3) laid left to right, top-aligned, padded with zeros."""
    out = np.zeros((max(b.shape[0] for b in boxes), sum(b.shape[1] for b in boxes), 3), np.uint8)
    left = 0
    for b in boxes:
        out[: b.shape[0], left : left + b.shape[1]] = b
        left += b.shape[1]
    return out


def _sticker_or_blown(
    image: NDArray[np.uint8], lut: NDArray[np.uint8], hue_lut: NDArray[np.uint8],
    params: DetectorParams,
) -> NDArray[np.uint8]:
    """1 where a pixel of an RGB image has a sticker colour once balanced by ``lut``, or
    is blown out as taken; else 0. Shape (h, w)."""
    import cv2

    labels, _ = colour_labels(cv2.LUT(image, lut), hue_lut, params)
    blown = cv2.inRange(image, (params.highlight_min,) * 3, (255, 255, 255))
    either = cv2.bitwise_or(labels, blown, dst=labels)  # (a label, 255, or 0)
    return cv2.threshold(either, 0, 1, cv2.THRESH_BINARY, dst=either)[1]


def _centre_of(
    region: NDArray[np.uint8], g: _GrownBlob, c: Candidate
) -> tuple[tuple[float, float], float]:
    """Centre and area of the largest outer contour of ``region`` (0/1, the grown blob
    ``g``'s pixels in its box) in the frame; the halved search's, scaled, when it has
    none. The contour is measured in the candidate's window (at ``g.origin``), as it
    always was: its box is all of the window that can hold a pixel of the blob."""
    import cv2

    (x, y), (x0, y0) = g.corner, g.origin
    contours, _ = cv2.findContours(
        region, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE, offset=(x - x0, y - y0)
    )
    if not contours:
        return (2 * c.where[0] + 0.5, 2 * c.where[1] + 0.5), 4 * c.area
    # (the area does not depend on where)
    contour = contours[0] if len(contours) == 1 else max(contours, key=cv2.contourArea)
    m = cv2.moments(contour)
    if m["m00"] <= 0:
        return (2 * c.where[0] + 0.5, 2 * c.where[1] + 0.5), 4 * c.area
    return (m["m10"] / m["m00"] + x0, m["m01"] / m["m00"] + y0), float(m["m00"])


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
    regions: ClothRegions | None = None,
) -> StickerDetections:
    """Search again, for the stickers not found, as a broad sheen leaves them: pastel.

    A semi-gloss sticker under a large light (a softbox, a window) reflects white light
    over its whole disc: its saturation falls to 0.1-0.3 while its hue survives, and
    nothing is blown out. The search runs :func:`detect_stickers` again with
    ``washed_saturation`` and ``washed_chroma`` (every other check unchanged: size,
    shape, disc and dot colours, white cloth around) and keeps what it finds of the
    stickers ``found`` lacks, away from the stickers found (a disc's distance). A blob
    covering a sticker found is that sticker: it is not judged again (``known``).

    Parameters
    ----------
    color, depth_mm, intrinsics, layout, params, napkin, colours
        As for :func:`detect_stickers`.
    found : StickerDetections
        The first search's result.
    regions : ClothRegions, keyword-only, optional
        The frame's white regions (:func:`.regions.cloth_regions`), when already
        found. The second search looks on the napkin's cells and
        ``washed_margin_cells`` around them only (the table, balanced to the low level,
        is pastel too), or everywhere when the napkin is not told from the table.

    Returns
    -------
    StickerDetections
        ``found`` with the washed-out stickers added (their scores halved, so that a
        person reading them sees which they are); its rejections are the first search's.
    """
    params = params or DetectorParams()
    if found.found.all():
        return found
    frame = search_frame(color, depth_mm, intrinsics, layout, napkin, params, colours=colours)
    return washed_out_search(frame, found, regions=regions)


def washed_out_search(
    frame: SearchFrame, found: StickerDetections, *, regions: ClothRegions | None
) -> StickerDetections:
    """The step of the detection after :func:`first_search`: the stickers ``found``
    lacks, searched again as a broad sheen leaves them (:func:`find_washed_out`), on
    the same :class:`SearchFrame` (its napkin, halving, depth, hue table and palette)
    and the frame's white regions (:func:`.regions.cloth_regions`; None: found here,
    as when their cells are not the napkin's sampling stride)."""
    import cv2

    params, napkin, color, layout, colours = (
        frame.params, frame.napkin, frame.color, frame.layout, frame.colours
    )
    if found.found.all():
        return found
    lower = replace(napkin, lut=balance_lut(napkin.white_rgb, params.washed_level))
    cells = RegionParams(cell_px=lower.stride)
    if regions is None or regions.cell_px != cells.cell_px:
        regions = cloth_regions(color, napkin.white_rgb, cells)
    looks = PastelLooks(color, lower, regions)  # (shared by the looks below)
    if len(pale_samples(color, found, layout, params, lower, colours, looks=looks)[0]) < 2:
        return found  # no pastel patch anywhere: nothing to search, nothing left unread
    roi = None
    cloth = looks.cloth(found.centroids)
    if found.found.any() and cloth is not None:
        m = 2 * params.washed_margin_cells + 1
        roi = cv2.dilate(cloth.astype(np.uint8), np.ones((m, m), np.uint8)).astype(bool)
    again = _search(  # (only the stickers not found yet can be merged)
        frame, pastel_params(params), lower.lut, roi=roi, report=~found.found,
        known=found.centroids,
    )
    merged = merge_second_search(found, again)
    return with_unread(color, merged, layout, params, lower, colours, looks=looks)


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
    from ..core.errors import CalibrationError

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
