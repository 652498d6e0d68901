"""Rigid maps from the flat napkin to the stickers seen: where a missing sticker would
lie if its part of the cloth lay like the rest (folding is isometric)."""

from __future__ import annotations

from functools import lru_cache
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

__all__ = ["kabsch", "rigid_prediction"]


def kabsch(src: NDArray, dst: NDArray) -> tuple[NDArray, NDArray]:
    """Rotations R (..., 3, 3) and translations t (..., 3) with dst ~ src @ R.T + t, in
    the least-squares sense, for stacks of point sets src, dst (..., k, 3)."""
    # the means as ndarray.mean takes them (sum, then divide), without its overhead
    k = src.shape[-2]
    cs = np.add.reduce(src, axis=-2, keepdims=True) / k
    cd = np.add.reduce(dst, axis=-2, keepdims=True) / k
    u, _, vt = np.linalg.svd((src - cs).mT @ (dst - cd))
    r = u @ vt
    d = np.sign(np.linalg.det(r))
    if not (d > 0).all():  # a reflection: turn the last axis of u round (times 1 elsewhere)
        fix = np.ones(u.shape[:-1])
        fix[..., -1] = d
        r = (u * fix[..., None, :]) @ vt
    r = r.mT
    t = cd[..., 0, :] - (cs @ r.mT)[..., 0, :]
    return r, t


#: Triples tried before the rest (see :func:`rigid_prediction`).
_FIRST_TRIPLES = 8


@lru_cache(maxsize=32)
def _triples(n: int) -> NDArray[np.intp]:
    """Every triple of 0..n-1 in :func:`itertools.combinations` order, (T, 3), read-only."""
    out = np.array(list(combinations(range(n), 3)), dtype=np.intp).reshape(-1, 3)
    out.flags.writeable = False
    return out


def rigid_prediction(
    uv_m: NDArray, pts: NDArray, use: NDArray[np.bool_], tol_m: float
) -> tuple[NDArray, NDArray[np.bool_]] | None:
    """Best rigid map of the material points of ``use`` onto their 3D points (all
    triples tried at once, RANSAC-style); returns (predicted 3D points of every sticker,
    inliers) or None."""
    ids = np.flatnonzero(use)
    if ids.size < 3:
        return None
    triples = ids[_triples(ids.size)]  # (T, 3), as combinations(ids, 3)
    a, b, c = (uv_m[triples[:, k]] for k in range(3))
    ab, ac = b - a, c - a
    area = np.abs(ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0])  # np.cross's z, as it takes it
    triples = triples[area > 1e-4]  # not nearly collinear (m^2)
    if len(triples) == 0:
        return None
    # The first few triples, then the rest: a triple that has every point as an inlier is
    # the best (the first such, as argmax over all would pick), and on a napkin lying
    # rigid one of the first few usually has; each triple's fit is its own.
    inl = np.zeros((0, ids.size), dtype=bool)
    for chunk in (triples[:_FIRST_TRIPLES], triples[_FIRST_TRIPLES:]):
        if not len(chunk):
            continue
        r, t = kabsch(uv_m[chunk], pts[chunk])  # (T, 3, 3), (T, 3)
        pred = np.einsum("tij,nj->tni", r, uv_m[ids]) + t[:, None, :]
        off = pred - pts[ids][None]  # (its lengths as np.linalg.norm takes them)
        inl = np.concatenate([inl, np.sqrt(np.add.reduce(off * off, axis=2)) < tol_m])
        if inl.all(axis=1).any():
            break
    best = inl[int(np.argmax(inl.sum(axis=1)))]
    if best.sum() < 3:
        return None
    r1, t1 = kabsch(uv_m[ids[best]], pts[ids[best]])
    mask = np.zeros(len(pts), dtype=bool)
    mask[ids[best]] = True
    return uv_m @ r1.T + t1, mask
