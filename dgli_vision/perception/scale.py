"""The napkin as its own ruler: how big it measures, and whether it keeps its shape.

The four stickers around a corner lie within 113 mm of each other, on a part of the cloth
that no fold of SPEC's states bends, and folding never stretches cloth. So the distances
between located stickers of the same corner are known in advance (42-113 mm), whatever
the state. Their ratio to the flat napkin's says:

* the **scale** (median ratio): depth in the wrong units (a depth scale of 0.8 makes the
  napkin measure 320 mm instead of 400) or wrong focal lengths shrink or grow every
  distance alike;
* the **isometry error** (spread of the ratios): an uncorrected lens stretches distances
  radially more than across, so near the image border the corners stop being rigid.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ..core.layout import CORNER_STICKERS, NapkinLayout
from ..core.order_stats import median
from .lift import Markers3D

__all__ = ["NapkinRuler", "measure_napkin"]

@dataclass(frozen=True)
class NapkinRuler:
    """What the located stickers say of the napkin's size and rigidity.

    Attributes
    ----------
    scale : float
        Median ratio of measured to flat distances between stickers of the same corner
        (1 for a right depth scale and intrinsics).
    spread : float
        Median absolute deviation of those ratios from ``scale`` (0 for a rigid,
        undistorted napkin; sensor noise gives about 0.01).
    worst : float
        Largest distance from 1 of a corner's median ratio.
    worst_against_scale : float
        Largest relative distance of a corner's median ratio from ``scale``, over the
        corners with three stickers or more located: how much one corner is stretched
        or shrunk against the rest (0 for a rigid napkin).
    pairs : int
        Number of sticker pairs measured.
    """

    scale: float
    spread: float
    worst: float
    pairs: int
    worst_against_scale: float = 0.0


@lru_cache(maxsize=1)
def _pairs_by_corner() -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    """Ids (i, j) of every pair of stickers around the same corner, and that corner
    (0-3), 24 pairs (the same for every napkin size: SPEC's sticker order); read-only,
    made once."""
    i, j, k = [], [], []
    for corner, ids in enumerate(CORNER_STICKERS):
        for a in range(4):
            for b in range(a + 1, 4):
                i.append(ids[a])
                j.append(ids[b])
                k.append(corner)
    out = np.array(i), np.array(j), np.array(k)
    for a in out:
        a.flags.writeable = False
    return out


def measure_napkin(
    markers: Markers3D, layout: NapkinLayout, *, min_pairs: int = 3
) -> NapkinRuler | None:
    """Scale and rigidity of the napkin from its located stickers.

    Parameters
    ----------
    markers : Markers3D
        Located stickers (metres).
    layout : NapkinLayout
        The flat napkin's sticker positions (mm).
    min_pairs : int, keyword-only
        Fewest pairs of same-corner stickers to measure from (default 3).

    Returns
    -------
    NapkinRuler or None
        None with fewer than ``min_pairs`` pairs located.
    """
    i, j, pair_corner = _pairs_by_corner()
    found = markers.found
    use = found[i] & found[j]
    if use.sum() < min_pairs:
        return None
    i, j = i[use], j[use]
    uv = layout.sticker_uv
    flat_mm = _lengths(uv[i] - uv[j])
    d_mm = _lengths(markers.points[i] - markers.points[j]) * 1e3
    ratio = d_mm / flat_mm
    scale = median(ratio)
    spread = median(np.abs(ratio - scale))
    corners = pair_corner[use]
    of_corner = [ratio[corners == k] for k in sorted(set(corners.tolist()))]
    medians = [median(r) for r in of_corner]
    worst = float(max(abs(m - 1.0) for m in medians))
    # a corner is judged on three stickers or more (three pairs): one pair with a
    # sticker half hidden (a gripper's finger, a flap's edge) moves its centre
    judged = [m for m, r in zip(medians, of_corner) if len(r) >= 3]
    against = max((abs(m / scale - 1.0) for m in judged), default=0.0) if scale > 0 else np.inf
    return NapkinRuler(scale, spread, worst, int(use.sum()), against)


def _lengths(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """The lengths of the rows of ``v`` as ``np.linalg.norm(v, axis=1)`` takes them,
    without its overhead."""
    return np.sqrt(np.add.reduce(v * v, axis=1))
