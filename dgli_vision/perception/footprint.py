"""How much of the table the cloth covers: the napkin's footprint, in mm^2.

Folding never stretches cloth, and every fold changes how much table the napkin covers:
a flat napkin covers all of its area, a corner fold 86-93% of it, four corners or a half
fold about half. The footprint is measured from colour (the napkin is white, the table
much darker once balanced to the napkin's white) and the table plane (each image cell's
area on the table, from the ray through it), so it needs no depth on the cloth itself.

The footprint is an interval: cloth hidden from the camera by an object above the
napkin (a gripper) may or may not be there, so the cells of such objects next to the
cloth widen it. It is ``None`` (not measured) where the cloth region cannot be told from
the table: it reaches the image border, or it measures more than the whole napkin can
cover (a table as bright as the napkin).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ..core.camera import Intrinsics
from .napkin import NapkinParams, NapkinView
from .params import FootprintParams, ShadeParams
from .regions import (
    MAX_BORDER_CELLS,
    ClothRegions,
    any_of,
    border_cells,
    cloth_cells,
    cloth_regions,
)
from .shade import into_shade, shadow_suspected

# (ClothRegions, cloth_cells and cloth_regions are found in stage 1, :mod:`.regions`;
# named here too, where they were first)
__all__ = [
    "ClothRegions",
    "Footprint",
    "FootprintParams",
    "cloth_cells",
    "cloth_regions",
    "measure_footprint",
]


@dataclass(frozen=True)
class Footprint:
    """The table area the napkin covers, as measured.

    Attributes
    ----------
    low_mm2, high_mm2 : float
        The area of the cloth seen, and that plus the area of objects above the napkin
        that may hide more of it, mm^2.
    cells : ndarray of bool, optional
        The napkin's cloth cells measured (the cloth in an arm's shadow included when
        followed there), on the grid of ``FootprintParams.cell_px``.
    """

    low_mm2: float
    high_mm2: float
    cells: NDArray[np.bool_] | None = field(default=None, compare=False, repr=False)

    def fraction(self, napkin_area_mm2: float) -> tuple[float, float]:
        """The interval as fractions of the napkin's area."""
        return self.low_mm2 / napkin_area_mm2, self.high_mm2 / napkin_area_mm2


def _table_area_mm2(
    intrinsics: Intrinsics, cells: NDArray[np.bool_], cell: int, up: NDArray, offset_m: float
) -> float:
    """Area on the table plane (mm^2) of the image ``cells`` (a mask on the grid of
    ``cell``-pixel cells).

    A pixel's ray ``d = ((u - cx) / fx, (v - cy) / fy, 1)`` meets the plane
    ``up . x = offset`` at ``offset d / (up . d)``, and the area that maps to an image
    area ``dA`` there is ``offset^2 dA / (fx fy |up . d|^3)`` (the Jacobian of the
    central projection onto a plane): evaluated at each cell's centre, only for the
    cells asked. Through a lens's distortion, each cell's corners are traced instead.
    """
    if intrinsics.distorted:  # traced for the cells' bounding box only
        rows, cols = np.flatnonzero(cells.any(axis=1)), np.flatnonzero(cells.any(axis=0))
        if not len(rows):
            return 0.0
        y0, y1, x0, x1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
        areas = _cell_areas_mm2(
            intrinsics, (y1 - y0, x1 - x0), cell, up, offset_m, origin=(y0, x0)
        )
        return float(areas[cells[y0:y1, x0:x1]].sum())
    # each cell's cosine from its column's and its row's terms (the same sums, cell by
    # cell), taken in row-major order as np.nonzero gives the cells
    h, w = cells.shape
    dx = (np.arange(w) * cell + (cell / 2 - 0.5) - intrinsics.cx) / intrinsics.fx
    dy = (np.arange(h) * cell + (cell / 2 - 0.5) - intrinsics.cy) / intrinsics.fy
    ys, xs = np.nonzero(cells)  # (the cells asked only, not the whole grid)
    cos = np.abs((up[0] * dx)[xs] + (up[1] * dy)[ys] + up[2])
    scale = offset_m**2 * cell * cell / (intrinsics.fx * intrinsics.fy) * 1e6
    return float(scale * np.sum(cos**-3.0))


def _cell_areas_mm2(
    intrinsics: Intrinsics,
    shape: tuple[int, int],
    cell: int,
    up: NDArray,
    offset_m: float,
    origin: tuple[int, int] = (0, 0),
) -> NDArray[np.float64]:
    """Area on the table plane (mm^2) of every image cell, shape ``shape``, from the
    points where the rays through each cell's corners meet the plane (through the
    lens's distortion, when the intrinsics carry it); ``origin``: the cell (row,
    column) of the first, for a block of the grid."""
    h, w = shape
    y0, x0 = origin
    ys, xs = np.mgrid[y0 : y0 + h + 1, x0 : x0 + w + 1] * cell - 0.5
    if intrinsics.distorted:  # the rays of the pixels as the lens bent them
        grid = _ideal_corners(intrinsics, cell)
        if grid is not None and y0 + h < grid.shape[1] and x0 + w < grid.shape[2]:
            xs, ys = grid[:, y0 : y0 + h + 1, x0 : x0 + w + 1]
        else:
            ideal = intrinsics.undistort_pixels(np.column_stack([xs.ravel(), ys.ravel()]))
            xs, ys = ideal[:, 0].reshape(xs.shape), ideal[:, 1].reshape(ys.shape)
    d = np.stack(
        [
            (xs - intrinsics.cx) / intrinsics.fx,
            (ys - intrinsics.cy) / intrinsics.fy,
            np.ones(xs.shape),
        ],
        axis=-1,
    )  # (h + 1, w + 1, 3)
    x = offset_m * d / (d @ up)[..., None]
    ex = x[:-1, 1:] - x[:-1, :-1]
    ey = x[1:, :-1] - x[:-1, :-1]
    return np.linalg.norm(np.cross(ex, ey), axis=-1) * 1e6


