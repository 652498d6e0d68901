"""The isometric fold operator: turn everything beyond a line about a rounded hinge.

A fold is given by a line through two material points and a material point on the flap
side. The flap (the material on that side) turns about the line, in the world, through a
circular hinge of radius ``rho``: a point at distance ``d`` beyond the line rolls onto the
arc while ``d <= rho * angle`` and continues straight after it, so arc length, and with it
every distance along the cloth, is preserved. ``over`` turns the flap up and onto the
napkin (back face up); ``under`` turns it down and beneath, and the whole cloth is then
lifted so that it rests on the table (z >= 0). The hinge radius is chosen so that the
flap lands on top of (or beneath) everything already there, one cloth thickness apart:
what is folded later lies on top.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from .mesh import ClothMesh

__all__ = ["flap_mask", "fold"]


def _side(uv: NDArray, p0: NDArray, p1: NDArray) -> NDArray:
    """Signed area (cross product) of material points relative to the line p0 -> p1."""
    t = p1 - p0
    return t[0] * (uv[..., 1] - p0[1]) - t[1] * (uv[..., 0] - p0[0])


def flap_mask(
    uv: NDArray[np.float64], p0: ArrayLike, p1: ArrayLike, flap_point: ArrayLike
) -> NDArray[np.bool_]:
    """Which material points (k, 2) lie on the flap side of the line through p0, p1 (mm)."""
    a, b, f = (np.asarray(x, dtype=np.float64) for x in (p0, p1, flap_point))
    ref = _side(f, a, b)
    if ref == 0:
        raise ValueError(f"flap point {f.tolist()} lies on the fold line")
    return np.sign(_side(uv, a, b)) == np.sign(ref)


def _top_under_flap(
    xyz: NDArray[np.float64],
    z_rel: NDArray[np.float64],
    moving: NDArray[np.bool_],
    landing: NDArray[np.float64],
    angle: float,
    spacing_mm: tuple[float, ...],
) -> float:
    """Height (m, relative to the hinge, at least 0) of the cloth that stays, where the
    flap lands (``landing``, world (k, 2), for a complete fold) or anywhere (a partial
    fold)."""
    stay = ~moving
    if not stay.any():
        return 0.0
    if angle != np.pi:
        return max(float(z_rel[stay].max()), 0.0)
    # every (staying point, landing point) pair at most the radius apart, as arrays (no
    # Python list a landing point); only the highest staying point of them counts
    near = cKDTree(xyz[stay, :2]).sparse_distance_matrix(
        cKDTree(landing), 1.5e-3 * max(spacing_mm), output_type="ndarray"
    )
    if near.size:
        return max(float(z_rel[stay][near["i"]].max()), 0.0)
    return 0.0


def fold(
    mesh: ClothMesh,
    p0_uv: ArrayLike,
    p1_uv: ArrayLike,
    flap_uv: ArrayLike,
    *,
    angle: float = np.pi,
    under: bool = False,
    thickness_m: float = 1e-3,
) -> ClothMesh:
    """Fold the napkin along the line through two material points.

    Parameters
    ----------
    mesh : ClothMesh
        The cloth before the fold; the material along the fold line must lie flat.
    p0_uv, p1_uv : array_like, shape (2,)
        Two material points (mm) on the fold line.
    flap_uv : array_like, shape (2,)
        A material point (mm) on the side that moves.
    angle : float, keyword-only
        Fold angle in radians: 0 leaves the cloth as it is, pi lays the flap flat.
    under : bool, keyword-only
        Turn the flap down and beneath the napkin instead of up and over it.
    thickness_m : float, keyword-only
        Cloth thickness in metres: the gap between layers.

    Returns
    -------
    ClothMesh
        The folded cloth (same material grid).
    """
    if not 0.0 <= angle <= np.pi:
        raise ValueError(f"angle must be in [0, pi], got {angle}")
    if thickness_m <= 0:
        raise ValueError(f"thickness_m must be positive, got {thickness_m}")
    p0 = np.asarray(p0_uv, dtype=np.float64)
    p1 = np.asarray(p1_uv, dtype=np.float64)
    moving = flap_mask(mesh.uv, p0, p1, flap_uv)
    xyz = mesh.xyz.copy()
    if not moving.any() or angle == 0.0:
        return mesh.with_xyz(xyz)
    # The hinge axis in the world: through the world positions of p0 and p1.
    w0, w1 = mesh.interpolate(np.stack([p0, p1]))
    axis = w1[:2] - w0[:2]
    axis /= np.linalg.norm(axis)
    normal = np.array([-axis[1], axis[0]])  # in the table plane, towards the flap
    if (xyz[moving, :2] - w0[:2]).mean(axis=0) @ normal < 0:
        normal = -normal
    h = 0.5 * (w0[2] + w1[2])
    sgn = -1.0 if under else 1.0  # fold under = fold over in a mirrored z
    z_rel = sgn * (xyz[:, 2] - h)
    rel = xyz[moving, :2] - w0[:2]
    d = rel @ normal  # (k,) distance beyond the line
    along = rel @ axis
    landing = w0[:2] + along[:, None] * axis - np.abs(d)[:, None] * normal
    stay_top = _top_under_flap(xyz, z_rel, moving, landing, angle, mesh.spacing_mm)
    # Hinge radius: the flap's top layer lands one thickness above the top of what lies
    # where it lands.
    flap_top = max(float(z_rel[moving].max()), 0.0)
    rho = 0.5 * (stay_top + flap_top + thickness_m)
    y = z_rel[moving] - rho  # height relative to the hinge axis
    d_pos = np.maximum(d, 0.0)
    alpha = np.minimum(d_pos, rho * angle) / rho
    rest = np.maximum(d_pos - rho * angle, 0.0)
    new_d = -y * np.sin(alpha) + rest * np.cos(angle)
    new_y = y * np.cos(alpha) + rest * np.sin(angle)
    # Points on the moving side but not beyond the line in the world keep their place.
    beyond = d > 0
    new_d = np.where(beyond, new_d, d)
    new_y = np.where(beyond, new_y, y)
    xyz[moving, :2] = w0[:2] + along[:, None] * axis + new_d[:, None] * normal
    xyz[moving, 2] = h + sgn * (new_y + rho)
    if under:
        xyz[:, 2] -= min(float(xyz[:, 2].min()), 0.0)
    return mesh.with_xyz(xyz)
