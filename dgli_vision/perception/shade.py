"""The napkin's cloth followed into a soft shadow.

The footprint's cloth cells are the cells brighter than the table (:mod:`.footprint`). A
robot arm's soft shadow across the napkin can leave the shadowed cloth darker than the
lit table, and that part of the napkin is then missing from the footprint: a footprint
measured too small, which makes a state's footprint check speak for the wrong state.

A shadow multiplies the light on cloth and table alike, and its edge is soft (tens of
pixels), while the napkin's outline is a step of the material (one or two pixels), as
large in the shade as in the light. So the cloth is followed from the cells that are
surely lit cloth across small steps of log-luminance only, at half the image's
resolution: the fill crosses a shadow's edge and stops at the outline. It runs only
where a shadow can be at play: when table notably darker than the rest of the table
lies next to the cloth.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ..core.colour import srgb_lut

__all__ = ["ShadeParams", "into_shade"]


@dataclass(frozen=True)
class ShadeParams:
    """How the cloth is followed into a shadow. Every field has a unit and a reason.

    Attributes
    ----------
    dark_table : float
        Largest luminance of a table cell next to the cloth, relative to the median
        cell (the table), that suggests a shadow. Default 0.75: an arm's shadow keeps
        40-65% of the light; a table's own shading varies by a few per cent.
    ring_cells : int
        How far from the cloth (cells) such table is looked for. Default 3.
    step : float
        Largest ratio of the brightest to the darkest value of any colour channel in
        the 3 x 3 half-resolution pixels around a pixel the fill crosses. Default 1.4:
        a soft shadow's edge changes the light by a few per cent per pixel (at most
        about 20% over three); the napkin's outline is a step of a factor 1.7 or more
        between cloth and table in at least one channel (blurred over about two).
    fill_fraction : float
        Least fraction of a cell's pixels the fill must reach for the cell to be cloth.
        Default 0.5.
    """

    dark_table: float = 0.75
    ring_cells: int = 3
    step: float = 1.4
    fill_fraction: float = 0.5


#: Levels of the log-luminance image per unit of natural log: 8-bit sRGB spans about
#: 8.1 units of log light, mapped onto 0-255.
LEVELS_PER_LOG = 31.0


@lru_cache(maxsize=1)
def _log_lut() -> NDArray[np.uint8]:
    """8-bit sRGB level -> quantised log of its linear light (255 at white)."""
    lin = np.maximum(srgb_lut(), srgb_lut()[1] / 2)
    return np.clip(np.rint(255 + LEVELS_PER_LOG * np.log(lin)), 0, 255).astype(np.uint8)


def shadow_suspected(
    cloth: NDArray[np.bool_], lum: NDArray[np.float64], params: ShadeParams | None = None
) -> bool:
    """Whether table notably darker than the median cell lies next to the ``cloth``
    cells (``lum``: every cell's luminance, balanced to the napkin's white)."""
    import cv2

    p = params or ShadeParams()
    side = 2 * p.ring_cells + 1
    ring = cv2.dilate(cloth.view(np.uint8), np.ones((side, side), np.uint8)).view(bool) & ~cloth
    if not ring.any():
        return False
    return bool((lum[ring] < p.dark_table * float(np.median(lum))).any())


def into_shade(
    color: NDArray[np.uint8],
    cloth: NDArray[np.bool_],
    seeds: NDArray[np.bool_],
    cell_px: int,
    close_cells: int,
    params: ShadeParams | None = None,
) -> NDArray[np.bool_]:
    """The ``cloth`` cells with the cloth followed from the ``seeds`` (cells surely lit
    cloth) into shadow; ``cloth`` itself when the fill adds no cell.

    Parameters
    ----------
    color : ndarray of uint8, shape (H, W, 3)
    cloth : ndarray of bool, shape (H // cell_px, W // cell_px)
        The napkin's cells as found by brightness (stickers' holes closed).
    seeds : ndarray of bool, same shape
        Cells whose centre pixel is cloth in the light: the fill starts there.
    cell_px, close_cells : int
        The cells' side (pixels, even) and the closing that fills stickers' holes (cells).
    params : ShadeParams, optional
    """
    import cv2

    p = params or ShadeParams()
    h, w = cloth.shape
    half = cell_px // 2
    filled = _fill(color[: h * cell_px, : w * cell_px], seeds, half, p)
    share = filled.reshape(h, half, w, half).mean(axis=(1, 3), dtype=np.float32)
    new = (share >= p.fill_fraction) & ~cloth
    # cloth in shadow: cells the fill covers whole that were not bright enough (the
    # outline's cells next to a dark object, half cloth, are not: they alone add nothing)
    whole = new & (share >= 1.0)
    if not whole.any():
        return cloth
    _, labels = cv2.connectedComponents(new.view(np.uint8), connectivity=8)
    keep = np.unique(labels[whole])
    grown = cloth | np.isin(labels, keep[keep > 0])
    kernel = np.ones((close_cells, close_cells), np.uint8)
    return cv2.morphologyEx(grown.view(np.uint8), cv2.MORPH_CLOSE, kernel).view(bool) | cloth


def _fill(
    color: NDArray[np.uint8], seeds: NDArray[np.bool_], half: int, p: ShadeParams
) -> NDArray[np.uint8]:
    """The pixels (0/1, half the image's resolution) reached from the centres of the
    ``seeds`` cells (of ``2 half`` pixels) without crossing a material edge."""
    import cv2

    h, w = seeds.shape
    small = cv2.resize(color, (w * half, h * half), interpolation=cv2.INTER_AREA)
    level = cv2.LUT(small, _log_lut())
    spread = cv2.morphologyEx(level, cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8))
    r, g, b = cv2.split(spread)
    edge = cv2.max(cv2.max(r, g), b)
    limit = LEVELS_PER_LOG * float(np.log(p.step))
    barrier = (edge > limit).view(np.uint8)
    mask = np.zeros((h * half + 2, w * half + 2), np.uint8)
    flags = 4 | cv2.FLOODFILL_MASK_ONLY | (1 << 8)
    ys, xs = np.nonzero(seeds)
    px, py = xs * half + half // 2, ys * half + half // 2
    open_ = barrier[py, px] == 0
    px, py = px[open_], py[open_]
    while px.size:
        cv2.floodFill(barrier, mask, (int(px[0]), int(py[0])), 0, 0, 0, flags)
        left = mask[py + 1, px + 1] == 0
        px, py = px[left], py[left]
    # the fill stops a pixel short of the outline on either side: give it back
    return cv2.dilate(mask[1:-1, 1:-1], np.ones((3, 3), np.uint8))
