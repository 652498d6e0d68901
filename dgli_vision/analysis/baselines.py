"""The representations the paper compares dGLI with (section 4.3).

* Edges: the 28 minimal distances between pairs of the 8 segments, Spearman distance.
* Corners: the 6 distances between the napkin's 4 corners, Spearman distance.
* Frechet, Hausdorff: distances between the full boundary polylines (4 corners and the
  edges between them) after centring and the optimal (Kabsch) rotation.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.distance import directed_hausdorff

from ..core.dgli import pair_indices
from ..core.errors import InvalidValueError

__all__ = [
    "align",
    "corner_distances",
    "discrete_frechet",
    "hausdorff",
    "pairwise_curve_distances",
    "segment_distances",
]


def _segment_min_distance(p0, p1, q0, q1) -> NDArray[np.float64]:
    """Minimal distance between segments p0-p1 and q0-q1, arrays (..., 3) -> (...)."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a = np.einsum("...i,...i", d1, d1)
    e = np.einsum("...i,...i", d2, d2)
    f = np.einsum("...i,...i", d2, r)
    c = np.einsum("...i,...i", d1, r)
    b = np.einsum("...i,...i", d1, d2)
    denom = a * e - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(denom > 1e-18, np.clip((b * f - c * e) / denom, 0, 1), 0.0)
        t = np.where(e > 0, (b * s + f) / e, 0.0)
        # Clamp t and recompute s (Ericson, Real-Time Collision Detection, 5.1.9).
        s = np.where(t < 0, np.where(a > 0, np.clip(-c / a, 0, 1), 0.0), s)
        s = np.where(t > 1, np.where(a > 0, np.clip((b - c) / a, 0, 1), 0.0), s)
        t = np.clip(t, 0, 1)
    c1 = p0 + s[..., None] * d1
    c2 = q0 + t[..., None] * d2
    return np.linalg.norm(c1 - c2, axis=-1)


def segment_distances(segments: NDArray[np.float64]) -> NDArray[np.float64]:
    """Edges representation: (..., m, 2, 3) -> (..., m (m - 1) / 2) minimal distances."""
    seg = np.asarray(segments, dtype=np.float64)
    i, j = pair_indices(seg.shape[-3])
    return _segment_min_distance(
        seg[..., i, 0, :], seg[..., i, 1, :], seg[..., j, 0, :], seg[..., j, 1, :]
    )


def corner_distances(corners: NDArray[np.float64]) -> NDArray[np.float64]:
    """Corners representation: (..., 4, 3) -> (..., 6) corner-to-corner distances."""
    c = np.asarray(corners, dtype=np.float64)
    i, j = pair_indices(c.shape[-2])
    return np.linalg.norm(c[..., i, :] - c[..., j, :], axis=-1)


def align(curve: NDArray[np.float64], target: NDArray[np.float64]) -> NDArray[np.float64]:
    """``curve`` (n, 3) centred and rotated (proper rotation) onto centred ``target``."""
    a = curve - curve.mean(axis=0)
    b = target - target.mean(axis=0)
    u, _, vt = np.linalg.svd(a.T @ b)
    d = np.sign(np.linalg.det(u @ vt))
    rot = u @ np.diag([1.0, 1.0, d]) @ vt
    return a @ rot


def discrete_frechet(p: NDArray[np.float64], q: NDArray[np.float64]) -> float:
    """Discrete Frechet distance of polylines (n, 3) and (k, 3), by anti-diagonals."""
    dist = np.linalg.norm(p[:, None, :] - q[None, :, :], axis=-1)
    n, k = dist.shape
    ca = np.full((n, k), np.inf)
    ca[0, 0] = dist[0, 0]
    ca[0, 1:] = np.maximum.accumulate(dist[0, 1:].clip(min=dist[0, 0]))
    ca[1:, 0] = np.maximum.accumulate(dist[1:, 0].clip(min=dist[0, 0]))
    for s in range(2, n + k - 1):  # cells (i, j) with i + j = s, i, j >= 1
        i = np.arange(max(1, s - k + 1), min(n - 1, s - 1) + 1)
        j = s - i
        best = np.minimum(np.minimum(ca[i - 1, j], ca[i, j - 1]), ca[i - 1, j - 1])
        ca[i, j] = np.maximum(best, dist[i, j])
    return float(ca[-1, -1])


def hausdorff(p: NDArray[np.float64], q: NDArray[np.float64]) -> float:
    """Symmetric Hausdorff distance of point sets (n, 3) and (k, 3)."""
    return float(max(directed_hausdorff(p, q)[0], directed_hausdorff(q, p)[0]))


def _align_many(curves: NDArray[np.float64], target: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`align` of each centred curve of ``curves`` (B, n, 3) onto centred ``target``
    (n, 3), all at once."""
    u, _, vt = np.linalg.svd(np.swapaxes(curves, 1, 2) @ target)
    d = np.sign(np.linalg.det(u @ vt))
    u = u.copy()
    u[..., :, 2] *= d[:, None]  # u @ diag(1, 1, d)
    return curves @ (u @ vt)


def _frechet_many(dist: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`discrete_frechet` of a stack of point distance tables (B, n, k)."""
    b, n, k = dist.shape
    ca = np.full((b, n, k), np.inf)
    ca[:, 0, 0] = dist[:, 0, 0]
    ca[:, 0, 1:] = np.maximum.accumulate(
        np.maximum(dist[:, 0, 1:], dist[:, 0, :1]), axis=1
    )
    ca[:, 1:, 0] = np.maximum.accumulate(
        np.maximum(dist[:, 1:, 0], dist[:, :1, 0]), axis=1
    )
    for s in range(2, n + k - 1):
        i = np.arange(max(1, s - k + 1), min(n - 1, s - 1) + 1)
        j = s - i
        best = np.minimum(np.minimum(ca[:, i - 1, j], ca[:, i, j - 1]), ca[:, i - 1, j - 1])
        ca[:, i, j] = np.maximum(best, dist[:, i, j])
    return ca[:, -1, -1]


def pairwise_curve_distances(curves: NDArray[np.float64], metric: str) -> NDArray[np.float64]:
    """Distance matrix between boundary polylines (n, m, 3) after alignment.

    Each row is computed for all its pairs at once (stacked rotations and distance
    tables, in blocks), with the same arithmetic as :func:`align` and
    :func:`discrete_frechet` / :func:`hausdorff` pair by pair.

    Parameters
    ----------
    curves : ndarray, shape (n, m, 3)
        Polylines with corresponding points (same material positions).
    metric : {"frechet", "hausdorff"}

    Returns
    -------
    ndarray, shape (n, n)
    """
    if metric not in ("frechet", "hausdorff"):
        raise InvalidValueError(f"metric must be 'frechet' or 'hausdorff', got {metric!r}")
    n = len(curves)
    centred = curves - curves.mean(axis=1, keepdims=True)
    out = np.zeros((n, n))
    block = 128
    for a in range(n):
        for b0 in range(a + 1, n, block):
            others = centred[b0 : b0 + block]
            moved = _align_many(np.broadcast_to(centred[a], others.shape).copy(), others)
            # moved[t] is curve a rotated onto others[t]
            dist = np.linalg.norm(moved[:, :, None, :] - others[:, None, :, :], axis=-1)
            if metric == "frechet":
                d = _frechet_many(dist)
            else:
                d = np.maximum(dist.min(axis=2).max(axis=1), dist.min(axis=1).max(axis=1))
            out[a, b0 : b0 + len(others)] = d
            out[b0 : b0 + len(others), a] = d
    return out
