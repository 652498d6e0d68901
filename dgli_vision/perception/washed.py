"""The second search's pieces: stickers a broad sheen washed out to pastel.

A semi-gloss sticker under a large light (a softbox, a window) reflects white light over
its whole disc: its saturation falls to 0.1-0.3 while its hue survives. The detector
(:func:`.detect.find_washed_out`) first looks for pastel samples of a sticker hue on the
napkin (:func:`pale_samples`, cheap); only then does it search again with the pastel
thresholds (:func:`pastel_params`), adds what that finds (:func:`merge_second_search`),
and reports the pastel patches that no search could read (:func:`with_unread`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ..core.layout import NapkinLayout
from .detections import DetectorParams, StickerDetections
from .labels import hue_lut
from .napkin import NapkinView
from .regions import ClothRegions, RegionParams, cloth_cells

__all__ = [
    "PastelLooks",
    "merge_second_search",
    "pale_cells",
    "pale_samples",
    "pastel_params",
    "with_unread",
]


def pastel_params(params: DetectorParams) -> DetectorParams:
    """``params`` with the second search's saturation, chroma and surround."""
    return replace(
        params,
        min_saturation=params.washed_saturation,
        min_chroma=params.washed_chroma,
        min_surround=params.washed_surround,
    )


def pale_samples(
    color: NDArray[np.uint8],
    found: StickerDetections,
    layout: NapkinLayout,
    params: DetectorParams,
    lower: NapkinView,
    colours: dict[str, tuple[int, int, int]] | None,
    *,
    edge_cells: int = 0,
    regions: ClothRegions | None = None,
    looks: PastelLooks | None = None,
) -> tuple[NDArray[np.float64], tuple[str, ...]]:
    """Pixels (x, y), shape (k, 2), and colour names of pastel samples of a sticker hue
    away from the stickers found, on the napkin's sampling grid (``lower.stride``): a
    cheap look before the second search, and what it leaves unread.

    Pastel: HSV saturation from ``washed_saturation`` to below ``min_saturation`` in the
    image balanced by ``lower.lut``, on the napkin and ``edge_cells`` cells in from its
    edge (cells across the edge mix white with the table, and a tinted or wood table is
    pale too); anywhere when the napkin is not told from the table. The rims of the
    stickers found are pastel too (their pixels mix with the cloth), so samples within
    two disc radii of them do not count. ``regions``: the frame's white regions
    (:func:`.regions.cloth_regions`), when already found; ``looks``: what earlier
    looks at the same frame found (:class:`PastelLooks`, of the same ``lower``).
    """
    import cv2

    s = lower.stride
    looks = looks or PastelLooks(color, lower, regions)
    lut, names = hue_lut(layout, params, colours)
    on_napkin = None  # (with nothing found, or the napkin not told from the table: anywhere)
    if found.found.any():
        cloth = looks.cloth(found.centroids)
        if cloth is not None:
            edge = np.ones((2 * edge_cells + 1,) * 2, np.uint8)
            on_napkin = cv2.erode(cloth.astype(np.uint8), edge).astype(bool)
    pale, hsv = looks.pale_cells(lut, params, on_napkin)
    if on_napkin is not None:
        pale &= on_napkin
    ys, xs = np.nonzero(pale)
    pts = (np.column_stack([xs, ys]).astype(np.float64) + 0.5) * s
    sample_names = [names[k - 1] for k in lut[hsv[ys, xs, 0]]]
    if not len(pts) or not found.found.any():
        return pts, tuple(sample_names)
    radius = float(np.sqrt(np.nanmedian(found.areas[found.found]) / np.pi))
    seen = found.centroids[found.found]
    far = np.linalg.norm(pts[:, None] - seen[None], axis=2).min(axis=1) >= 2 * radius
    return pts[far], tuple(n for n, f in zip(sample_names, far) if f)


def pale_cells(
    color: NDArray[np.uint8],
    lut: NDArray[np.uint8],
    params: DetectorParams,
    lower: NapkinView,
    *,
    within: NDArray[np.bool_] | None = None,
) -> tuple[NDArray[np.bool_], NDArray[np.uint8]]:
    """Pastel cells of a sticker hue, not next to vivid ones, shape (H // s, W // s) for
    cells of s = ``lower.stride`` pixels averaged (a sensor's noise tints single pixels,
    not cells); and the cells' HSV once balanced by ``lower.lut``.

    ``within`` (bool, that shape): the cells that matter; only the box around them that
    their test reads (:data:`_VIVID_REACH` cells more) is computed, the other cells are
    not pastel and their HSV is 0. Default: every cell.
    """
    return _pale_cells_in(color, lut, params, lower, _cells_box(color, lower.stride, within))


