"""Finding the napkin: its white (colour constancy), and what covers it (highlights,
objects above it).

SPEC's napkin is white or light grey and unpatterned, so its pixels tell each image's
white balance and exposure. :func:`find_napkin` estimates that white from the brightest
large neutral surface, and returns a per-channel lookup table that maps the image to one
where the napkin is neutral at a fixed level; the detector thresholds that normalised
image relative to the napkin, not with absolute numbers. It also marks where nothing can
be seen: blown-out highlights, and objects standing well above the table that are not
napkin-coloured (a gripper, an arm).

All work happens on a subsampled image (``stride``) except the lookup, which OpenCV
applies to the full frame in about a millisecond.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ..core.camera import Intrinsics
from ..core.colour import linear_to_srgb, srgb_lut
from ..core.order_stats import median, quantile
from .params import NapkinParams

__all__ = ["NapkinMasks", "NapkinParams", "NapkinView", "balance_lut", "find_napkin"]


@dataclass(frozen=True, eq=False)
class NapkinView:
    """The napkin as found in one image.

    Attributes
    ----------
    white_rgb : ndarray, shape (3,)
        The napkin's white in the image, linear RGB in [0, 1].
    lut : ndarray of uint8, shape (256, 1, 3)
        Per-channel lookup (for ``cv2.LUT`` on RGB) that balances the image to a neutral
        napkin at ``target_level``.
    highlight : ndarray of bool, shape (H // stride + 1, W // stride + 1)
        Blown-out or much-brighter-than-napkin near-white samples.
    occluder : ndarray of bool, same shape
        Samples of an object above the table (raised, not napkin-coloured).
    cloth : ndarray of bool, same shape
        Samples of the napkin: bright and neutral once balanced.
    stride : int
        Subsampling of the masks, pixels.
    raised : ndarray of bool, same shape, optional
        Samples of cloth held up above the table (not an object, see
        ``NapkinParams.raised_cloth_mm``).
    height_mm : ndarray of float32, same shape, optional
        Height of every sample above the table plane, mm (NaN without a reading).
    raised_px : ndarray of int, shape (n, 2), optional
        Every pixel (x, y) of cloth held up, at full resolution (the samples of
        ``raised`` pool them).
    raised_height_mm : ndarray of float32, shape (n,), optional
        Their heights above the table, mm.
    """

    white_rgb: NDArray[np.float64]
    lut: NDArray[np.uint8]
    highlight: NDArray[np.bool_]
    occluder: NDArray[np.bool_]
    stride: int
    cloth: NDArray[np.bool_] | None = None
    raised: NDArray[np.bool_] | None = None
    height_mm: NDArray[np.float32] | None = None
    raised_px: NDArray[np.intp] | None = None
    raised_height_mm: NDArray[np.float32] | None = None

    def near(self, mask: NDArray[np.bool_], uv: NDArray, radius_px: float) -> NDArray[np.bool_]:
        """Which pixels ``uv`` (n, 2) have a ``mask`` sample within ``radius_px``."""
        return _near(mask, uv, radius_px, self.stride)

    def masks(self) -> NapkinMasks:
        """What the later stages ask of this view (the masks, heights, nearness), as a
        value of its own."""
        return NapkinMasks(
            self.stride, self.highlight, self.occluder, self.cloth, self.raised, self.height_mm
        )


@dataclass(frozen=True, eq=False)
class NapkinMasks:
    """Where things are around the napkin, on its sampling grid: what the evidence stage
    receives from the napkin stage (:meth:`NapkinView.masks`).

    Attributes
    ----------
    stride : int
        Subsampling of the masks, pixels: sample (i, j) is pixel (u, v) = (j, i) * stride.
    highlight, occluder : ndarray of bool, shape (H // stride + 1, W // stride + 1)
        Highlights, and objects above the table (see :class:`NapkinView`).
    cloth, raised : ndarray of bool, same shape, optional
        The napkin's samples, and cloth held up above the table.
    height_mm : ndarray of float32, same shape, optional
        Height of every sample above the table plane, mm (NaN without a reading).
    """

    stride: int
    highlight: NDArray[np.bool_]
    occluder: NDArray[np.bool_]
    cloth: NDArray[np.bool_] | None = None
    raised: NDArray[np.bool_] | None = None
    height_mm: NDArray[np.float32] | None = None

    def near(self, mask: NDArray[np.bool_], uv: NDArray, radius_px: float) -> NDArray[np.bool_]:
        """Which pixels ``uv`` (n, 2) have a ``mask`` sample within ``radius_px``."""
        return _near(mask, uv, radius_px, self.stride)

    def height_at(self, uv: NDArray) -> NDArray[np.float64]:
        """Median height above the table (mm) of the 3 x 3 samples around pixels ``uv``
        (n, 2); NaN where there is no reading (or no heights at all)."""
        out = np.full(len(uv), np.nan)
        if self.height_mm is None:
            return out
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        ok = np.isfinite(uv).all(axis=1)
        hh, ww = self.height_mm.shape
        s = self.stride
        near = ok & (np.abs(uv) < 1e9).all(axis=1)  # (an int, once rounded)
        ij = np.zeros((len(uv), 2), dtype=np.intp)
        ij[near] = np.rint(uv[near, ::-1] / s)  # round half to even, as round() does
        inside = near & (ij >= 1).all(axis=1) & (ij[:, 0] < hh - 1) & (ij[:, 1] < ww - 1)
        if inside.any():  # whole 3 x 3 windows, all at once
            out[inside] = _window_medians(self.height_mm, ij[inside])
        for k in np.flatnonzero(ok & ~inside):  # windows the grid's edge cuts
            u, v = uv[k]
            i, j = round(v / s), round(u / s)
            win = self.height_mm[max(i - 1, 0) : i + 2, max(j - 1, 0) : j + 2]
            told = win[np.isfinite(win)]
            if told.size:
                out[k] = median(told)  # np.nanmedian's value, without its overhead
        return out

    def without_objects_near(self, uv: NDArray, radius_px: float) -> NapkinMasks:
        """These masks with no object within ``radius_px`` of the pixels ``uv`` (n, 2)
        (more than a sample): a sticker on a flap held up is a raised, coloured patch,
        not an object."""
        if not self.occluder.any() or not len(uv):
            return self
        hh, ww = self.occluder.shape
        s, reach = self.stride, radius_px + self.stride
        mine = np.zeros((hh, ww), dtype=bool)
        for u, v in np.asarray(uv, dtype=np.float64):
            if not (np.isfinite(u) and np.isfinite(v)):
                continue
            # only the samples within reach can be: a window, not the whole grid
            i0, i1 = max(int(np.floor((v - reach) / s)), 0), min(int((v + reach) // s) + 2, hh)
            j0, j1 = max(int(np.floor((u - reach) / s)), 0), min(int((u + reach) // s) + 2, ww)
            if i0 >= i1 or j0 >= j1:
                continue
            us, vs = np.arange(j0, j1) * s, np.arange(i0, i1) * s
            mine[i0:i1, j0:j1] |= np.hypot(us[None, :] - u, vs[:, None] - v) <= reach
        return replace(self, occluder=self.occluder & ~mine)


def _window_medians(grid: NDArray[np.floating], ij: NDArray[np.intp]) -> NDArray[np.float64]:
    """The median of the finite values of the 3 x 3 window of ``grid`` around each
    sample (i, j) of ``ij`` (n, 2), windows inside the grid; NaN where none is finite.
    ``np.nanmedian``'s value: the middle one, or the mean of the two middle ones in the
    grid's dtype."""
    d = np.arange(-1, 2)
    rows = (ij[:, 0, None] + d)[:, :, None]
    cols = (ij[:, 1, None] + d)[:, None, :]
    win = np.sort(grid[rows, cols].reshape(len(ij), 9), axis=1)  # NaN last
    n = np.count_nonzero(np.isfinite(win), axis=1)
    k = np.arange(len(ij))
    hi = win[k, n // 2 % 9]
    lo = win[k, np.maximum(n - 1, 0) // 2]
    mid = np.where(n % 2 == 1, hi, (lo + hi) / grid.dtype.type(2))
    return np.where(n > 0, mid, np.nan).astype(np.float64)


def _near(
    mask: NDArray[np.bool_], uv: NDArray, radius_px: float, stride: int
) -> NDArray[np.bool_]:
    """Which pixels ``uv`` (n, 2) have a sample of ``mask`` (on a grid of ``stride``
    pixels) within ``radius_px`` (and a sample)."""
    out = np.zeros(len(uv), dtype=bool)
    if not mask.any():
        return out
    reach = radius_px + stride
    vs, us = np.nonzero(mask) if not np.isfinite(reach) else (None, None)
    for k, p in enumerate(np.asarray(uv, dtype=np.float64)):
        if not np.all(np.isfinite(p)):
            continue
        if vs is None:  # only the samples of a window around p can be near
            pts = _samples_around(mask, p, reach, stride)
        else:
            pts = np.stack([us, vs], 1) * stride
        if len(pts):
            out[k] = bool((np.abs(pts - p).max(axis=1) <= reach).any())
    return out


def _samples_around(
    mask: NDArray[np.bool_], p: NDArray[np.float64], reach: float, stride: int
) -> NDArray[np.intp]:
    """The pixels (x, y), shape (n, 2), of the samples of ``mask`` (a grid of
    ``stride`` pixels) that may lie within ``reach`` of the pixel ``p``: those of a
    window of the grid a sample wider each way than the reach."""
    hh, ww = mask.shape
    i0 = max(int(np.floor((p[1] - reach) / stride)) - 1, 0)
    i1 = min(int(np.floor((p[1] + reach) / stride)) + 2, hh)
    j0 = max(int(np.floor((p[0] - reach) / stride)) - 1, 0)
    j1 = min(int(np.floor((p[0] + reach) / stride)) + 2, ww)
    if i0 >= i1 or j0 >= j1:
        return np.zeros((0, 2), dtype=np.intp)
    vs, us = np.nonzero(mask[i0:i1, j0:j1])
    return np.stack([us + j0, vs + i0], 1) * stride


def balance_lut(white_rgb: NDArray[np.float64], level: int) -> NDArray[np.uint8]:
    """Per-channel lookup (for ``cv2.LUT`` on RGB), shape (256, 1, 3), that maps the
    napkin's white (linear RGB, shape (3,)) to a neutral 8-bit ``level``."""
    gains = srgb_lut()[level] / np.maximum(np.asarray(white_rgb, dtype=np.float64), 1e-4)
    table = linear_to_srgb(srgb_lut()[:, None] * gains[None, :]) * 255.0
    return np.clip(np.rint(table), 0, 255).astype(np.uint8).reshape(256, 1, 3)


def _height_above_table(
    intrinsics: Intrinsics,
    normal: NDArray[np.float64],
    offset_m: float,
    x: NDArray,
    y: NDArray,
    depth_mm: NDArray,
) -> NDArray[np.float32]:
    """Height (mm) above the table plane of pixels ``(x, y)`` at z-depths ``depth_mm``
    (broadcast together): ``(u z, v z, z) . n - offset``."""
    u = (x - intrinsics.cx) / intrinsics.fx
    v = (y - intrinsics.cy) / intrinsics.fy
    slope = (u * normal[0] + v * normal[1] + normal[2]).astype(np.float32)
    return (np.asarray(depth_mm, dtype=np.float32) * slope - offset_m * 1e3).astype(np.float32)


def _not_napkin(lum: NDArray, chroma: NDArray, p: NapkinParams) -> NDArray[np.bool_]:
    """Too dark or too coloured (balanced brightness and chroma) to be the napkin."""
    return (lum < p.occluder_darkness) | (
        chroma > p.occluder_chroma * np.maximum(lum, p.occluder_darkness)
    )


#: Raised blocks beyond which :func:`_raised_cloth_pixels` first drops those too dark to
#: hold any napkin-coloured pixel (a bound that never drops one that does).
_MANY_BLOCKS = 64


def _brightest_in_blocks(
    color: NDArray[np.uint8], bi: NDArray[np.intp], bj: NDArray[np.intp], s: int
) -> NDArray[np.uint8]:
    """Largest channel value over the pixels of each block (rows ``bi``, columns ``bj``
    of the ``s``-pixel sampling grid; the same window as the depth erosion: rows and
    columns ``k s - s // 2`` to ``k s - s // 2 + s - 1``), computed on the part of the
    image the blocks span.

    A block reduction, not a dilation of every pixel: the maximum of the ``s`` rows of
    each block row, then of the ``3 s`` values (pixels and channels) of each block on
    the rows left. Where the image's edge cuts a block, the missing pixels count as 0,
    which no maximum of 8-bit values notices.
    """
    import cv2

    h, w = color.shape[:2]
    lo = s // 2
    i0, i1 = int(bi.min()), int(bi.max()) + 1  # the block rows and columns spanned
    j0, j1 = int(bj.min()), int(bj.max()) + 1
    ys, xs = i0 * s - lo, j0 * s - lo  # their first pixel row and column (maybe outside)
    ye, xe = i1 * s - lo, j1 * s - lo
    if ys >= 0 and xs >= 0 and ye <= h and xe <= w:  # (whole blocks: a view of the frame)
        span = color[ys:ye, xs:xe].reshape(ye - ys, -1)
    else:
        y0, y1, x0, x1 = max(ys, 0), min(ye, h), max(xs, 0), min(xe, w)
        span = np.zeros((ye - ys, 3 * (xe - xs)), np.uint8)
        span[y0 - ys : y1 - ys, 3 * (x0 - xs) : 3 * (x1 - xs)] = color[y0:y1, x0:x1].reshape(
            y1 - y0, -1
        )
    rows = span[0::s].copy()  # (rows of blocks, 3 x columns)
    for k in range(1, s):
        cv2.max(rows, span[k::s], dst=rows)
    top = rows[:, 0 :: 3 * s].copy()  # (rows of blocks, columns of blocks)
    for k in range(1, 3 * s):
        cv2.max(top, rows[:, k :: 3 * s], dst=top)
    return top[bi - i0, bj - j0]


def _nearest_in_blocks(depth_mm: NDArray[np.uint16], s: int) -> NDArray[np.uint16]:
    """The nearest reading minus one around every ``s``-th pixel, shape
    (ceil(H / s), ceil(W / s)): the minimum of ``depth - 1`` over rows and columns
    ``k s - s // 2`` to ``k s - s // 2 + s - 1`` (an ``s`` x ``s`` erosion sampled every
    ``s``-th pixel), 65535 where the block has no reading (0 wraps to the largest
    value, so the nearest reading wins the minimum).

    The rows of each block first, then the columns on the ``H / s`` rows left: one pass
    over the image, not an erosion of all of it. The rows are taken in order, a band of
    :data:`_BAND_ROWS` at a time, less one into a buffer that stays in cache and reduced
    there (a frame fresh from memory reads fastest in order; every ``s``-th row at a
    time, ``s`` times over, costs a tenth more).
    """
    import cv2

    one = np.uint16(1)
    hh, ww = depth_mm.shape
    nh, first = -(-hh // s), s - s // 2  # blocks; rows of the first (the edge cuts it)
    whole = max(min(nh - 1, (hh - first) // s), 0)  # blocks after it with all s rows
    mins = np.empty((nh, ww), np.uint16)  # each block's rows' minimum, less one
    np.subtract(depth_mm[:first], one).min(axis=0, out=mins[0])
    per = max(_BAND_ROWS // s, 1)  # blocks a band
    band = np.empty((min(per, whole) * s, ww), np.uint16)
    for b0 in range(0, whole, per):
        b1 = min(b0 + per, whole)
        rows = band[: (b1 - b0) * s]
        np.subtract(depth_mm[first + b0 * s : first + b1 * s], one, out=rows)
        rows.reshape(b1 - b0, s, ww).min(axis=1, out=mins[1 + b0 : 1 + b1])
    if whole < nh - 1:  # the last block, cut by the image's edge
        np.subtract(depth_mm[first + s * whole :], one).min(axis=0, out=mins[-1])
    return cv2.erode(mins, np.ones((1, s), np.uint8))[:, ::s]


#: Rows of depth :func:`_nearest_in_blocks` takes at a time (a quarter of a megabyte of a
#: 1280-pixel-wide frame: it stays in cache while it is reduced).
_BAND_ROWS = 96


def _block_pixels(
    bi: NDArray[np.intp], bj: NDArray[np.intp], s: int, hh: int, ww: int
) -> NDArray[np.intp]:
    """Flat indices (``y * W + x``) of the pixels of blocks (rows ``bi``, columns ``bj``
    of the ``s``-pixel grid; the erosion's window around each sample), block after
    block, row after row, those outside the image left out."""
    dy, dx = np.mgrid[0:s, 0:s] - s // 2  # the erosion's window around each sample
    corner = (bi * s) * ww + bj * s
    at = (corner[:, None] + (dy * ww + dx).ravel()[None, :]).ravel()
    lo, hi = s // 2, s - 1 - s // 2  # the window's reach before and after its sample
    y_ok = (bi.min() * s >= lo) and (bi.max() * s + hi < hh)
    x_ok = (bj.min() * s >= lo) and (bj.max() * s + hi < ww)
    if y_ok and x_ok:  # no block at the image's edge: every pixel is inside
        return at
    ys = (bi[:, None] * s + dy.ravel()[None, :]).ravel()
    xs = (bj[:, None] * s + dx.ravel()[None, :]).ravel()
    return at[(ys >= 0) & (ys < hh) & (xs >= 0) & (xs < ww)]


def _raised_cloth_pixels(
    color: NDArray[np.uint8],
    depth_mm: NDArray[np.uint16],
    intrinsics: Intrinsics,
    normal: NDArray[np.float64],
    offset_m: float,
    white: NDArray[np.float64],
    p: NapkinParams,
) -> tuple[NDArray[np.intp], NDArray[np.float32]]:
    """Pixels (x, y) of napkin-coloured cloth standing more than ``raised_cloth_mm``
    above the table, at full resolution, and their heights (mm).

    The nearest reading of each block of ``stride`` x ``stride`` pixels around a sample
    says whether anything in the block may stand that high; only those blocks are looked
    at pixel by pixel (a frame with every fold laid flat has none).
    """

    s = p.stride
    hh, ww = depth_mm.shape
    nearest = _nearest_in_blocks(depth_mm, s).astype(np.float32) + 1.0
    gy, gx = np.arange(nearest.shape[0])[:, None] * s, np.arange(nearest.shape[1])[None, :] * s
    # a block's slope varies by well under a millimetre of height: 2 mm of slack
    block_top = _height_above_table(intrinsics, normal, offset_m, gx, gy, nearest)
    bi, bj = np.nonzero((nearest < 65535) & (block_top > p.raised_cloth_mm - 2.0))
    if len(bi) > _MANY_BLOCKS:  # an arm or a gripper: drop the blocks with no bright pixel
        bright = _brightest_in_blocks(color, bi, bj, s)
        keep = srgb_lut()[bright] >= p.occluder_darkness * float(np.min(white))
        bi, bj = bi[keep], bj[keep]
    if not len(bi):
        empty = np.zeros((0, 2), dtype=np.intp)
        return empty, np.zeros(0, dtype=np.float32)
    at = _block_pixels(bi, bj, s, hh, ww)
    # colour first (a gripper's or an arm's pixels go no further), one channel at a time
    # (np.take: the values of fancy indexing, several times faster for many pixels)
    lut, wt = srgb_lut(), np.maximum(white, 1e-4)
    px = np.take(color.reshape(-1, 3), at, axis=0)  # (n, 3) uint8
    r, g, b = (np.take(lut / wt[k], px[:, k]) for k in range(3))  # balanced: 256 divisions
    lum = (r + g + b) / 3
    chroma = np.maximum(np.maximum(r, g), b) - np.minimum(np.minimum(r, g), b)
    at = at[~_not_napkin(lum, chroma, p)]
    ys, xs = np.divmod(at, ww)
    d = np.take(depth_mm.reshape(-1), at)
    height = _height_above_table(intrinsics, normal, offset_m, xs, ys, d)
    up_high = (d > 0) & (height > p.raised_cloth_mm)
    return np.column_stack([xs[up_high], ys[up_high]]), height[up_high]


def find_napkin(
    color: NDArray[np.uint8],
    depth_mm: NDArray[np.uint16],
    intrinsics: Intrinsics,
    table_normal: NDArray[np.float64] | None = None,
    table_offset_m: float | None = None,
    params: NapkinParams | None = None,
) -> NapkinView:
    """Estimate the napkin's white and mark highlights and objects above it.

    Parameters
    ----------
    color : ndarray of uint8, shape (H, W, 3)
        RGB image.
    depth_mm : ndarray of uint16, shape (H, W)
        Registered depth, mm (0 = no reading).
    intrinsics : Intrinsics
    table_normal : ndarray, shape (3,), optional
        Unit normal of the table plane towards the camera (camera frame).
    table_offset_m : float, optional
        ``normal @ x`` of the table plane's points, metres. Without a plane, no
        occluders are marked.
    params : NapkinParams, optional

    Returns
    -------
    NapkinView
    """
    p = params or NapkinParams()
    samples = _Samples.of(color, p)
    white = _napkin_white(samples, p)
    lut = balance_lut(white, p.target_level)
    lum, chroma = samples.balanced(white)
    lum, chroma = lum.reshape(samples.shape), chroma.reshape(samples.shape)
    cloth = (lum >= p.min_napkin_brightness) & (chroma <= p.neutral_chroma * lum)
    highlight = samples.clipped.reshape(samples.shape) | (
        (lum >= p.highlight_level * _local_level(lum, cloth, p))
        & (chroma <= p.highlight_chroma * lum)
    )
    if table_normal is None or table_offset_m is None:
        occluder = np.zeros(samples.shape, dtype=bool)
        return NapkinView(white, lut, highlight, occluder, p.stride, cloth)
    s = p.stride
    # the pass over every depth pixel first: the samples' rows are then in cache
    raised_px, raised_height = _raised_cloth_pixels(
        color, depth_mm, intrinsics, table_normal, table_offset_m, white, p
    )
    d = depth_mm[::s, ::s].astype(np.float32)
    xs, ys = np.arange(samples.shape[1]) * s, np.arange(samples.shape[0]) * s
    height_mm = _height_above_table(
        intrinsics, table_normal, table_offset_m, xs[None, :], ys[:, None], d
    )
    occluder = _objects((d > 0) & (height_mm > p.occluder_height_mm), lum, chroma, p)
    raised_cloth, keep = _held_up_cloth(raised_px, samples.shape, p)
    height_mm[d <= 0] = np.nan
    if not keep.all():  # (a flap held up keeps every pixel: no copy of them then)
        raised_px, raised_height = raised_px[keep], raised_height[keep]
    return NapkinView(
        white, lut, highlight, occluder, s, cloth, raised_cloth, height_mm, raised_px,
        raised_height,
    )


@dataclass(frozen=True, eq=False)
class _Samples:
    """The image subsampled by ``stride``: linear channels as separate flat arrays
    (reductions over a last axis of 3 are slow), shape (n,) each, float32; ``clipped``
    (n,) the blown-out samples; ``shape`` the grid's; ``codes`` the 8-bit levels of the
    three channels (3, n)."""

    r: NDArray[np.float32]
    g: NDArray[np.float32]
    b: NDArray[np.float32]
    clipped: NDArray[np.bool_]
    shape: tuple[int, int]
    codes: NDArray[np.uint8]

    @classmethod
    def of(cls, color: NDArray[np.uint8], p: NapkinParams) -> _Samples:
        import cv2

        sub = color[:: p.stride, :: p.stride]
        codes = np.ascontiguousarray(np.moveaxis(sub, -1, 0)).reshape(3, -1)
        r, g, b = cv2.LUT(codes, _linear8())  # (the float table gives float32 planes)
        clipped = (
            (codes[0] >= p.clipped_level)
            & (codes[1] >= p.clipped_level)
            & (codes[2] >= p.clipped_level)
        )
        return cls(r, g, b, clipped, sub.shape[:2], codes)

    def median_of(self, which: NDArray[np.bool_]) -> NDArray[np.float64]:
        """Per-channel median (3,) of the samples ``which`` (non-empty): the linear
        value of each channel's median 8-bit level (the levels' lookup only grows, so it
        is the median of the linear values, found by counting 256 levels rather than by
        sorting, with ``cv2.calcHist`` under the mask rather than gathering the samples;
        the mean of the two middle ones for an even count)."""
        import cv2

        n = int(np.count_nonzero(which))
        lut = _linear8()
        mask = np.ascontiguousarray(which, dtype=bool).view(np.uint8).reshape(self.shape)
        counts = np.empty((3, 256), np.float32)
        for k in range(3):
            plane = self.codes[k].reshape(self.shape)
            cv2.calcHist([plane], [0], mask, [256], [0, 256], hist=counts[k, :, None])
        ranks = np.cumsum(counts, axis=1, dtype=np.int64)
        # each channel's levels of ranks (n - 1) // 2 and n // 2: how many levels hold
        # fewer samples (``searchsorted(..., side="right")``)
        lo = np.count_nonzero(ranks <= (n - 1) // 2, axis=1)
        hi = np.count_nonzero(ranks <= n // 2, axis=1)
        a, b = lut[lo], lut[hi]
        return np.where(lo == hi, a, (a + b) / np.float32(2)).astype(np.float64)

    def balanced(self, white: NDArray) -> tuple[NDArray, NDArray]:
        """Brightness and chroma (n,) of every sample balanced to ``white``."""
        w = np.maximum(white, 1e-4).astype(np.float32)
        br, bg, bb = self.r / w[0], self.g / w[1], self.b / w[2]
        lum = br + bg  # ((br + bg) + bb) / 3, in place
        lum += bb
        lum /= 3
        chroma = np.maximum(br, bg)
        np.maximum(chroma, bb, out=chroma)
        np.minimum(br, bg, out=br)  # (br is not needed any more)
        np.minimum(br, bb, out=br)
        chroma -= br
        return lum, chroma


@lru_cache(maxsize=1)
def _linear8() -> NDArray[np.float32]:
    """Linear light of each 8-bit level, float32 (256,)."""
    return srgb_lut().astype(np.float32)


def _local_level(
    lum: NDArray[np.float32], cloth: NDArray[np.bool_], p: NapkinParams
) -> NDArray[np.float32]:
    """The napkin's own brightness around every sample, relative to its white (at least
    1), shape of ``lum``: the mean of the cloth samples within ``level_window`` samples,
    each capped at ``highlight_level`` (a lobe cannot raise its own surround much).

    Light falls off across a napkin under a lamp (1.2-2 times from side to side) and a
    fabric's sheen brightens a broad part of it; measured against this level, its
    brighter side is no highlight, while a mirror highlight stands out of the cloth
    around it."""
    import cv2

    k = (p.level_window, p.level_window)
    weight = cloth.astype(np.float32)
    capped = np.minimum(lum, p.highlight_level).astype(np.float32) * weight
    total = cv2.blur(weight, k, borderType=cv2.BORDER_REPLICATE)
    level = cv2.blur(capped, k, borderType=cv2.BORDER_REPLICATE) / np.maximum(total, 1e-6)
    return np.maximum(np.where(total > 0, level, 1.0), 1.0).astype(np.float32)


def _napkin_white(samples: _Samples, p: NapkinParams) -> NDArray[np.float64]:
    """The napkin's white, linear RGB (3,): the median of the brightest samples, refined
    twice on the neutral, bright samples under that white (the napkin itself), of which
    the brighter half (the part facing the light) sets the level."""
    bright = samples.r + samples.g + samples.b
    usable = ~samples.clipped
    if np.count_nonzero(usable) < 50:
        usable = np.ones(len(bright), dtype=bool)
    level = quantile(bright[usable], 1.0 - p.bright_fraction)
    top = usable & (bright >= level)
    white = samples.median_of(top)
    for _ in range(2):
        lum, chroma = samples.balanced(white)
        napkin = usable & (lum >= p.min_napkin_brightness) & (chroma <= p.neutral_chroma * lum)
        if np.count_nonzero(napkin) < 20:
            break
        white = samples.median_of(napkin & (lum >= median(lum[napkin])))
    return np.maximum(white, 1e-4)


def _objects(
    raised: NDArray[np.bool_], lum: NDArray, chroma: NDArray, p: NapkinParams
) -> NDArray[np.bool_]:
    """Samples of an object above the table: raised and not napkin-coloured; a few
    isolated samples are depth noise, not an object."""
    import cv2

    if not raised.any():  # (nothing above the table: no object, nothing to open)
        return np.zeros(raised.shape, dtype=bool)
    occluder = raised & _not_napkin(lum, chroma, p)
    opened = np.ones((3, 3), np.uint8)
    occluder = cv2.morphologyEx(occluder.astype(np.uint8), cv2.MORPH_OPEN, opened)
    return occluder.astype(bool)


def _held_up_cloth(
    raised_px: NDArray[np.intp], shape: tuple[int, int], p: NapkinParams
) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """The samples (``shape``) of cloth held up, from its pixels ``raised_px`` (n, 2),
    and which of those pixels they keep (n,).

    A flap seen nearly edge-on is a line a pixel or two wide: every pixel counts for its
    sample (pooling), and connected parts of some size are kept rather than opening the
    mask, which would erase it.
    """
    import cv2

    s = p.stride
    if not len(raised_px):  # (every fold laid flat: nothing held up)
        return np.zeros(shape, dtype=bool), np.zeros(0, dtype=bool)
    held_up = np.zeros(shape, dtype=np.uint8)
    cell = (raised_px[:, 1] // s) * shape[1] + raised_px[:, 0] // s  # (flat: np.put, np.take)
    np.put(held_up, cell, 1)
    _, lab, stats, _ = cv2.connectedComponentsWithStats(held_up, connectivity=8)
    big = np.flatnonzero(stats[:, cv2.CC_STAT_AREA] >= p.min_raised_samples)
    raised_cloth = np.isin(lab, big[big > 0])
    return raised_cloth, np.take(raised_cloth, cell)
