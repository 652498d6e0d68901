"""Order statistics of small 1-D arrays without numpy's general machinery.

``np.median`` spends most of its time, on a few thousand values, in axis handling and
checks; the per-frame pipeline takes dozens of medians. These give the same values.
From :data:`ONE_PIVOT_FROM` values on, each partitions about a single index and reads the
neighbouring order statistic as the largest (smallest) value on its side: on thousands of
values, ``np.partition`` about several indices at once costs two to seven times as much.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["median", "nanmedian", "quantile", "sorted_median", "sorted_quantile"]

#: Size from which one partition and a pass over one side beat a partition about two or
#: three indices (below it, the extra call costs more than it saves).
ONE_PIVOT_FROM = 1024


def median(x: NDArray) -> float:
    """``np.median`` of a non-empty 1-D array, to the bit: the middle order statistics
    by one partition (their mean in the array's dtype when the count is even), NaN when
    the array holds one.

    Parameters
    ----------
    x : ndarray, shape (n,)

    Returns
    -------
    float
    """
    n = x.size
    k = n // 2
    if n >= ONE_PIVOT_FROM:
        part = np.partition(x, k)
        if np.isnan(part[k:].max()):  # NaN sorts last: any lies at k or beyond
            return float("nan")
        if n % 2:
            return float(part[k])
        return float((part[:k].max() + part[k]) / x.dtype.type(2))
    if n % 2:
        part = np.partition(x, (k, n - 1))
        middle = part[k]
    else:
        part = np.partition(x, (k - 1, k, n - 1))
        middle = (part[k - 1] + part[k]) / x.dtype.type(2)
    return float("nan") if np.isnan(part[n - 1]) else float(middle)


def quantile(x: NDArray, q: float) -> float:
    """``np.quantile(x, q)`` (its default, linear method) of a non-empty 1-D array for a
    float ``q`` in [0, 1], to the bit: the two order statistics around ``(n - 1) q`` by
    one partition, and numpy's interpolation between them; NaN when the array holds one.

    Parameters
    ----------
    x : ndarray, shape (n,)
    q : float

    Returns
    -------
    float
    """
    n = x.size
    virtual, lo, hi = _bracket(n, q)
    if n >= ONE_PIVOT_FROM:
        part = np.partition(x, lo)
        if np.isnan(part[lo:].max()):  # NaN sorts last: any lies at lo or beyond
            return float("nan")
        a = part[lo]
        b = part[hi:].min() if hi > lo else a  # the next order statistic
    else:
        part = np.partition(x, sorted({0, n - 1, lo, hi}))
        if np.isnan(part[n - 1]):
            return float("nan")
        a, b = part[lo], part[hi]
    return _between(a, b, virtual - lo)


def _bracket(n: int, q: float) -> tuple[float, int, int]:
    """numpy's linear method: the virtual index ``(n - 1) q`` and the order statistics
    either side of it (both the end one beyond the ends)."""
    virtual = (n - 1) * q
    lo = int(np.floor(virtual))
    hi = lo + 1
    if virtual >= n - 1:
        lo = hi = n - 1
    elif virtual < 0:
        lo = hi = 0
    return virtual, lo, hi


def _between(a: float, b: float, gamma: float) -> float:
    """numpy's interpolation between two order statistics, to the bit."""
    gamma = float(gamma)
    diff = b - a
    if gamma >= 0.5:
        return float(b - diff * (1 - gamma))
    return float(a + diff * gamma)


def sorted_quantile(ordered: NDArray, q: float) -> float:
    """:func:`quantile` of a non-empty array already sorted (NaN last, as ``np.sort``
    leaves it), to the bit. Where values repeat a lot (8-bit levels through a table), a
    partition costs two to three times a sort."""
    n = ordered.size
    virtual, lo, hi = _bracket(n, q)
    if np.isnan(ordered[n - 1]):
        return float("nan")
    return _between(ordered[lo], ordered[hi], virtual - lo)


def sorted_median(ordered: NDArray) -> float:
    """:func:`median` of a non-empty array already sorted (NaN last), to the bit."""
    n = ordered.size
    k = n // 2
    if np.isnan(ordered[n - 1]):
        return float("nan")
    if n % 2:
        return float(ordered[k])
    return float((ordered[k - 1] + ordered[k]) / ordered.dtype.type(2))


def nanmedian(x: NDArray) -> float:
    """``np.nanmedian`` of a 1-D array, to the bit: the median of its values that are not
    NaN; NaN when there is none (without numpy's warning)."""
    told = x[~np.isnan(x)]
    return median(told) if told.size else float("nan")
