"""OmniGibson's ``Folded`` and ``Unfolded`` cloth predicates, for comparison.

OmniGibson (``omnigibson/object_states/folded.py``) calls a cloth *folded* when its
surface is mostly flat (at least half its triangles' normals within 45 degrees of the
up axis), and the convex hull of its points seen from above has less than 0.75 of the
flat cloth's area and a diagonal under 0.85 of its diagonal; *unfolded* when it is as
flat, with at least 0.9 of both. Between the two it is neither. Computed here on the
coarse mesh of :class:`~.material.ClothMaterial` against the rest frame, so that
``dgli label`` reports them beside its own states on the same frames.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "FLAT_SHARE",
    "FOLDED_AREA",
    "FOLDED_DIAGONAL",
    "HULL_DIRECTIONS",
    "NORMAL_DEG",
    "UNFOLDED_AREA",
    "UNFOLDED_DIAGONAL",
    "Predicates",
    "hull_area_diagonal",
    "predicates",
]

#: A triangle is flat when its normal is within this many degrees of the up axis.
NORMAL_DEG = 45.0
#: Share of flat triangles both predicates ask for.
FLAT_SHARE = 0.5
#: Folded: hull area and diagonal below these shares of the flat cloth's.
FOLDED_AREA, FOLDED_DIAGONAL = 0.75, 0.85
#: Unfolded: hull area and diagonal at least these shares of the flat cloth's.
UNFOLDED_AREA, UNFOLDED_DIAGONAL = 0.9, 0.9


@dataclass(frozen=True, eq=False)
class Predicates:
    """Per frame (arrays of t): OmniGibson's measures and its two predicates."""

    smoothness: NDArray[np.float64]
    area: NDArray[np.float64]
    diagonal: NDArray[np.float64]
    folded: NDArray[np.bool_]
    unfolded: NDArray[np.bool_]


#: The hull is the polygon of the points extreme in this many directions (exact for a
#: rectangle's corners, within 1% of the exact hull's area for a rounded outline), for
#: all the frames of a block at once.
HULL_DIRECTIONS = 32


def hull_area_diagonal(xy: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """Area and longest chord of the convex hull of points (t, n, 2), each (t,)."""
    ang = np.linspace(0, 2 * np.pi, HULL_DIRECTIONS, endpoint=False)
    dirs = np.stack([np.cos(ang), np.sin(ang)], axis=1).astype(np.float32)  # (K, 2)
    reach = dirs @ xy.astype(np.float32).transpose(0, 2, 1)  # (t, K, n)
    far = np.argmax(reach, axis=2)  # (t, K): counter-clockwise round the hull
    poly = np.take_along_axis(xy, far[..., None], axis=1)  # (t, K, 2)
    nxt = np.roll(poly, -1, axis=1)
    area = 0.5 * np.abs((poly[..., 0] * nxt[..., 1] - nxt[..., 0] * poly[..., 1]).sum(axis=1))
    chords = np.linalg.norm(poly[:, :, None] - poly[:, None], axis=-1)
    return area, chords.max(axis=(1, 2))


def predicates(
    coarse: NDArray[np.float64], faces: NDArray[np.int64], flat: tuple[float, float]
) -> Predicates:
    """OmniGibson's predicates of frames (``coarse`` (t, M, 3), metres, z up) of a mesh
    with triangles ``faces``, against the flat cloth's hull ``flat`` (area, diagonal)."""
    pts = coarse.astype(np.float32)
    a = pts[:, faces[:, 0]]
    u, v = pts[:, faces[:, 1]] - a, pts[:, faces[:, 2]] - a  # (t, F, 3)
    nx = u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1]
    ny = u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2]
    nz = u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]
    nz2 = nz * nz
    norm2 = nx * nx + ny * ny + nz2
    # within NORMAL_DEG of the up axis, either way up: nz^2 > cos^2 |n|^2
    flat_tri = nz2 > np.float32(np.cos(np.radians(NORMAL_DEG)) ** 2) * norm2
    smooth = flat_tri.sum(axis=1) / np.maximum((norm2 > 0).sum(axis=1), 1)
    hull_area, hull_diagonal = hull_area_diagonal(coarse[..., :2])
    area = hull_area / max(flat[0], 1e-12)
    diagonal = hull_diagonal / max(flat[1], 1e-12)
    even = smooth >= FLAT_SHARE
    return Predicates(
        smoothness=smooth,
        area=area,
        diagonal=diagonal,
        folded=even & (area < FOLDED_AREA) & (diagonal < FOLDED_DIAGONAL),
        unfolded=even & (area >= UNFOLDED_AREA) & (diagonal >= UNFOLDED_DIAGONAL),
    )
