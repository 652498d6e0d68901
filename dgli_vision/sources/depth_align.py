"""Depth aligned to colour as the RealSense SDK aligns it (``rs.align``), in numpy.

The SDK's alignment of a depth frame to the colour stream (its SSE ``image_transform``,
what the x86-64 wheels run) takes every depth pixel with a reading, maps the top-left
corner ``(u - 0.5, v - 0.5)`` of the pixel to 3-D at its depth, moves it by the
depth-to-colour extrinsics and projects it into the colour image, in single precision;
``p + 0.5`` truncated is the colour pixel. Where colour has more pixels per degree than
depth it does the same with the bottom-right corner ``(u + 0.5, v + 0.5)`` and fills the
rectangle between them, else it writes that one pixel; it keeps the nearest depth where
pixels meet, clips at the image's edges, and leaves 0 (no depth) where none lands.
Matched here bit for bit (tests/test_depth_align.py: every pixel of every frame, depth at
half the colour resolution, at the same resolution, 15 mm to the side and turned).

:class:`DepthToColour` does the same, vectorised. When the two streams share their
centre of projection, where a corner lands does not depend on its depth, but for the
rounding of ``(x z) / z`` in single precision, which moves a corner by about 1e-4 pixel:
unless a corner lands that close to a truncation boundary, the rectangles are worked out
once per recording, and aligning a frame is a few gathers (:attr:`DepthToColour.fast`;
when the streams differ only in their intrinsics, rows then columns: 1.4 ms a 1280 x 720
frame from 640 x 360, against about 4-7 for ``rs.align``). Otherwise the corners near a
boundary are worked out at their pixels' depths, and where one differs (a depth camera
to the side, or depth at colour's resolution, every corner at a tie) the whole frame is
aligned pixel by pixel (``np.minimum.at``; 30-100 ms a frame, which is why a playback
leaves those to the SDK).

Streams read: without lens distortion (every D400's depth stream; a colour stream whose
coefficients are all zero, as a D435's are). Others are aligned by the SDK
(:attr:`DepthToColour.supported` is False).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

__all__ = ["DepthToColour", "StreamCamera"]

#: Lens models whose zero coefficients mean no distortion (the SDK's names).
_PLAIN_MODELS = frozenset(
    {"none", "brown_conrady", "inverse_brown_conrady", "modified_brown_conrady"}
)


#: No rotation between the streams (the SDK's column-major 3 x 3).
_IDENTITY = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)


@dataclass(frozen=True)
class StreamCamera:
    """A RealSense stream's intrinsics as the SDK gives them (``rs.intrinsics``).

    Attributes
    ----------
    width, height : int
    fx, fy, ppx, ppy : float
    model : str
        The distortion model's SDK name (``"brown_conrady"``, ``"none"``...).
    coeffs : tuple of float
        Its five coefficients.
    """

    width: int
    height: int
    fx: float
    fy: float
    ppx: float
    ppy: float
    model: str = "none"
    coeffs: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0)

    @property
    def distorted(self) -> bool:
        """Its coefficients are not all zero."""
        return any(abs(c) > 0.0 for c in self.coeffs)


@dataclass(frozen=True)
class DepthToColour:
    """What aligning a depth stream to a colour stream needs.

    Attributes
    ----------
    depth, colour : StreamCamera
    rotation : tuple of 9 float
        Depth to colour, column-major as the SDK's ``rs.extrinsics`` holds it.
    translation : tuple of 3 float
        Metres.
    scale_m : float
        Metres per depth unit.
    """

    depth: StreamCamera
    colour: StreamCamera
    rotation: tuple[float, ...]
    translation: tuple[float, float, float]
    scale_m: float

    @property
    def supported(self) -> bool:
        """The lens models are ones :meth:`align` reads (otherwise the SDK aligns)."""
        d, c = self.depth, self.colour
        depth_ok = d.model in _PLAIN_MODELS and not d.distorted
        colour_ok = c.model in _PLAIN_MODELS and not c.distorted
        return depth_ok and colour_ok

    @property
    def fixed(self) -> bool:
        """Where a depth pixel lands does not depend on its depth (no translation)."""
        return not any(self.translation)

    @property
    def fast(self) -> bool:
        """Aligned by precomputed gathers, every frame (1.4 ms a 1280 x 720 frame from
        640 x 360): the streams share their centre of projection and no corner lands
        near a rounding tie (where the SDK's rounding depends on each pixel's depth and
        the frame is aligned pixel by pixel, 30-100 ms)."""
        return self.supported and self.fixed and _at_risk(self) is None

    def align(self, raw: NDArray[np.uint16]) -> NDArray[np.uint16]:
        """The depth frame ``raw`` (the depth stream's size, its own units) aligned to
        the colour stream: the colour stream's size, the same units, 0 where no depth
        pixel lands.

        Raises
        ------
        ValueError
            ``raw`` is not the depth stream's size, or the lens models are not read.
        """
        d, c = self.depth, self.colour
        if raw.shape != (d.height, d.width):
            raise ValueError(
                f"depth frame is {raw.shape[1]}x{raw.shape[0]}, its stream {d.width}x{d.height}"
            )
        if not self.supported:
            raise ValueError("lens model not read: align with the SDK")
        if self.fixed:
            risky = _at_risk(self)
            near = raw.ravel()[risky] if risky is not None else None
            if near is None or not near.any() or _as_at_unit_depth(self, raw, risky):
                if self.rotation == _IDENTITY:
                    return _separable_min(raw, *_separable_sources(self))
                return _gather_min(raw, _fixed_sources(self), (c.height, c.width))
        return _scatter_min(self, raw, _frame_corners(self, raw))


def _corner_rays(cal: DepthToColour) -> tuple[NDArray[np.float32], ...]:
    """The rays through every depth pixel's top-left and bottom-right corners, in the
    depth camera at unit depth, float32 as the SDK precomputes them: x0 and x1 as row
    vectors (1, W), y0 and y1 as column vectors (H, 1)."""
    d = cal.depth
    f32 = np.float32
    u = np.arange(d.width, dtype=f32)[None, :]
    v = np.arange(d.height, dtype=f32)[:, None]
    half = f32(0.5)
    x0 = (u - half - f32(d.ppx)) / f32(d.fx)
    x1 = (u + half - f32(d.ppx)) / f32(d.fx)
    y0 = (v - half - f32(d.ppy)) / f32(d.fy)
    y1 = (v + half - f32(d.ppy)) / f32(d.fy)
    return x0, y0, x1, y1


def _fov_pixels(cam: StreamCamera) -> tuple[np.float32, np.float32]:
    """Pixels per degree across and down (the SDK's ``rs2_fov``, in single precision)."""
    f32 = np.float32
    out = []
    for size, pp, f in ((cam.width, cam.ppx, cam.fx), (cam.height, cam.ppy, cam.fy)):
        a = f32(pp) + f32(0.5)
        fov = (np.arctan2(a, f32(f)) + np.arctan2(f32(size) - a, f32(f))) * f32(57.2957795)
        out.append(f32(size) / fov)
    return out[0], out[1]


def _both_corners(cal: DepthToColour) -> bool:
    """Whether the SDK fills each depth pixel's rectangle from corner to corner (colour
    has more pixels per degree than depth, or two special sizes) or writes one pixel
    where the top-left corner lands."""
    d, c = cal.depth, cal.colour
    dx, dy = _fov_pixels(d)
    cx, cy = _fov_pixels(c)
    special = ((d.width, d.height), (c.width, c.height)) in (
        ((640, 240), (320, 180)), ((640, 480), (640, 360))
    )
    return bool(dx < cx or dy < cy or special)


def _project(
    cal: DepthToColour, x: NDArray, y: NDArray, z: NDArray | np.float32, *, exact: bool = False
) -> tuple[NDArray, NDArray]:
    """Colour pixels of the depth-camera points ``(x z, y z, z)``, computed as the SDK's
    SSE alignment computes them (its order of operations in single precision), then
    ``p + 0.5`` truncated (what the SDK 2.59 wheel gives, measured: its 1:1 alignment's
    holes and its 2:1 overlaps are those of truncation, not of rounding)."""
    r = [np.float32(v) for v in cal.rotation]
    t = [np.float32(v) for v in cal.translation]
    px, py = z * x, z * y
    qx = r[0] * px + (r[3] * py + (r[6] * z + t[0]))
    qy = r[1] * px + (r[4] * py + (r[7] * z + t[1]))
    qz = r[2] * px + (r[5] * py + (r[8] * z + t[2]))
    nx, ny = qx / qz, qy / qz
    c = cal.colour
    half = np.float32(0.5)
    col = (nx * np.float32(c.fx) + np.float32(c.ppx)) + half
    row = (ny * np.float32(c.fy) + np.float32(c.ppy)) + half
    if exact:  # before the truncation
        return col, row
    return col.astype(np.int32), row.astype(np.int32)  # truncated toward zero


@dataclass(frozen=True, eq=False)
class _Corners:
    """Where a frame's depth pixels with a reading land: their flat indices, readings
    and the colour rectangles (c0, r0) - (c1, r1), unclipped."""

    index: NDArray[np.intp]
    values: NDArray[np.uint16]
    c0: NDArray[np.int32]
    r0: NDArray[np.int32]
    c1: NDArray[np.int32]
    r1: NDArray[np.int32]


def _frame_corners(cal: DepthToColour, raw: NDArray[np.uint16]) -> _Corners:
    """Every depth pixel's rectangle at its own depth (as the SDK computes it)."""
    x0, y0, x1, y1 = _corner_rays(cal)
    index = np.flatnonzero(raw)
    v, u = np.divmod(index, raw.shape[1])
    values = raw.ravel()[index]
    z = values.astype(np.float32) * np.float32(cal.scale_m)
    c0, r0 = _project(cal, x0[0, u], y0[v, 0], z)
    if _both_corners(cal):
        c1, r1 = _project(cal, x1[0, u], y1[v, 0], z)
    else:
        c1, r1 = c0, r0
    return _Corners(index, values, c0, r0, c1, r1)


@lru_cache(maxsize=4)
def _unit_corners(cal: DepthToColour) -> tuple[NDArray[np.int32], ...]:
    """Every depth pixel's rectangle (c0, r0, c1, r1, flat over the depth image) at 1 m:
    where it lands at any depth when the streams share their centre of projection, but
    for the rounding of a corner at a tie (checked frame by frame)."""
    x0, y0, x1, y1 = _corner_rays(cal)
    full = np.ones((cal.depth.height, cal.depth.width), np.float32)
    one = np.float32(1.0)
    c0, r0 = _project(cal, x0 * full, y0 * full, one)
    if _both_corners(cal):
        c1, r1 = _project(cal, x1 * full, y1 * full, one)
    else:
        c1, r1 = c0, r0
    return c0.ravel(), r0.ravel(), c1.ravel(), r1.ravel()


#: A corner landing within this many colour pixels of a whole number (where ``p + 0.5``
#: is truncated) at 1 m may land on the other side at another depth: single precision
#: moves ``(x z) / z`` by about 1e-7 of itself, 1e-4 pixel across a 1280-pixel image.
_TIE_PX = 1e-3


@lru_cache(maxsize=4)
def _at_risk(cal: DepthToColour) -> NDArray[np.intp] | None:
    """For streams sharing their centre of projection: the depth pixels (flat indices)
    one of whose corners lands within :data:`_TIE_PX` of a truncation boundary at 1 m,
    whose rectangle may then depend on their depth (the SDK computes it at that depth);
    None when there are none (a 640 x 360 stream under 1280 x 720: every corner half a
    pixel from one)."""
    x0, y0, x1, y1 = _corner_rays(cal)
    full = np.ones((cal.depth.height, cal.depth.width), np.float32)
    one = np.float32(1.0)
    risky = np.zeros(full.shape, bool)
    corners = [(x0, y0), (x1, y1)] if _both_corners(cal) else [(x0, y0)]
    for x, y in corners:
        for p in _project(cal, x * full, y * full, one, exact=True):
            risky |= np.abs(p - np.rint(p)) < _TIE_PX
    found = np.flatnonzero(risky)
    return found if len(found) else None


def _as_at_unit_depth(
    cal: DepthToColour, raw: NDArray[np.uint16], risky: NDArray[np.intp]
) -> bool:
    """The frame's rectangles at its own depths are those at 1 m, checked where they may
    not be (``risky`` pixels with a reading): the precomputed gathers then give the
    SDK's answer exactly."""
    x0, y0, x1, y1 = _corner_rays(cal)
    index = risky[raw.ravel()[risky] > 0]
    v, u = np.divmod(index, raw.shape[1])
    z = raw.ravel()[index].astype(np.float32) * np.float32(cal.scale_m)
    unit = _unit_corners(cal)
    got = list(_project(cal, x0[0, u], y0[v, 0], z))
    got += list(_project(cal, x1[0, u], y1[v, 0], z)) if _both_corners(cal) else got
    return all(np.array_equal(a, b[index]) for a, b in zip(got, unit))


@lru_cache(maxsize=4)
def _fixed_sources(cal: DepthToColour) -> NDArray[np.intp]:
    """For streams sharing their centre of projection: for every colour pixel, the depth
    pixels whose rectangle (clipped to the image) covers it, shape (K, H*W); a depth
    pixel's index, or the index one past the last (a zero appended to the frame) where
    fewer than K cover it."""
    d, c = cal.depth, cal.colour
    c0, r0, c1, r1 = _unit_corners(cal)
    src = np.arange(d.width * d.height)
    targets, sources = [], []
    for dy in range(int((r1 - r0).max(initial=-1)) + 1):
        for dx in range(int((c1 - c0).max(initial=-1)) + 1):
            col, row = c0 + dx, r0 + dy
            ok = (row <= r1) & (col <= c1) & (col >= 0) & (row >= 0)
            ok &= (col < c.width) & (row < c.height)
            targets.append(row[ok] * c.width + col[ok])
            sources.append(src[ok])
    none = d.width * d.height  # the zero appended to each frame
    target = np.concatenate(targets) if targets else np.zeros(0, np.intp)
    if not len(target):
        return np.full((1, c.width * c.height), none, np.intp)
    source = np.concatenate(sources)
    order = np.argsort(target, kind="stable")
    target, source = target[order], source[order]
    first = np.searchsorted(target, target, side="left")
    rank = np.arange(len(target)) - first  # which of the pixel's covering depth pixels
    out = np.full((int(rank.max()) + 1, c.width * c.height), none, np.intp)
    out[rank, target] = source
    return out


def _covering(lo: NDArray[np.int32], hi: NDArray[np.int32], size: int) -> NDArray[np.intp]:
    """For each of ``size`` colour columns (or rows), the depth columns (rows) whose
    span ``lo..hi`` (clipped to the image) covers it, shape (K, size); ``len(lo)`` (a
    sentinel) where fewer than K do."""
    cover: list[list[int]] = [[] for _ in range(size)]
    for k in range(len(lo)):
        for c in range(max(int(lo[k]), 0), min(int(hi[k]), size - 1) + 1):
            cover[c].append(k)
    width = max(1, max(len(c) for c in cover))
    out = np.full((width, size), len(lo), np.intp)
    for c, found in enumerate(cover):
        out[: len(found), c] = found
    return out


@lru_cache(maxsize=4)
def _separable_sources(cal: DepthToColour) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """For streams that differ only in their intrinsics (no rotation, no translation, no
    distortion): a depth column lands on colour columns that depend on it alone, a row
    on rows: the depth rows covering each colour row, (K, H), and the depth columns
    covering each colour column, (K, W) (:func:`_covering`)."""
    d, c = cal.depth, cal.colour
    c0, r0, c1, r1 = (a.reshape(d.height, d.width) for a in _unit_corners(cal))
    return (
        _covering(r0[:, 0], r1[:, 0], c.height),
        _covering(c0[0], c1[0], c.width),
    )


def _separable_min(
    raw: NDArray[np.uint16], rows: NDArray[np.intp], cols: NDArray[np.intp]
) -> NDArray[np.uint16]:
    """:func:`_gather_min` for separable streams: the nearest reading over each colour
    row's depth rows, then over each colour column's depth columns."""
    h, w = raw.shape
    ext = np.full((h + 1, w + 1), 65535, np.uint16)  # a last row and column of "none"
    np.subtract(raw, 1, out=ext[:h, :w], casting="unsafe")  # 0 -> 65535
    by_row = np.take(ext, rows[0], axis=0)
    for k in range(1, len(rows)):
        np.minimum(by_row, np.take(ext, rows[k], axis=0), out=by_row)
    best = np.take(by_row, cols[0], axis=1)
    for k in range(1, len(cols)):
        np.minimum(best, np.take(by_row, cols[k], axis=1), out=best)
    best += 1  # 65535 (no reading) -> 0
    return best


def _gather_min(
    raw: NDArray[np.uint16], sources: NDArray[np.intp], shape: tuple[int, int]
) -> NDArray[np.uint16]:
    """The nearest reading among each colour pixel's depth pixels (0 where none has one):
    readings shifted down by one, so that 0 (none) wraps to the largest value."""
    flat = np.empty(raw.size + 1, np.uint16)
    np.subtract(raw.ravel(), 1, out=flat[:-1], casting="unsafe")  # 0 -> 65535
    flat[-1] = 65535
    best = np.take(flat, sources[0])  # (np.take: half the time of flat[sources[0]])
    more = np.empty_like(best)
    for k in range(1, len(sources)):
        np.minimum(best, np.take(flat, sources[k], out=more), out=best)
    best += 1  # 65535 (no reading) -> 0
    return best.reshape(shape)


def _scatter_min(
    cal: DepthToColour, raw: NDArray[np.uint16], corners: _Corners
) -> NDArray[np.uint16]:
    """A frame aligned from its own rectangles (clipped to the image), the nearest
    reading kept."""
    c = cal.colour
    k = corners
    values = k.values - np.uint16(1)  # no 0 here; 0 (no reading) is 65535 below
    out = np.full(c.width * c.height, 65535, np.uint16)
    for dy in range(int((k.r1 - k.r0).max(initial=-1)) + 1):
        for dx in range(int((k.c1 - k.c0).max(initial=-1)) + 1):
            col, row = k.c0 + dx, k.r0 + dy
            ok = (row <= k.r1) & (col <= k.c1) & (col >= 0) & (row >= 0)
            ok &= (col < c.width) & (row < c.height)
            np.minimum.at(out, row[ok] * c.width + col[ok], values[ok])
    out += 1  # 65535 (no reading) -> 0
    return out.reshape(c.height, c.width)
