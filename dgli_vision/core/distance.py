"""Spearman distance between coordinate vectors and the Davies-Bouldin index.

The Spearman distance (paper eq. 10) is ``1 - rho`` where ``rho`` is Pearson's
correlation of the ranks of the two vectors (ties get their average rank). It lies in
[0, 2]: 0 for vectors ordered alike, 2 for opposite orders. Being rank-based, it ignores
any monotone rescaling of the coordinates, such as the clipping of near-singular dGLI.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "average_ranks",
    "centred_unit_ranks",
    "davies_bouldin",
    "davies_bouldin_points",
    "pairwise_spearman",
    "soft_centred_unit_ranks",
    "spearman_distance",
    "spearman_to_ranked",
]


def average_ranks(x: ArrayLike) -> NDArray[np.float64]:
    """Ranks 1..n along the last axis, ties sharing their average rank.

    The same as ``scipy.stats.rankdata(x, axis=-1)`` (method "average"), in numpy alone:
    importing scipy.stats costs more than half a second at start-up.

    Parameters
    ----------
    x : array_like, shape (..., n)
        Values without NaN.

    Returns
    -------
    ndarray of float64, shape (..., n)
    """
    a = np.asarray(x, dtype=np.float64)
    n = a.shape[-1]
    rows = a.reshape(-1, n)
    m = len(rows)
    order = np.argsort(rows, axis=1, kind="stable")
    ordered = np.take_along_axis(rows, order, axis=1)
    starts = np.ones((m, n), dtype=bool)
    starts[:, 1:] = ordered[:, 1:] != ordered[:, :-1]
    group = np.cumsum(starts, axis=1) + (np.arange(m) * n)[:, None]  # tie groups, unique per row
    position = np.broadcast_to(np.arange(1.0, n + 1.0), (m, n))
    sums = np.bincount(group.ravel(), weights=position.ravel(), minlength=m * n + 1)
    counts = np.bincount(group.ravel(), minlength=m * n + 1)
    ranks = np.empty((m, n))
    np.put_along_axis(ranks, order, (sums / np.maximum(counts, 1))[group], axis=1)
    return ranks.reshape(a.shape)


def centred_unit_ranks(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Average ranks along the last axis, centred and scaled to unit norm: what the
    Spearman correlation of two rows is the dot product of.

    Rows with all values equal have no defined correlation; they become all-zero rows,
    which makes their correlation with anything 0 (distance 1).
    """
    r = average_ranks(x)
    r -= r.mean(axis=-1, keepdims=True)
    norm = np.linalg.norm(r, axis=-1, keepdims=True)
    return np.divide(r, norm, out=np.zeros_like(r), where=norm > 0)


_centred_unit_ranks = centred_unit_ranks


def soft_centred_unit_ranks(x: ArrayLike, tie_scale: float) -> NDArray[np.float64]:
    """:func:`centred_unit_ranks` made continuous in the values, along the last axis.

    Each value's rank counts the others below it, each by a logistic step
    ``(1 + tanh((x_i - x_j) / tau)) / 2`` instead of 0 or 1, with ``tau`` =
    ``tie_scale`` times the row's range. Values farther apart than a few ``tau`` rank
    as :func:`average_ranks` ranks them (exact ties too); two values within ``tau`` of
    each other share their ranks in proportion, so a change of either far smaller than
    ``tau`` never swaps two whole ranks (which moves a Spearman distance over six
    coordinates by 0.057 at once).

    Parameters
    ----------
    x : array_like, shape (..., n)
        Values without NaN.
    tie_scale : float
        ``tau`` as a fraction of each row's range (max - min); 0 gives the exact ranks.
    """
    a = np.asarray(x, dtype=np.float64)
    if tie_scale <= 0:
        return centred_unit_ranks(a)
    # (the reductions by the ufuncs themselves: ndarray.max, .sum and np.linalg.norm's
    # values, without their overhead, which is most of what one frame's row costs)
    spread = np.maximum.reduce(a, axis=-1, keepdims=True)
    spread -= np.minimum.reduce(a, axis=-1, keepdims=True)
    tau = tie_scale * spread
    tau = np.where(tau > 0, tau, 1.0)[..., None]
    step = np.tanh((a[..., :, None] - a[..., None, :]) / tau)  # (..., n, n)
    r = 0.5 * np.add.reduce(step, axis=-1)  # rank minus its mean (n + 1) / 2, exactly
    norm = np.sqrt(np.add.reduce(r * r, axis=-1, keepdims=True))
    return np.divide(r, norm, out=np.zeros_like(r), where=norm > 0)


