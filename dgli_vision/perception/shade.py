"""The napkin's cloth followed into a soft shadow.

The footprint's cloth cells are the cells brighter than the table (:mod:`.footprint`). A
robot arm's soft shadow across the napkin can leave the shadowed cloth darker than the
lit table, and that part of the napkin is then missing from the footprint: a footprint
measured too small, which makes a state's footprint check speak for the wrong state.

A shadow multiplies the light on cloth and table alike, and its edge is soft (several
centimetres), while the napkin's outline is a step of the material within a pixel or
two, as large in the shade as in the light. So the cloth is followed, at half the
image's resolution, from the cells that are surely lit cloth through every pixel whose
3 x 3 neighbourhood spans a small ratio of light in each colour channel: the fill
crosses a shadow's edge and stops at the outline. (A fill that compares neighbouring
pixels only runs out along a slanting outline, whose mixed pixels change a little from
one to the next.) A fill that reaches the image border found no outline: the caller
does not take its cells. It runs only where a shadow can be at play: when table notably
darker than the rest of the table lies next to the cloth.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ..core.colour import srgb_lut
from .params import ShadeParams

__all__ = ["ShadeParams", "into_shade", "shadow_suspected"]


#: Levels of the log-luminance image per unit of natural log: 8-bit sRGB spans about
#: 8.1 units of log light, mapped onto 0-255.
_LEVELS_PER_LOG = 31.0


@lru_cache(maxsize=1)
def _log_lut() -> NDArray[np.uint8]:
    """8-bit sRGB level -> quantised log of its linear light (255 at white)."""
    lin = np.maximum(srgb_lut(), srgb_lut()[1] / 2)
    return np.clip(np.rint(255 + _LEVELS_PER_LOG * np.log(lin)), 0, 255).astype(np.uint8)


def shadow_suspected(
    cloth: NDArray[np.bool_],
    lum: NDArray[np.float64],
    chroma: NDArray[np.float64],
    table_lum: float,
    raised: NDArray[np.bool_] | None = None,
    params: ShadeParams | None = None,
) -> bool:
    """Whether table notably darker than the median cell lies next to the ``cloth``
    cells: at least ``params.dark_cells`` cells within ``params.ring_cells`` of it, not
    stickers (by their ``chroma``) nor ``raised`` (objects above the table).

    Parameters
    ----------
    cloth : ndarray of bool, shape (h, w)
        The napkin's cells.
    lum, chroma : ndarray, same shape
        Every cell's luminance and chroma, balanced to the napkin's white.
    table_lum : float
        The table's luminance (the median cell's).
    raised : ndarray of bool, same shape, optional
    params : ShadeParams, optional
    """
    import cv2

    p = params or ShadeParams()
    side = 2 * p.ring_cells + 1
    near = cv2.dilate(cloth.view(np.uint8), np.ones((side, side), np.uint8)).view(bool)
    ring = near & ~cloth & (lum < p.dark_table * table_lum)
    if raised is not None:
        ring &= ~raised
    if np.count_nonzero(ring) < p.dark_cells:
        return False
    table = chroma[ring] <= p.sticker_chroma * lum[ring]
    return int(np.count_nonzero(table)) >= p.dark_cells


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
    if not seeds.any():
        return cloth
    h, w = cloth.shape
    ys, xs = np.nonzero(cloth)
    m = p.margin_cells
    box = (max(ys.min() - m, 0), min(ys.max() + m + 1, h))
    box += (max(xs.min() - m, 0), min(xs.max() + m + 1, w))
    count = _fill_counts(color, seeds, cell_px, box, p)
    if count is None:  # the cloth in shade reaches out of the box: the whole frame
        count = _fill_counts(color, seeds, cell_px, (0, h, 0, w), p)
    full = (cell_px // 2) ** 2
    new = (count >= p.fill_fraction * full) & ~cloth
    # cloth in shadow: cells the fill covers whole that were not bright enough (the
    # outline's cells next to a dark object, half cloth, are not: they alone add nothing)
    whole = new & (count >= full)
    if not whole.any():
        return cloth
    _, labels = cv2.connectedComponents(new.view(np.uint8), connectivity=8)
    keep = np.unique(labels[whole])
    grown = cloth | np.isin(labels, keep[keep > 0])
    kernel = np.ones((close_cells, close_cells), np.uint8)
    return cv2.morphologyEx(grown.view(np.uint8), cv2.MORPH_CLOSE, kernel).view(bool) | cloth


def _fill_counts(
    color: NDArray[np.uint8],
    seeds: NDArray[np.bool_],
    cell_px: int,
    box: tuple[int, int, int, int],
    p: ShadeParams,
) -> NDArray[np.uint8] | None:
    """How many of each cell's half-resolution pixels the fill from the centres of the
    ``seeds`` cells reaches without crossing a material edge, shape ``seeds.shape``;
    the fill is confined to the ``box`` of cells (rows y0:y1, columns x0:x1). None when
    it reaches a side of the box that is not the image's border."""
    import cv2

    y0, y1, x0, x1 = box
    half = cell_px // 2
    hh, ww = (y1 - y0) * half, (x1 - x0) * half
    crop = color[y0 * cell_px : y1 * cell_px, x0 * cell_px : x1 * cell_px]
    level = cv2.LUT(cv2.resize(crop, (ww, hh), interpolation=cv2.INTER_AREA), _log_lut())
    spread = cv2.morphologyEx(level, cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8))
    limit = _LEVELS_PER_LOG * float(np.log(p.step))
    _, over = cv2.threshold(spread, limit, 255, cv2.THRESH_BINARY)
    barrier = cv2.cvtColor(over, cv2.COLOR_RGB2GRAY)  # not 0 where any channel is over
    mask = np.zeros((hh + 2, ww + 2), np.uint8)
    flags = 4 | cv2.FLOODFILL_MASK_ONLY | (1 << 8)
    ys, xs = np.nonzero(seeds[y0:y1, x0:x1])
    px, py = xs * half + half // 2, ys * half + half // 2
    open_ = barrier[py, px] == 0
    px, py = px[open_], py[open_]
    while px.size:
        cv2.floodFill(barrier, mask, (int(px[0]), int(py[0])), 0, 0, 0, flags)
        left = mask[py + 1, px + 1] == 0
        px, py = px[left], py[left]
    h, w = seeds.shape
    inside = mask[1:-1, 1:-1]  # (floodFill marks the mask's own border)
    sides = ((y0 > 0, inside[0]), (y1 < h, inside[-1]))
    sides += ((x0 > 0, inside[:, 0]), (x1 < w, inside[:, -1]))
    if any(cut and side.any() for cut, side in sides):
        return None
    # the fill stops a pixel short of the outline on either side: give it back; each
    # reached pixel counts 1 in its cell's sum (an area average of 0 / cells' pixels)
    reached = cv2.dilate(inside, np.ones((3, 3), np.uint8)) * np.uint8(half * half)
    count = np.zeros((h, w), np.uint8)
    count[y0:y1, x0:x1] = cv2.resize(reached, (x1 - x0, y1 - y0), interpolation=cv2.INTER_AREA)
    return count
