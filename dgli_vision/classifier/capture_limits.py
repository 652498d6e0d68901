"""The camera's working envelope: what a frame must give for a verdict to be trusted.

Two limits of the images themselves, not of the cloth:

* **Sticker size.** A sticker must be at least :data:`MIN_STICKER_PX` pixels across for
  its 12 mm dot to keep a readable core after a real lens's and sensor's blur; smaller,
  identities are guesses, so no verdict is given and the message says how small they
  are and what is needed (a camera too far away, or a lens too wide).
* **An uncorrected lens near the image border.** Without distortion coefficients, a
  sticker near the border may be displaced by a large fraction of its own size (a
  typical wide lens, k1 about 0.1, moves a point at the edge of a 1280 x 720 frame by
  tens of pixels); missing or displaced stickers there turn into folds. The verdict's
  confidence is scaled down smoothly with the displacement a lens would cause at the
  outermost sticker, relative to the sticker's size (:func:`border_factor`): a typical
  lens, or the weakest lens that the stickers' own distances allow, whichever is
  weaker. An uncorrected lens stretches a corner near the border against the rest of
  the napkin (cloth does not stretch), so a napkin whose corners keep their printed
  distances rules a strong lens out.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..core.camera import Intrinsics
from ..core.layout import CORNER_STICKERS

__all__ = [
    "BORDER_DOUBT",
    "LENS_BOUND_ALLOWANCE",
    "LENS_STRETCH_NOISE",
    "MIN_STICKER_PX",
    "TYPICAL_K1",
    "border_factor",
    "lens_k1_bound",
    "sticker_px",
    "sticker_size_problem",
]

#: Smallest sticker diameter (pixels) a verdict is given for: the 12 mm dot is then 4
#: pixels across, and a blur of 1-1.6 pixels (a lens, demosaicing) leaves its centre
#: readable. A robot's head camera (1.2 m, fx 605) sees 15.
MIN_STICKER_PX = 10.0
#: First radial coefficient of a typical uncorrected wide lens (the renderer's
#: ``distortion`` condition draws 0.06-0.12).
TYPICAL_K1 = 0.1
#: Displacement a typical lens would cause at the outermost sticker, in sticker
#: diameters, where the confidence starts to fall (first) and where it is halved (second).
BORDER_DOUBT = (0.5, 1.5)
#: How far (relative) one corner's sticker distances may lie from the napkin's scale
#: with no lens at all: sensor noise, wrinkles and a sticker on a crease (renders give
#: under 0.3% on clean images and RIGIDITY_TOLERANCE's "under 2%" at worst); the
#: largest lens the measured stretch allows is worked out with it added.
LENS_STRETCH_NOISE = 0.02
#: How much larger than the measured stretch's own bound a lens is taken to be at most:
#: the model (one ``r`` per corner, a napkin facing the camera) is approximate; on 24
#: renders through a known lens (``benchmarks/reliability.py``'s ``aside-lens``, seed
#: 5151) the plain bound fell below the lens's ``k1`` once, by 13%.
LENS_BOUND_ALLOWANCE = 1.25


def sticker_px(depth_mm: float, intrinsics: Intrinsics, disc_diameter_mm: float) -> float:
    """Diameter (pixels) of a sticker face-on at ``depth_mm`` (NaN without a depth)."""
    if not (depth_mm > 0):
        return float("nan")
    return disc_diameter_mm * intrinsics.fx / depth_mm


def sticker_size_problem(
    depth_mm: float, intrinsics: Intrinsics, disc_diameter_mm: float
) -> str | None:
    """Why the stickers are too small to be read at the napkin's depth, or None.

    Parameters
    ----------
    depth_mm : float
        The napkin's distance from the camera (the median depth of its stickers or of
        the frame), mm.
    intrinsics : Intrinsics
    disc_diameter_mm : float
        The stickers' printed diameter.

    Returns
    -------
    str or None
        ``"stickers 8 px across, need 10 (the napkin is 2300 mm from the camera: ...)"``.
    """
    size = sticker_px(depth_mm, intrinsics, disc_diameter_mm)
    if not (size < MIN_STICKER_PX):
        return None
    farthest = disc_diameter_mm * intrinsics.fx / MIN_STICKER_PX
    return (
        f"stickers {size:.0f} px across, need {MIN_STICKER_PX:.0f} (the napkin is "
        f"{depth_mm:.0f} mm from the camera; with this lens at most {farthest:.0f} mm)"
    )


def lens_k1_bound(
    centroids_px: NDArray[np.float64], intrinsics: Intrinsics, stretch: float
) -> float:
    """The largest first radial coefficient ``k1`` of an uncorrected lens that leaves
    the napkin's corners as little stretched against each other as measured.

    Lifted without its coefficients, a lens with ``k1`` scales the distances around a
    point at normalised radius ``r`` by ``1 + k1 r^2`` across the radius and
    ``1 + 3 k1 r^2`` along it. The napkin's scale is the median over its corners, so the
    corner farthest in ``r^2`` from the corners' median (by ``d``) is stretched against
    it by at least ``k1 d`` (the weaker direction alone: a corner's distances mix both,
    and a tilted napkin's depth adds to them). A measured stretch ``stretch`` (plus
    :data:`LENS_STRETCH_NOISE`) so bounds ``k1`` by ``(stretch + noise) / d``, taken
    :data:`LENS_BOUND_ALLOWANCE` times larger for what the model leaves out.

    Parameters
    ----------
    centroids_px : ndarray, shape (16, 2)
        The stickers' centres, pixels, NaN where not located.
    intrinsics : Intrinsics
    stretch : float
        The largest relative distance of a corner's sticker distances from the napkin's
        scale (``NapkinRuler.worst_against_scale``).

    Returns
    -------
    float
        The bound; ``inf`` when fewer than two corners have three stickers located, or
        they lie at one radius (the stretch then says nothing of the lens).
    """
    c = np.asarray(centroids_px, dtype=np.float64)
    if c.shape != (16, 2) or not np.isfinite(stretch):
        return float("inf")
    x = (c[:, 0] - intrinsics.cx) / intrinsics.fx
    y = (c[:, 1] - intrinsics.cy) / intrinsics.fy
    r2 = x * x + y * y
    corners = [r2[list(ids)] for ids in CORNER_STICKERS]
    told = [float(np.mean(v[np.isfinite(v)])) for v in corners if np.isfinite(v).sum() >= 3]
    if len(told) < 2:
        return float("inf")
    d = float(np.max(np.abs(np.asarray(told) - np.median(told))))
    if d <= 1e-6:
        return float("inf")
    return LENS_BOUND_ALLOWANCE * (stretch + LENS_STRETCH_NOISE) / d


def border_factor(
    centroids_px: NDArray[np.float64],
    intrinsics: Intrinsics,
    sticker_diameter_px: float,
    *,
    stretch: float | None = None,
) -> float:
    """Factor in [0.5, 1] on a verdict's confidence for stickers near the image border
    of a lens whose distortion is not known (1 when it is known).

    An uncorrected lens moves a point at normalised radius ``r`` by ``k1 r^3`` focal
    lengths: ``k1`` a typical lens's (:data:`TYPICAL_K1`), or, with the napkin's
    measured ``stretch``, the largest that stretch allows (:func:`lens_k1_bound`) when
    that is smaller. At the located sticker farthest from the principal point, that
    displacement in sticker diameters below :data:`BORDER_DOUBT`'s first value leaves
    the confidence as it is; above it the factor falls linearly to 0.5 at the second.

    Parameters
    ----------
    centroids_px : ndarray, shape (n, 2)
        Located stickers' centres, pixels (NaN rows are ignored); all 16 rows (NaN where
        not located) for ``stretch`` to count.
    intrinsics : Intrinsics
    sticker_diameter_px : float
        The stickers' diameter at the napkin's depth, pixels.
    stretch : float, keyword-only, optional
        How far one corner's sticker distances lie from the napkin's scale
        (``NapkinRuler.worst_against_scale``); None: not measured (a typical lens).
    """
    if intrinsics.distorted:
        return 1.0
    c = np.asarray(centroids_px, dtype=np.float64).reshape(-1, 2)
    found = c[np.isfinite(c).all(axis=1)]
    if not len(found) or not (sticker_diameter_px > 0):
        return 1.0
    x = (found[:, 0] - intrinsics.cx) / intrinsics.fx
    y = (found[:, 1] - intrinsics.cy) / intrinsics.fy
    r = float(np.sqrt(x * x + y * y).max())
    k1 = TYPICAL_K1
    if stretch is not None:
        k1 = min(k1, lens_k1_bound(c, intrinsics, stretch))
    moved = k1 * r**3 * intrinsics.fx / sticker_diameter_px
    lo, hi = BORDER_DOUBT
    return min(max(1.0 - 0.5 * (moved - lo) / (hi - lo), 0.5), 1.0)  # (np.clip's value)
