"""Rigid maps from the flat napkin to the stickers seen: where a missing sticker would
lie if its part of the cloth lay like the rest (folding is isometric), and the pose of
the napkin that lies flat.

One fit, :func:`fit_rigid` (every triple of the stickers asked tried at once,
RANSAC-style, then a least-squares fit of the inliers), serves every user of a rigid
map in perception: the evidence's predicted places (:mod:`.evidence`) and the pose of
the napkin that stays for the corners' tips (:mod:`.tips`). Its result,
:class:`RigidFit`, keeps the map itself, so no caller fits its inliers again.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

from ..core.layout import NapkinLayout

__all__ = ["RigidFit", "fit_rigid", "flat_points_m", "kabsch"]


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


#: Triples tried before the rest (see :func:`fit_rigid`).
_FIRST_TRIPLES = 8


@lru_cache(maxsize=32)
def _triples(n: int) -> NDArray[np.intp]:
    """Every triple of 0..n-1 in :func:`itertools.combinations` order, (T, 3), read-only."""
    out = np.array(list(combinations(range(n), 3)), dtype=np.intp).reshape(-1, 3)
    out.flags.writeable = False
    return out


@lru_cache(maxsize=32)
def flat_points_m(layout: NapkinLayout) -> NDArray[np.float64]:
    """The stickers' material points on the flat napkin, (u, v, 0) in metres, shape
    (16, 3); read-only, once per layout."""
    uv = layout.sticker_uv
    out = np.column_stack([uv * 1e-3, np.zeros(len(uv))])
    out.flags.writeable = False
    return out


@dataclass(frozen=True, eq=False)
class RigidFit:
    """A rigid map of the flat napkin onto the stickers seen, ``x = R m + t``.

    Attributes
    ----------
    rotation : ndarray, shape (3, 3)
        R, from material (u, v, 0) metres to the camera frame.
    translation : ndarray, shape (3,)
        t, metres.
    inliers : ndarray of bool, shape (n,)
        The stickers it was fitted to (within the tolerance of the best triple's map).
    predicted : ndarray, shape (n, 3)
        Where it puts every sticker's material point, camera frame, metres.
    """

    rotation: NDArray[np.float64]
    translation: NDArray[np.float64]
    inliers: NDArray[np.bool_]
    predicted: NDArray[np.float64]

    def corners_spanned(self, corner_of: NDArray[np.intp]) -> int:
        """How many corners (``corner_of``: each sticker's corner) its inliers hold."""
        return len(set(corner_of[self.inliers].tolist()))

    def face_cos(self, up: NDArray[np.float64]) -> float:
        """The cosine between the napkin's front-face normal as mapped and ``up``: near
        1 for a napkin lying front face up."""
        return float(self.rotation[:, 2] @ up)


def fit_rigid(
    uv_m: NDArray, pts: NDArray, use: NDArray[np.bool_], tol_m: float
) -> RigidFit | None:
    """Best rigid map of the material points ``uv_m`` (n, 3) of the stickers ``use``
    (n,) onto their 3D points ``pts`` (n, 3): every triple not nearly collinear tried
    at once, RANSAC-style, the triple's map with the most inliers within ``tol_m``
    (metres) kept, and the least-squares map of those inliers returned; None with
    fewer than three stickers or inliers."""
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
    return RigidFit(r1, t1, mask, uv_m @ r1.T + t1)
