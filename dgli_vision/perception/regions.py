"""The frame's white regions: where the napkin's cloth may be, found once per frame.

Stage 1 with the napkin (:mod:`.napkin`): the frame is averaged over cells of
``RegionParams.cell_px`` pixels, the cells bright and neutral enough against the
napkin's white are cloth, the stickers' holes are closed, and the cells are labelled by
connected region (:class:`ClothRegions`, :func:`cloth_regions`). The napkin's cells are
the regions holding located stickers (:func:`cloth_cells`). The second sticker search
(:mod:`.washed`), the footprint (:mod:`.footprint`) and the corners' tips
(:mod:`.tips`) read them; none of them finds them again.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..core.colour import srgb_lut
from ..core.order_stats import sorted_median, sorted_quantile
from .napkin import NapkinParams, NapkinView
from .params import RegionParams

__all__ = [
    "MAX_BORDER_CELLS",
    "ClothRegions",
    "RegionParams",
    "any_of",
    "border_cells",
    "cloth_cells",
    "cloth_regions",
]

#: Cells of the image border a napkin's region may touch and still be all in view: a
#: bright seam the closing joined to it touches with one or two.
MAX_BORDER_CELLS = 2


@dataclass(frozen=True, eq=False)
class ClothRegions:
    """The white regions of a frame: image cells of ``cell_px`` pixels (averaged) that
    look like the napkin's cloth, with its stickers' holes closed, labelled by connected
    region (0: not cloth), shape ``(H // cell_px, W // cell_px)``. Found once per frame
    (:func:`cloth_regions`); the footprint and the second sticker search both read it.
    ``cells`` keeps the averaged cells themselves (RGB, ``cv2.INTER_AREA`` of the
    frame's top-left ``H // cell_px * cell_px`` x ``W // cell_px * cell_px`` pixels), for
    a later stage that needs the same average. ``lum``: every cell's luminance balanced to
    the napkin's white (1); ``lit``: the cells bright and neutral enough to be cloth,
    before the closing; ``chroma``: every cell's chroma (largest less smallest balanced
    channel); ``table_lum``: the median cell's luminance (the table's)."""

    labels: NDArray[np.int32]
    cell_px: int
    cells: NDArray[np.uint8] | None = None
    lum: NDArray[np.float64] | None = None
    lit: NDArray[np.bool_] | None = None
    chroma: NDArray[np.float64] | None = None
    table_lum: float = float("nan")


def _cell_means(color: NDArray[np.uint8], c: int) -> NDArray[np.uint8]:
    """The mean of every ``c`` x ``c`` cell of an 8-bit image (H, W, channels), shape
    ``(H // c, W // c, channels)``: ``cv2.resize(..., INTER_AREA)`` of the image's
    top-left ``H // c * c`` x ``W // c * c`` pixels, to the bit.

    For an integer factor OpenCV averages each cell pixel by pixel; for a cell side a
    power of two from 4 to 16 the sums are found here instead by whole rows (the ``c``
    rows of each row of cells added as 16-bit numbers, one reduction), then, on those
    sums turned on their side (a pixel's channel a row, a row of cells a column), by
    the ``c`` rows of each column of cells (log2 ``c`` additions of long rows, not of
    a few values per cell), and rounded as OpenCV rounds (the nearest integer, ties
    to even). Other sides are left to OpenCV (its 2 x 2 average rounds ties up).
    """
    import cv2

    h, w = color.shape[0] // c, color.shape[1] // c
    crop = color[: h * c, : w * c]
    if crop.ndim != 3 or crop.dtype != np.uint8 or c not in (4, 8, 16):
        return cv2.resize(crop, (w, h), interpolation=cv2.INTER_AREA)
    ch = crop.shape[2]
    rows = crop.reshape(h, c, w * c * ch)  # (a copy only for a cropped frame)
    # one reduction over the rows of each row of cells (at most 16 x 16 x 255: 16 bits
    # hold it), a third less time than adding the rows one by one
    sums = rows.sum(axis=1, dtype=np.uint16)  # (h, w c ch)
    side = cv2.transpose(sums).reshape(w, c, ch * h)  # [column of cells, pixel, (ch, row)]
    while side.shape[1] > 1:
        half = side.shape[1] // 2
        side = cv2.add(side[:, :half].reshape(w, -1), side[:, half:].reshape(w, -1))
        side = side.reshape(w, half, ch * h)
    cells = side.reshape(w, ch, h).transpose(2, 0, 1)  # (h, w, ch), a view
    return cv2.convertScaleAbs(np.ascontiguousarray(cells), alpha=1.0 / (c * c))


def cloth_regions(
    color: NDArray[np.uint8],
    white_rgb: NDArray[np.float64],
    params: RegionParams | None = None,
    napkin_params: NapkinParams | None = None,
) -> ClothRegions | None:
    """The white regions of a frame (None for an image of fewer than 4 cells a side).

    Parameters
    ----------
    color : ndarray of uint8, shape (H, W, 3)
    white_rgb : ndarray, shape (3,)
        The napkin's white, linear RGB (:attr:`.napkin.NapkinView.white_rgb`).
    params, napkin_params : optional
    """
    import cv2

    p = params or RegionParams()
    q = napkin_params or NapkinParams()
    c = p.cell_px
    h, w = color.shape[0] // c, color.shape[1] // c
    if h < 4 or w < 4:
        return None
    small = _cell_means(color, c)
    # The napkin's white; where the napkin is blown out the estimate falls on the next
    # brightest surface (the table), so the level is at least that of the brightest
    # few per cent of the cells, clipped ones included. (One channel at a time: the
    # same arithmetic as reductions over the last axis, ten times cheaper; the linear
    # light of every cell by one table look-up, cv2.LUT keeping the table's float64.)
    linear = cv2.LUT(small, srgb_lut())
    r, g, b = linear[..., 0], linear[..., 1], linear[..., 2]
    white = np.maximum(white_rgb, 1e-4)
    level = sorted_quantile(np.sort(((r + g + b) / 3).ravel()), 1.0 - q.bright_fraction)
    white = white * max(1.0, level / float(white.mean()))
    r, g, b = r / white[0], g / white[1], b / white[2]  # the napkin at 1
    lum = (r + g + b) / 3
    chroma = np.maximum(np.maximum(r, g), b) - np.minimum(np.minimum(r, g), b)
    # Most of the view is table: a table nearly as bright as the napkin raises the bar.
    table = sorted_median(np.sort(lum.ravel()))
    floor = max(q.min_napkin_brightness, table + p.table_margin)
    cloth = (lum >= floor) & (chroma <= q.neutral_chroma * lum)
    kernel = np.ones((p.close_cells, p.close_cells), np.uint8)
    closed = cv2.morphologyEx(cloth.view(np.uint8), cv2.MORPH_CLOSE, kernel)
    _, labels = cv2.connectedComponents(closed, connectivity=8)
    return ClothRegions(labels, c, small, lum, cloth, chroma, table)


def cloth_cells(
    color: NDArray[np.uint8],
    napkin: NapkinView,
    sticker_px: NDArray[np.float64],
    params: RegionParams | None = None,
    napkin_params: NapkinParams | None = None,
    *,
    regions: ClothRegions | None = None,
) -> NDArray[np.bool_] | None:
    """The napkin's cells: image cells of ``params.cell_px`` pixels (averaged) that are
    its white cloth, with its stickers' holes filled, in the parts that hold located
    stickers; shape ``(H // cell_px, W // cell_px)``. None where the cloth cannot be
    told from the table (it reaches the image border).

    Parameters
    ----------
    color : ndarray of uint8, shape (H, W, 3)
    napkin : NapkinView
        The napkin's white.
    sticker_px : ndarray, shape (n, 2)
        Pixels (x, y) of located stickers (NaN rows ignored).
    params, napkin_params : optional
    regions : ClothRegions, keyword-only, optional
        The frame's white regions (:func:`cloth_regions`) when already found (of the
        same cell size).
    """
    p = params or RegionParams()
    if regions is None or regions.cell_px != p.cell_px:
        regions = cloth_regions(color, napkin.white_rgb, p, napkin_params)
    if regions is None:
        return None
    labels, c = regions.labels, regions.cell_px
    h, w = labels.shape
    px = np.asarray(sticker_px, dtype=np.float64).reshape(-1, 2)
    px = px[np.isfinite(px).all(axis=1)]
    col = np.minimum(np.maximum(px[:, 0] // c, 0), w - 1).astype(np.intp)
    row = np.minimum(np.maximum(px[:, 1] // c, 0), h - 1).astype(np.intp)
    # the regions holding them (a set of a dozen labels: np.unique costs more)
    held = np.array(sorted(set(labels[row, col].tolist()) - {0}), dtype=labels.dtype)
    if held.size == 0:
        return None
    cloth = any_of(labels, held)
    # a region cut by the image border is not all in view; a thread of a cell or two
    # (a bright seam the closing joined) does not make it so
    if border_cells(cloth) > MAX_BORDER_CELLS:
        return None
    return cloth


def any_of(labels: NDArray[np.int32], wanted: NDArray) -> NDArray[np.bool_]:
    """``np.isin(labels, wanted)`` for labels of connected regions (0 and up): a
    comparison per label wanted (the napkin is one region, or a few)."""
    if len(wanted) > 8:
        return np.isin(labels, wanted)
    out = np.zeros(labels.shape, dtype=bool)
    for label in wanted.tolist():
        out |= labels == label
    return out


def border_cells(cells: NDArray[np.bool_]) -> int:
    """How many of the ``cells`` lie on the grid's border."""
    count = np.count_nonzero
    return int(count(cells[0]) + count(cells[-1]) + count(cells[1:-1, 0]) + count(cells[1:-1, -1]))