def _cells_box(
    color: NDArray[np.uint8], s: int, within: NDArray[np.bool_] | None
) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1): the cells (of ``s`` pixels) :func:`pale_cells` computes for
    the cells ``within`` (all of them for None): their box and :data:`_VIVID_REACH`
    cells more; empty when ``within`` holds none."""
    import cv2

    h, w = color.shape[0] // s, color.shape[1] // s
    if within is None:
        return 0, 0, w, h
    if not within.any():
        return 0, 0, 0, 0
    bx, by, bw, bh = cv2.boundingRect(within.astype(np.uint8))
    m = _VIVID_REACH
    return max(bx - m, 0), max(by - m, 0), min(bx + bw + m, w), min(by + bh + m, h)


def _pale_cells_in(
    color: NDArray[np.uint8],
    lut: NDArray[np.uint8],
    params: DetectorParams,
    lower: NapkinView,
    box: tuple[int, int, int, int],
    averaged: NDArray[np.uint8] | None = None,
) -> tuple[NDArray[np.bool_], NDArray[np.uint8]]:
    """:func:`pale_cells` of the cells in ``box`` (x0, y0, x1, y1); elsewhere not
    pastel, HSV 0. ``averaged``: the frame's cells already averaged (RGB, shape
    (H // s, W // s, 3), ``ClothRegions.cells``), else they are averaged here."""
    import cv2

    s = lower.stride
    h, w = color.shape[0] // s, color.shape[1] // s
    x0, y0, x1, y1 = box
    pale, hsv = np.zeros((h, w), bool), np.zeros((h, w, 3), np.uint8)
    if x1 > x0 and y1 > y0:
        if averaged is not None and averaged.shape == (h, w, 3):
            cells = averaged[y0:y1, x0:x1]
        else:  # (cells are averaged independently: any box of whole cells gives its own)
            cells = cv2.resize(
                color[y0 * s : y1 * s, x0 * s : x1 * s], (x1 - x0, y1 - y0),
                interpolation=cv2.INTER_AREA,
            )
        pale[y0:y1, x0:x1], hsv[y0:y1, x0:x1] = _pale_in(cells, lut, params, lower.lut)
    return pale, hsv


class PastelLooks:
    """What the looks for pastel patches at one frame (:func:`pale_samples`) share:
    the napkin's cells for each set of stickers found, and the pastel cells computed
    so far (a box of them; a later look within it reads them, as computing them again
    gives the same cells). The cells are averaged once, by :func:`.regions.cloth_regions`
    (``ClothRegions.cells``), when ``regions`` keeps them.

    Parameters
    ----------
    color : ndarray of uint8, shape (H, W, 3)
    lower : NapkinView
        The napkin balanced to the low level (its ``stride`` is the cell size).
    regions : ClothRegions, optional
        The frame's white regions, when already found.
    """

    def __init__(
        self, color: NDArray[np.uint8], lower: NapkinView, regions: ClothRegions | None
    ) -> None:
        self.color, self.lower, self.regions = color, lower, regions
        self._cloth: dict[bytes, NDArray[np.bool_] | None] = {}
        self._cells: tuple[tuple, tuple[int, int, int, int], NDArray, NDArray] | None = None

    def cloth(self, sticker_px: NDArray[np.float64]) -> NDArray[np.bool_] | None:
        """:func:`.regions.cloth_cells` of the stickers at ``sticker_px`` (n, 2)."""
        key = np.ascontiguousarray(sticker_px, dtype=np.float64).tobytes()
        if key not in self._cloth:
            grid = RegionParams(cell_px=self.lower.stride)
            self._cloth[key] = cloth_cells(
                self.color, self.lower, sticker_px, grid, regions=self.regions
            )
        return self._cloth[key]

    def pale_cells(
        self, lut: NDArray[np.uint8], params: DetectorParams,
        within: NDArray[np.bool_] | None,
    ) -> tuple[NDArray[np.bool_], NDArray[np.uint8]]:
        """:func:`pale_cells` (the pastel cells a copy: the caller's to change)."""
        box = _cells_box(self.color, self.lower.stride, within)
        key = (lut.tobytes(), params)
        if self._cells is None or self._cells[0] != key or not _holds(self._cells[1], box):
            averaged = None
            if self.regions is not None and self.regions.cell_px == self.lower.stride:
                averaged = self.regions.cells
            self._cells = (
                key, box, *_pale_cells_in(self.color, lut, params, self.lower, box, averaged)
            )
        return self._cells[2].copy(), self._cells[3]


def _holds(outer: tuple[int, int, int, int], inner: tuple[int, int, int, int]) -> bool:
    """Whether box ``inner`` (x0, y0, x1, y1) lies within box ``outer`` (or is empty)."""
    if inner[2] <= inner[0] or inner[3] <= inner[1]:
        return True
    return (
        outer[0] <= inner[0] and outer[1] <= inner[1]
        and inner[2] <= outer[2] and inner[3] <= outer[3]
    )


#: How far (cells) a vivid cell makes the pastel cells around it a sticker's rim.
_VIVID_REACH = 2


def _pale_in(
    sub: NDArray[np.uint8],
    lut: NDArray[np.uint8],
    params: DetectorParams,
    balance: NDArray[np.uint8],
) -> tuple[NDArray[np.bool_], NDArray[np.uint8]]:
    """:func:`pale_cells` of averaged cells ``sub`` (RGB, shape (h, w, 3)); the test of
    a cell reads the cells within :data:`_VIVID_REACH` of it."""
    import cv2

    hsv = cv2.cvtColor(cv2.LUT(sub, balance), cv2.COLOR_RGB2HSV)
    pale = cv2.inRange(
        hsv,
        (0, params.washed_saturation, params.min_value),
        (180, max(params.min_saturation - 1, 0), 255),
    ).astype(bool)
    sticker_hue = lut[np.minimum(hsv[..., 0], 179)] > 0
    pale &= sticker_hue
    # a sheen washes whole discs: pale cells next to vivid ones are the rim of a sticker
    # partly under a flap, not a washed-out one
    vivid = cv2.inRange(hsv, (0, params.min_saturation, params.min_value), (180, 255, 255))
    reach = np.ones((2 * _VIVID_REACH + 1,) * 2, np.uint8)
    vivid = cv2.dilate(vivid & sticker_hue.astype(np.uint8) * 255, reach)
    pale &= vivid == 0
    return pale, hsv


def merge_second_search(found: StickerDetections, again: StickerDetections) -> StickerDetections:
    """``found`` with the stickers it lacks that ``again`` found, away from the stickers
    found (a disc's distance); their scores halved, so that a person reading them sees
    which they are. The rejections stay ``found``'s."""
    new = ~found.found & again.found
    if not new.any():
        return found
    seen = found.centroids[found.found]
    if len(seen):
        d_px = np.linalg.norm(again.centroids[:, None] - seen[None], axis=2).min(axis=1)
        radius = np.sqrt(np.where(again.found, again.areas, 0.0) / np.pi)
        new &= ~(d_px < 2 * radius)
    n = len(found.centroids)
    keys = ("centroids", "areas", "scores", "depth_mm", "foreshortening")
    out = {
        k: np.array(getattr(found, k) if getattr(found, k) is not None else np.ones(n))
        for k in keys
    }
    for k in keys:
        if getattr(again, k) is not None:
            out[k][new] = getattr(again, k)[new]
    out["scores"][new] *= 0.5
    return StickerDetections(
        out["centroids"], out["areas"], out["scores"], out["depth_mm"], found.rejected,
        out["foreshortening"],
    )


def with_unread(
    color: NDArray[np.uint8],
    found: StickerDetections,
    layout: NapkinLayout,
    params: DetectorParams,
    lower: NapkinView,
    colours: dict[str, tuple[int, int, int]] | None,
    *,
    regions: ClothRegions | None = None,
    looks: PastelLooks | None = None,
) -> StickerDetections:
    """``found`` with the pastel patches on the napkin that no search could read
    (``pale_px``, ``pale_colours``). ``regions`` and ``looks`` as for
    :func:`pale_samples`."""
    left = pale_samples(
        color, found, layout, params, lower, colours, edge_cells=1, regions=regions,
        looks=looks,
    )
    return _washed(found, left, lower.stride)


def _washed(
    found: StickerDetections, left: tuple[NDArray, tuple[str, ...]], stride: int
) -> StickerDetections:
    """``found`` with the pastel samples left unread, and the colours of those that clump
    like a sticker: a connected patch (on the sampling grid of ``stride`` pixels) of at
    least a third of a sticker's area (that of the stickers found; 3 samples at least).
    Sensor noise in a dim image tints single samples, never a patch."""
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