def _centred_unit_ranks_row(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`centred_unit_ranks` of one short vector (n,), as a row (1, n), bit for bit.

    A few dozen values are ranked faster in Python than by a dozen numpy calls. Every
    intermediate is exact as it is there: an average rank is a half-integer (the sum of
    its tie group's positions over their count), so is their mean ``(n + 1) / 2``, and
    the sum of their squares is a small multiple of 1/4; only the square root and the
    division round, the same way.
    """
    values = x.tolist()
    n = len(values)
    order = sorted(range(n), key=values.__getitem__)
    ranks = [0.0] * n
    start = 0
    while start < n:
        end = start
        first = values[order[start]]
        while end + 1 < n and values[order[end + 1]] == first:
            end += 1
        rank = (start + end + 2) / 2  # positions start + 1 .. end + 1
        for k in range(start, end + 1):
            ranks[order[k]] = rank
        start = end + 1
    mean = (n + 1) / 2
    r = np.array([ranks], dtype=np.float64)
    r -= mean
    norm = float(np.sqrt((r * r).sum()))
    if norm > 0:
        r /= norm
    else:
        r[:] = 0.0
    return r


def spearman_to_ranked(
    x: ArrayLike, ranked: NDArray[np.float64], *, tie_scale: float = 0.0
) -> NDArray[np.float64]:
    """Spearman distances of one vector to rows already ranked, shape (p,).

    The same as ``pairwise_spearman(x[None], y)[0]`` with ``ranked`` =
    ``centred_unit_ranks(y)``: a classifier that compares every frame with the same
    references ranks them once.

    Parameters
    ----------
    x : array_like, shape (k,)
        A complete coordinate vector (no NaN).
    ranked : ndarray, shape (p, k)
        :func:`centred_unit_ranks` of the rows to compare with.
    tie_scale : float, keyword-only
        With a positive value, ``x`` is ranked by :func:`soft_centred_unit_ranks` (near
        ties share their ranks, so the distance is continuous in ``x``); 0 (default)
        ranks it exactly.
    """
    xa = np.asarray(x, dtype=np.float64)
    if xa.ndim != 1 or ranked.ndim != 2 or ranked.shape[1] != len(xa):
        raise ValueError(f"x (k,) and ranked (p, k) do not match: {xa.shape}, {ranked.shape}")
    if np.isnan(xa).any():
        raise ValueError("x contains NaN; use spearman_distance(..., omit_nan=True)")
    if tie_scale > 0:
        row = soft_centred_unit_ranks(xa, tie_scale)[None]
    else:
        row = _centred_unit_ranks_row(xa)
    return np.clip(1.0 - row @ ranked.T, 0.0, 2.0)[0]


def spearman_distance(
    x: ArrayLike, y: ArrayLike, *, omit_nan: bool = False, min_common: int = 3
) -> NDArray[np.float64] | float:
    """Spearman distance ``1 - rho`` of two vectors (paper eq. 10).

    Parameters
    ----------
    x, y : array_like, shape (..., n)
        Coordinate vectors; leading dimensions broadcast.
    omit_nan : bool, keyword-only
        If False (default), a NaN in either vector gives NaN. If True, coordinates that
        are NaN in *either* vector are ignored and the ranks are taken over the others.
    min_common : int, keyword-only
        With ``omit_nan``, fewer than this many common coordinates give NaN.

    Returns
    -------
    float or ndarray of float64, shape (...)
        Distance in [0, 2]. A vector whose values are all equal correlates with nothing:
        its distance to anything is 1.
    """
    xa, ya = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
    if xa.ndim == 0:
        raise ValueError("x and y must be vectors, got scalars")
    if xa.shape[-1] < 2:
        raise ValueError(f"x and y need at least 2 coordinates, got {xa.shape[-1]}")
    shape = xa.shape[:-1]
    xs = xa.reshape(-1, xa.shape[-1])
    ys = ya.reshape(-1, ya.shape[-1])
    keep = ~(np.isnan(xs) | np.isnan(ys))
    out = np.full(len(xs), np.nan)
    complete = keep.all(axis=1)
    if complete.any():
        rx = _centred_unit_ranks(xs[complete])
        ry = _centred_unit_ranks(ys[complete])
        out[complete] = 1.0 - np.einsum("ij,ij->i", rx, ry)
    if omit_nan:
        for k in np.flatnonzero(~complete):
            if keep[k].sum() >= min_common:
                rx = _centred_unit_ranks(xs[k, keep[k]])
                ry = _centred_unit_ranks(ys[k, keep[k]])
                out[k] = 1.0 - float(rx @ ry)
    out = np.clip(out, 0.0, 2.0)
    if shape == ():
        return float(out[0])
    return out.reshape(shape)


def pairwise_spearman(x: ArrayLike, y: ArrayLike | None = None) -> NDArray[np.float64]:
    """Matrix of Spearman distances between the rows of ``x`` and of ``y``.

    Parameters
    ----------
    x : array_like, shape (n, k)
        Complete coordinate vectors (no NaN).
    y : array_like, shape (p, k), optional
        Defaults to ``x``.

    Returns
    -------
    ndarray of float64, shape (n, p)
        ``D[i, j] = spearman_distance(x[i], y[j])``; exactly 0 on the diagonal when ``y``
        is omitted.
    """
    xa = np.asarray(x, dtype=np.float64)
    if xa.ndim != 2:
        raise ValueError(f"x must have shape (n, k), got {xa.shape}")
    if np.isnan(xa).any():
        raise ValueError("x contains NaN; use spearman_distance(..., omit_nan=True)")
    rx = _centred_unit_ranks(xa)
    if y is None:
        dist = np.clip(1.0 - rx @ rx.T, 0.0, 2.0)
        np.fill_diagonal(dist, 0.0)
        return dist
    ya = np.asarray(y, dtype=np.float64)
    if ya.ndim != 2 or ya.shape[1] != xa.shape[1]:
        raise ValueError(f"y must have shape (p, {xa.shape[1]}), got {ya.shape}")
    if np.isnan(ya).any():
        raise ValueError("y contains NaN; use spearman_distance(..., omit_nan=True)")
    return np.clip(1.0 - rx @ _centred_unit_ranks(ya).T, 0.0, 2.0)


def _check_labels(labels: ArrayLike, n: int) -> tuple[NDArray, NDArray[np.intp]]:
    lab = np.asarray(labels)
    if lab.shape != (n,):
        raise ValueError(f"labels must have shape ({n},), got {lab.shape}")
    classes, index = np.unique(lab, return_inverse=True)
    if len(classes) < 2:
        raise ValueError("the Davies-Bouldin index needs at least 2 classes")
    return classes, index


def _db_from_parts(scatter: NDArray, separation: NDArray) -> float:
    """Paper eq. 11: mean over classes of max_j (s_i + s_j) / d(c_i, c_j)."""
    k = len(scatter)
    ratio = (scatter[:, None] + scatter[None, :]) / separation
    ratio[np.arange(k), np.arange(k)] = -np.inf
    return float(np.mean(ratio.max(axis=1)))


def davies_bouldin(distances: ArrayLike, labels: ArrayLike) -> float:
    """Davies-Bouldin index from a distance matrix, with class medoids as centres.

    For any distance (Spearman, Frechet, Hausdorff, ...) the centre of a class is its
    medoid, the member with the least summed distance to the others; the scatter ``s_i``
    is the mean distance of the members to it and the separation the medoid-to-medoid
    distance. Lower is better (paper eq. 11).

    Parameters
    ----------
    distances : array_like, shape (n, n)
        Symmetric distance matrix.
    labels : array_like, shape (n,)
        Class of each sample; at least two classes.

    Returns
    -------
    float
        The index; ``inf`` if two classes share a medoid position (zero separation).
    """
    dist = np.asarray(distances, dtype=np.float64)
    if dist.ndim != 2 or dist.shape[0] != dist.shape[1]:
        raise ValueError(f"distances must be a square matrix, got shape {dist.shape}")
    classes, index = _check_labels(labels, dist.shape[0])
    medoids = np.empty(len(classes), dtype=np.intp)
    scatter = np.empty(len(classes))
    for c in range(len(classes)):
        members = np.flatnonzero(index == c)
        sub = dist[np.ix_(members, members)]
        medoids[c] = members[np.argmin(sub.sum(axis=1))]
        scatter[c] = dist[members, medoids[c]].mean()
    separation = dist[np.ix_(medoids, medoids)]
    with np.errstate(divide="ignore", invalid="ignore"):
        return _db_from_parts(scatter, separation)


def davies_bouldin_points(
    points: ArrayLike,
    labels: ArrayLike,
    metric: Callable[[NDArray, NDArray], float],
) -> float:
    """Davies-Bouldin index of vectors, with class means as centres (paper eq. 11).

    Parameters
    ----------
    points : array_like, shape (n, k)
        One vector per sample.
    labels : array_like, shape (n,)
        Class of each sample; at least two classes.
    metric : callable
        ``metric(u, v) -> float`` for vectors of shape (k,).

    Returns
    -------
    float
        The index (lower is better).
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2:
        raise ValueError(f"points must have shape (n, k), got {pts.shape}")
    classes, index = _check_labels(labels, len(pts))
    centres = np.stack([pts[index == c].mean(axis=0) for c in range(len(classes))])
    scatter = np.array(
        [np.mean([metric(p, centres[c]) for p in pts[index == c]]) for c in range(len(classes))]
    )
    k = len(classes)
    separation = np.array([[metric(centres[a], centres[b]) for b in range(k)] for a in range(k)])
    with np.errstate(divide="ignore", invalid="ignore"):
        return _db_from_parts(scatter, separation)