def _ideal_corners(intrinsics: Intrinsics, cell: int) -> NDArray[np.float64] | None:
    """The undistorted pixels (x, y) of the corners of every ``cell``-pixel cell of the
    camera's image, shape (2, H // cell + 1, W // cell + 1), made once per camera (each
    pixel is undistorted on its own: a block of the grid is what undistorting the
    block gives); None for a camera that cannot be a cache key."""
    try:
        return _camera_corners(intrinsics, cell)
    except TypeError:  # unhashable intrinsics (a list of coefficients)
        return None


@lru_cache(maxsize=4)
def _camera_corners(intrinsics: Intrinsics, cell: int) -> NDArray[np.float64]:
    """:func:`_ideal_corners`, kept for the last few cameras."""
    ys, xs = np.mgrid[0 : intrinsics.height // cell + 1, 0 : intrinsics.width // cell + 1]
    ys, xs = ys * cell - 0.5, xs * cell - 0.5
    ideal = intrinsics.undistort_pixels(np.column_stack([xs.ravel(), ys.ravel()]))
    grid = ideal.T.reshape(2, *xs.shape).copy()
    grid.flags.writeable = False
    return grid


def _in_shade(
    color: NDArray[np.uint8],
    cloth: NDArray[np.bool_],
    regions: ClothRegions,
    raised: NDArray[np.bool_] | None,
    p: FootprintParams,
    shade: ShadeParams | None = None,
) -> NDArray[np.bool_] | None:
    """The napkin's ``cloth`` cells with its cloth in an arm's shadow (:mod:`.shade`)
    added, when table in shadow lies next to them (``raised``: the cells of objects
    above the table, not table); None when there is none to add."""
    import cv2

    if regions.lum is None or regions.lit is None or regions.chroma is None:
        return None
    if not shadow_suspected(
        cloth, regions.lum, regions.chroma, regions.table_lum, raised, shade
    ):
        return None
    lit = regions.lit & cloth
    seeds = cv2.erode(lit.view(np.uint8), np.ones((3, 3), np.uint8)).view(bool)
    grown = into_shade(color, cloth, seeds, p.cell_px, p.close_cells, shade)
    return None if grown is cloth else grown


def measure_footprint(
    color: NDArray[np.uint8],
    intrinsics: Intrinsics,
    up: NDArray[np.float64],
    offset_m: float,
    napkin: NapkinView,
    sticker_px: NDArray[np.float64],
    napkin_area_mm2: float,
    params: FootprintParams | None = None,
    napkin_params: NapkinParams | None = None,
    *,
    regions: ClothRegions | None = None,
    shade: ShadeParams | None = None,
) -> Footprint | None:
    """The napkin's footprint on the table, or None when it cannot be measured.

    Parameters
    ----------
    color : ndarray of uint8, shape (H, W, 3)
        RGB image.
    intrinsics : Intrinsics
    up : ndarray, shape (3,)
        Unit table normal towards the camera (camera frame).
    offset_m : float
        ``up @ x`` of the table plane's points, metres.
    napkin : NapkinView
        The napkin's white and the objects above it.
    sticker_px : ndarray, shape (n, 2)
        Pixels (x, y) of the located stickers: the cloth is the part of the white
        region that holds them (NaN rows are ignored).
    napkin_area_mm2 : float
        The flat napkin's area.
    params, napkin_params : optional
    regions : ClothRegions, keyword-only, optional
        The frame's white regions, when found (of the same cell size).
    shade : ShadeParams, keyword-only, optional
        How the cloth is followed into an arm's shadow.

    Returns
    -------
    Footprint or None
    """
    import cv2

    p = params or FootprintParams()
    q = napkin_params or NapkinParams()
    c = p.cell_px
    h, w = color.shape[0] // c, color.shape[1] // c
    if float(up @ np.array([0.0, 0.0, 1.0])) == 0.0:
        return None
    if regions is None or regions.cell_px != c:
        regions = cloth_regions(color, napkin.white_rgb, p, q)
    cloth = cloth_cells(color, napkin, sticker_px, p, q, regions=regions)
    if cloth is None:
        return None
    low = _table_area_mm2(intrinsics, cloth, c, up, offset_m)
    if low > p.max_fraction * napkin_area_mm2:
        return None
    high = low
    occ = None
    if napkin.occluder.any():
        occ = cv2.resize(napkin.occluder.astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST)
    raised = None if occ is None else cv2.dilate(occ, np.ones((3, 3), np.uint8)).view(bool)
    shaded = _in_shade(color, cloth, regions, raised, p, shade)
    if shaded is not None:
        area = _table_area_mm2(intrinsics, shaded, c, up, offset_m)
        if border_cells(shaded) <= MAX_BORDER_CELLS and area <= p.max_fraction * napkin_area_mm2:
            cloth, low, high = shaded, area, area
        else:  # the fill ran out onto the table: the shadowed cloth is not measured
            high = napkin_area_mm2 * p.max_fraction
    if occ is not None:
        # objects above the table (napkin's own sampling grid) next to the cloth
        near = cv2.dilate(cloth.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
        over = occ.astype(bool) & ~cloth
        _, olab, _, _ = cv2.connectedComponentsWithStats(over.astype(np.uint8), 8)
        touching = np.unique(olab[near & over])
        hidden = any_of(olab, touching[touching > 0])
        high += _table_area_mm2(intrinsics, hidden, c, up, offset_m)
    return Footprint(low, min(high, napkin_area_mm2 * p.max_fraction), cloth)
