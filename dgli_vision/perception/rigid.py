"""Rigid maps from the flat napkin to the stickers seen: where a missing sticker would
lie if its part of the cloth lay like the rest (folding is isometric)."""

from __future__ import annotations

from itertools import combinations

import numpy as np
from numpy.typing import NDArray

__all__ = ["kabsch", "rigid_prediction"]


def kabsch(src: NDArray, dst: NDArray) -> tuple[NDArray, NDArray]:
    """Rotations R (..., 3, 3) and translations t (..., 3) with dst ~ src @ R.T + t, in
    the least-squares sense, for stacks of point sets src, dst (..., k, 3)."""
    cs, cd = src.mean(axis=-2, keepdims=True), dst.mean(axis=-2, keepdims=True)
    cov = np.swapaxes(src - cs, -1, -2) @ (dst - cd)
    u, _, vt = np.linalg.svd(cov)
    d = np.sign(np.linalg.det(u @ vt))
    fix = np.ones(u.shape[:-1])
    fix[..., -1] = d
    r = np.swapaxes((u * fix[..., None, :]) @ vt, -1, -2)
    t = cd[..., 0, :] - (cs @ np.swapaxes(r, -1, -2))[..., 0, :]
    return r, t


def rigid_prediction(
    uv_m: NDArray, pts: NDArray, use: NDArray[np.bool_], tol_m: float
) -> tuple[NDArray, NDArray[np.bool_]] | None:
    """Best rigid map of the material points of ``use`` onto their 3D points (all
    triples tried at once, RANSAC-style); returns (predicted 3D points of every sticker,
    inliers) or None."""
    ids = np.flatnonzero(use)
    if ids.size < 3:
        return None
    triples = np.array(list(combinations(ids, 3)))  # (T, 3)
    a, b, c = (uv_m[triples[:, k]] for k in range(3))
    area = np.abs(np.cross(b - a, c - a)[:, 2])
    triples = triples[area > 1e-4]  # not nearly collinear (m^2)
    if len(triples) == 0:
        return None
    r, t = kabsch(uv_m[triples], pts[triples])  # (T, 3, 3), (T, 3)
    pred = np.einsum("tij,nj->tni", r, uv_m[ids]) + t[:, None, :]
    inl = np.linalg.norm(pred - pts[ids][None], axis=2) < tol_m  # (T, n)
    best = inl[int(np.argmax(inl.sum(axis=1)))]
    if best.sum() < 3:
        return None
    r1, t1 = kabsch(uv_m[ids[best]], pts[ids[best]])
    mask = np.zeros(len(pts), dtype=bool)
    mask[ids[best]] = True
    return uv_m @ r1.T + t1, mask
