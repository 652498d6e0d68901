"""Gauss linking integral (GLI) of segment pairs, its directional derivative (dGLI) and
the dGLI cloth coordinates.

Conventions
-----------
For two segments ``a -> b`` and ``c -> d`` parametrised as ``g1(s) = a + s (b - a)`` and
``g2(t) = c + t (d - c)``, ``s, t`` in [0, 1], the Gauss linking integral is::

    GLI = 1 / (4 pi) * integral (g1'(s) x g2'(t)) . (g1(s) - g2(t)) / |g1(s) - g2(t)|^3 ds dt

so that summing it over all segment pairs of two closed polygons gives their linking
number. Geometrically ``-4 pi GLI`` is the signed area of the spherical quadrilateral swept
by the unit vector of ``w(s, t) = g1(s) - g2(t)``, whose corners are
``p = a - c``, ``q = b - c``, ``r = b - d`` and ``s = a - d``. We split it into the
triangles ``(p, q, r)`` and ``(p, r, s)`` and use the signed solid angle of Van Oosterom and
Strackee (1983), ``tan(Omega / 2) = N / D`` with ``N = p . (q x r)`` and
``D = |p||q||r| + (p.q)|r| + (p.r)|q| + (q.r)|p|``. This equals the Klenin-Langowski
arcsin formula *with* its sign factor, is smooth across coplanar (flat) configurations,
where the arcsin form has a square-root kink, and can be differentiated in closed form.

The dGLI (paper eq. 8) is the derivative of the GLI when ``b`` and ``d`` move along the
unit vector ``up``: ``d/de GLI(a, b + e up, c, d + e up)`` at ``e = 0``. Here it is
*exact* (analytic differentiation of the expression above), not a finite difference:
its error is rounding only (about 1e-13 relative on ordinary configurations, checked in
the tests against a central difference and Richardson extrapolation).

Because GLI and dGLI only depend on differences of points, both are invariant under
translations; they are invariant under rotations about ``up`` and dGLI scales as
``1 / lambda`` when all points are scaled by ``lambda``.

Degenerate input
----------------
* A NaN in any input point gives NaN (a missing segment stays missing).
* Touching segments (a shared point, an endpoint on the other segment, crossing
  interiors) are coplanar: their GLI is exactly 0 and their dGLI is *defined* as 0 (the
  one-sided derivatives may diverge there).
* Near-intersecting pairs have a dGLI that grows like one over their distance. Its
  magnitude is clipped at ``clip / mean(|b - a|, |d - c|)`` (``clip`` defaults to
  :data:`DEFAULT_CLIP`), keeping the sign; the bound scales like the dGLI itself, so the
  clipping commutes with a change of units (paper section 3.3).
* A zero-length segment has GLI 0; its dGLI is the exact derivative (the segment grows
  out of a point), which is finite unless it touches the other one.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["DEFAULT_CLIP", "cloth_coordinates", "dgli", "gli", "pair_indices"]

#: Default clipping factor: ``|dGLI| <= DEFAULT_CLIP / mean segment length`` of the pair.
#: Two perpendicular segments of length L crossing at a distance L / 100 have
#: ``|dGLI| ~ 10 / L``; ordinary cloth pairs stay below ``1 / L``.
DEFAULT_CLIP = 25.0

#: Pairs per block in the vectorised kernel: small enough for the ~40 temporaries of a
#: block to stay in the CPU cache, large enough to amortise numpy's per-call overhead.
_BLOCK = 8192

_INV_2PI = 1.0 / (2.0 * np.pi)

#: |p . (q x r)| below this times |p||q||r| counts as coplanar (a few rounding errors).
_COPLANAR_RTOL = 1e-13


def pair_indices(m: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Indices ``(i, j)``, ``i < j``, of all pairs of ``m`` segments in row-major order.

    Parameters
    ----------
    m : int
        Number of segments.

    Returns
    -------
    i, j : ndarray of intp, shape (m (m - 1) / 2,)
        ``(0, 1), (0, 2), ..., (0, m-1), (1, 2), ..., (m-2, m-1)``.
    """
    if m < 0:
        raise ValueError(f"m must be non-negative, got {m}")
    i, j = _pair_indices(m)
    return i.copy(), j.copy()


@lru_cache(maxsize=16)
def _pair_indices(m: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    i, j = np.triu_indices(m, k=1)
    i.flags.writeable = False
    j.flags.writeable = False
    return i, j


def _frame(up: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrix (3, 3) whose third row is ``up / |up|`` (rows orthonormal)."""
    u = np.asarray(up, dtype=np.float64)
    if u.shape == (3,):
        return _frame_cached(float(u[0]), float(u[1]), float(u[2]))
    raise ValueError(f"up must be a 3-vector, got shape {u.shape}")


@lru_cache(maxsize=64)
def _frame_cached(x: float, y: float, z: float) -> NDArray[np.float64]:
    u = np.array([x, y, z])
    if u.shape != (3,):
        raise ValueError(f"up must be a 3-vector, got shape {u.shape}")
    # (a vector's norm as np.linalg.norm takes it, sqrt(x . x), without its overhead:
    # a new up every frame)
    norm = math.sqrt(u.dot(u))
    if not math.isfinite(norm) or norm == 0.0:
        raise ValueError(f"up must be a finite non-zero vector, got {u.tolist()}")
    e3 = u / norm
    helper = np.array([1.0, 0.0, 0.0]) if abs(e3[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = _cross3(helper, e3)
    e1 /= math.sqrt(e1.dot(e1))
    e2 = _cross3(e3, e1)
    rot = np.stack([e1, e2, e3])
    rot.flags.writeable = False
    return rot


def _cross3(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """``np.cross`` of two 3-vectors, the same products and differences in floats (a
    new ``up`` every frame: np.cross costs ten times more)."""
    (a0, a1, a2), (b0, b1, b2) = a.tolist(), b.tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _points(x: ArrayLike, name: str) -> NDArray[np.float64]:
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim == 0 or arr.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (..., 3), got {arr.shape}")
    return arr


class _Workspace:
    """Scratch rows for the kernel, reused across blocks so that no temporaries are made.

    ``rows`` is a float64 array (_ROWS, n); row ranges are named in :func:`_dgli_z`.
    """

    def __init__(self, n: int) -> None:
        self.rows = np.empty((_ROWS, n))

    def view(self, n: int) -> NDArray[np.float64]:
        return self.rows[:, :n]


_ROWS = 40


def _dot(x: NDArray, y: NDArray, out: NDArray, tmp: NDArray) -> NDArray:
    """Row-wise dot product of component-major (3, n) arrays into ``out`` (n,)."""
    np.multiply(x[0], y[0], out=out)
    np.multiply(x[1], y[1], out=tmp)
    out += tmp
    np.multiply(x[2], y[2], out=tmp)
    out += tmp
    return out


def _dgli_z(w: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unclipped dGLI with ``up = +z``, computed in place in a workspace.

    ``w`` is a workspace view (_ROWS, n) whose rows 0-11 hold, component-major, the four
    Gauss-map corners ``p = a - c`` (rows 0-2: x, y, z), ``q = b - c`` (3-5),
    ``r = b - d`` (6-8) and ``s = a - d`` (9-11) of n pairs. Returns a view (n,) of ``w``
    (overwritten by the next call). Touching pairs give NaN here (0 / 0); the caller maps
    them to 0. Every line is one numpy call writing into a preallocated row: this keeps a
    block in cache and runs about 4x faster than the same formulas with temporaries.
    """
    p, q, r, s = w[0:3], w[3:6], w[6:9], w[9:12]
    t, u = w[12], w[13]
    mul, div = np.multiply, np.divide
    # Norms (n,).
    np_ = np.sqrt(_dot(p, p, w[14], t), out=w[14])
    nq = np.sqrt(_dot(q, q, w[15], t), out=w[15])
    nr = np.sqrt(_dot(r, r, w[16], t), out=w[16])
    ns = np.sqrt(_dot(s, s, w[17], t), out=w[17])
    p_q = _dot(p, q, w[18], t)
    p_r = _dot(p, r, w[19], t)
    q_r = _dot(q, r, w[20], t)
    p_s = _dot(p, s, w[21], t)
    r_s = _dot(r, s, w[22], t)
    # N = p . (q x r), the same for both triangles (p . (r x s)) since s = p - q + r.
    n = w[23]
    mul(q[1], r[2], out=n)
    mul(q[2], r[1], out=t)
    n -= t
    n *= p[0]
    mul(q[2], r[0], out=u)
    mul(q[0], r[2], out=t)
    u -= t
    u *= p[1]
    n += u
    mul(q[0], r[1], out=u)
    mul(q[1], r[0], out=t)
    u -= t
    u *= p[2]
    n += u
    # D1 = |q| K + (p.q)|r| + (q.r)|p| and D2 = |s| K + (p.s)|r| + (r.s)|p|, K = |p||r| + p.r
    k = mul(np_, nr, out=w[24])
    k += p_r
    d1 = mul(nq, k, out=w[25])
    d1 += mul(p_q, nr, out=t)
    d1 += mul(q_r, np_, out=t)
    d2 = mul(ns, k, out=w[26])
    d2 += mul(p_s, nr, out=t)
    d2 += mul(r_s, np_, out=t)
    # dN/de = z . (r x p) for both triangles (q moves by +z, s by -z).
    m = mul(p[1], r[0], out=w[27])
    m -= mul(p[0], r[1], out=t)
    # dD1/de = (q_z / |q|) K + J and dD2/de = -((s_z / |s|) K + J), J = p_z |r| + r_z |p|.
    j = mul(p[2], nr, out=w[28])
    j += mul(r[2], np_, out=t)
    dd1 = div(q[2], nq, out=w[29])
    dd1 *= k
    dd1 += j
    md2 = div(s[2], ns, out=w[30])  # minus dD2/de
    md2 *= k
    md2 += j
    nn = mul(n, n, out=w[31])
    # dOmega_i / 2 = (D_i N' - N D_i') / (N^2 + D_i^2).
    t1 = mul(d1, m, out=w[32])
    t1 -= mul(n, dd1, out=t)
    t1 /= np.add(mul(d1, d1, out=u), nn, out=u)
    t2 = mul(d2, m, out=w[33])
    t2 += mul(n, md2, out=t)
    t2 /= np.add(mul(d2, d2, out=u), nn, out=u)
    # dGLI = -(dOmega1 + dOmega2) / (4 pi).
    t1 += t2
    t1 *= -_INV_2PI
    # Coplanar crossing interiors (N = 0 with a quadrilateral spanning the full circle,
    # D <= 0) touch: defined as 0. D <= 0 is rare otherwise, so test N only there.
    suspect = np.flatnonzero(np.minimum(d1, d2, out=t) <= 0.0)
    if suspect.size:
        scale = np_[suspect] * nq[suspect] * nr[suspect]
        t1[suspect[np.abs(n[suspect]) <= _COPLANAR_RTOL * scale]] = 0.0
    return t1


#: Up to this many pairs (one frame's 28 of 8 segments), :func:`_dgli_z_small`: the
#: same formulas as :func:`_dgli_z` on stacked rows, a third of its numpy calls (whose
#: overhead, not arithmetic, is what a few pairs cost).
_SMALL = 256

#: Rows of :func:`_dgli_z_small`'s dot products, as (left, right) corner indices (p 0,
#: q 1, r 2, s 3): |p|^2, |r|^2, |q|^2, |s|^2, p.r, p.q, p.s, q.r, r.s.
_DOT_LEFT = np.array([0, 2, 1, 3, 0, 0, 0, 1, 2])
_DOT_RIGHT = np.array([0, 2, 1, 3, 2, 1, 3, 2, 3])
#: Component orders of the cross product q x r: (q[1] r[2] - q[2] r[1], ...).
_CROSS_A = np.array([1, 2, 0])
_CROSS_B = np.array([2, 0, 1])


def _dgli_z_small(corners: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`_dgli_z` of the corners (4, 3, n) (p, q, r, s, component-major), bit for
    bit: every element goes through the same operations in the same order, on stacked
    rows (the four norms, the five dot products, both triangles at once)."""
    p, r = corners[0], corners[2]
    prod = np.multiply(corners[_DOT_LEFT], corners[_DOT_RIGHT])  # (9, 3, n)
    dots = np.add(prod[:, 0], prod[:, 1])  # (x0 y0 + x1 y1) + x2 y2, as _dot sums
    dots += prod[:, 2]
    norms = np.sqrt(dots[:4])  # |p|, |r|, |q|, |s|
    np_, nr, nq_ns = norms[0], norms[1], norms[2:4]
    q = corners[1]
    cross = np.multiply(q[_CROSS_A], r[_CROSS_B])
    cross -= np.multiply(q[_CROSS_B], r[_CROSS_A])
    cross *= p
    n = np.add(cross[0], cross[1])  # N = p . (q x r)
    n += cross[2]
    k = np.multiply(np_, nr)
    k += dots[4]  # K = |p||r| + p.r
    d = np.multiply(nq_ns, k)  # D1, D2
    d += np.multiply(dots[5:7], nr)
    d += np.multiply(dots[7:9], np_)
    m = np.multiply(p[1], r[0])
    m -= np.multiply(p[0], r[1])
    j = np.multiply(p[2], nr)
    j += np.multiply(r[2], np_)
    dd = np.divide(corners[1::2, 2], nq_ns)  # dD1/de and minus dD2/de
    dd *= k
    dd += j
    t = np.multiply(d, m)
    ndd = np.multiply(n, dd)
    t[0] -= ndd[0]
    t[1] += ndd[1]
    den = np.multiply(d, d)
    den += np.multiply(n, n)
    t /= den
    out = np.add(t[0], t[1])
    out *= -_INV_2PI
    suspect = np.flatnonzero(np.minimum(d[0], d[1]) <= 0.0)
    if suspect.size:
        scale = np_[suspect] * nq_ns[0][suspect] * nr[suspect]
        out[suspect[np.abs(n[suspect]) <= _COPLANAR_RTOL * scale]] = 0.0
    return out


def _load_corners(w: NDArray, a: NDArray, b: NDArray, c: NDArray, d: NDArray) -> None:
    """Write the corners p, q, r, s of endpoint arrays (3, ...) into ``w[0:4]`` (4, 3, ...)."""
    np.subtract(a, c, out=w[0])
    np.subtract(b, c, out=w[1])
    np.subtract(b, d, out=w[2])
    np.subtract(a, d, out=w[3])


def _finish(raw: NDArray, bound: NDArray, nan_in: NDArray | None) -> NDArray:
    """Map touching pairs (NaN from 0 / 0, not from input) to 0 and clip at ``bound``."""
    bad = np.isnan(raw)
    if bad.any():
        fix = bad if nan_in is None else bad & ~nan_in
        raw[fix] = 0.0
    np.clip(raw, -bound, bound, out=raw)
    return raw


def _dgli_blocks(
    a: NDArray, b: NDArray, c: NDArray, d: NDArray, bound: NDArray
) -> NDArray[np.float64]:
    """dGLI (up = +z) of component-major arrays (3, n), clipped at ``bound`` (n,)."""
    n_pairs = a.shape[1]
    out = np.empty(n_pairs)
    ws = _Workspace(min(_BLOCK, n_pairs))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for lo in range(0, n_pairs, _BLOCK):
            hi = min(lo + _BLOCK, n_pairs)
            w = ws.view(hi - lo)
            corners = w[:12].reshape(4, 3, hi - lo)
            _load_corners(corners, a[:, lo:hi], b[:, lo:hi], c[:, lo:hi], d[:, lo:hi])
            raw = _dgli_z(w)
            nan_in = None
            if np.isnan(raw).any():
                block = np.concatenate([x[:, lo:hi] for x in (a, b, c, d)])
                nan_in = np.isnan(block).any(axis=0)
            out[lo:hi] = _finish(raw, bound[lo:hi], nan_in)
    return out


def gli(a: ArrayLike, b: ArrayLike, c: ArrayLike, d: ArrayLike) -> NDArray[np.float64]:
    """Gauss linking integral of the segments ``a -> b`` and ``c -> d``.

    Parameters
    ----------
    a, b, c, d : array_like, shape (..., 3)
        Segment endpoints; leading dimensions broadcast.

    Returns
    -------
    ndarray of float64, shape (...)
        The GLI, including the 1 / (4 pi) factor, in (-1/2, 1/2). 0 for coplanar and
        touching pairs, NaN where an input is NaN.
    """
    pa, pb, pc, pd = np.broadcast_arrays(*(_points(x, n) for x, n in zip((a, b, c, d), "abcd")))
    p = pa - pc
    q = pb - pc
    r = pb - pd
    s = pa - pd
    norms = [np.linalg.norm(v, axis=-1) for v in (p, q, r, s)]
    npn, nq, nr, ns = norms
    n = np.einsum("...i,...i->...", p, np.cross(q, r))

    def dot(x: NDArray, y: NDArray) -> NDArray:
        return np.einsum("...i,...i->...", x, y)

    d1 = npn * nq * nr + dot(p, q) * nr + dot(p, r) * nq + dot(q, r) * npn
    d2 = npn * nr * ns + dot(p, r) * ns + dot(p, s) * nr + dot(r, s) * npn
    with np.errstate(invalid="ignore"):
        omega = 2.0 * (np.arctan2(n, d1) + np.arctan2(n, d2))
        # |GLI| < 1/2 for non-intersecting pairs; rounding at near-crossings (error about
        # 1e-16 L / gap) could step over it.
        result = np.clip(-omega / (4.0 * np.pi), -0.5, 0.5)
        scale = npn + nq + nr + ns
        touching = np.minimum(np.minimum(npn, nq), np.minimum(nr, ns)) <= 1e-12 * scale
        coplanar = np.abs(n) <= _COPLANAR_RTOL * npn * nq * nr
    return np.where(touching | coplanar, 0.0, result)


def dgli(
    a: ArrayLike,
    b: ArrayLike,
    c: ArrayLike,
    d: ArrayLike,
    up: ArrayLike = (0.0, 0.0, 1.0),
    *,
    clip: float = DEFAULT_CLIP,
) -> NDArray[np.float64]:
    """Directional derivative of the GLI when ``b`` and ``d`` move along ``up``.

    Exact (closed-form) derivative, see the module docstring.

    Parameters
    ----------
    a, b, c, d : array_like, shape (..., 3)
        Segment endpoints of ``a -> b`` and ``c -> d``; leading dimensions broadcast.
    up : array_like, shape (3,)
        Direction of motion (normalised here), e.g. the table normal.
    clip : float, keyword-only
        Magnitudes are clipped at ``clip / mean(|b - a|, |d - c|)``, keeping the sign.
        ``np.inf`` disables clipping.

    Returns
    -------
    ndarray of float64, shape (...)
        dGLI in inverse units of the input coordinates. NaN where an input is NaN; 0 for
        touching segments.
    """
    rot = _frame(up)
    pts = np.broadcast_arrays(*(_points(x, n) for x, n in zip((a, b, c, d), "abcd")))
    shape = pts[0].shape[:-1]
    # Rotate so that up is +z and go component-major: each (3, n).
    cm = [np.ascontiguousarray((x.reshape(-1, 3) @ rot.T).T) for x in pts]
    len_ab = np.sqrt(((cm[1] - cm[0]) ** 2).sum(axis=0))
    len_cd = np.sqrt(((cm[3] - cm[2]) ** 2).sum(axis=0))
    with np.errstate(divide="ignore"):
        bound = clip / (0.5 * (len_ab + len_cd))
    bound = np.where(np.isnan(bound), np.inf, bound)
    return _dgli_blocks(*cm, bound).reshape(shape)


def cloth_coordinates(
    segments: ArrayLike, up: ArrayLike = (0.0, 0.0, 1.0), *, clip: float = DEFAULT_CLIP
) -> NDArray[np.float64]:
    """dGLI cloth coordinates: the dGLI of every pair of segments.

    Parameters
    ----------
    segments : array_like, shape (..., m, 2, 3)
        ``m`` oriented segments (start, end) per state; leading dimensions are a batch.
        NaN marks a missing segment.
    up : array_like, shape (3,)
        The direction of the derivative (table normal, pointing away from the table).
    clip : float, keyword-only
        Clipping factor, see :func:`dgli`.

    Returns
    -------
    ndarray of float64, shape (..., m (m - 1) / 2)
        ``dgli(seg_i start, seg_i end, seg_j start, seg_j end)`` for ``i < j`` in
        row-major order (0-1, 0-2, ..., (m-2)-(m-1)); NaN where either segment is missing.
    """
    seg = np.asarray(segments, dtype=np.float64)
    if seg.ndim < 3 or seg.shape[-2:] != (2, 3):
        raise ValueError(f"segments must have shape (..., m, 2, 3), got {seg.shape}")
    m = seg.shape[-3]
    batch = seg.shape[:-3]
    i, j = _pair_indices(m)
    n_pairs = len(i)
    rot = _frame(up)
    flat = (seg.reshape(-1, 3) @ rot.T).reshape(-1, m, 2, 3)  # (B, m, 2, 3), up is +z
    # States last, so that gathering the segments of the pairs copies contiguous rows:
    # (2, 3, m, B) = endpoint (start, end), component, segment, state.
    comp = np.ascontiguousarray(flat.transpose(2, 3, 1, 0))
    length = np.sqrt(((comp[1] - comp[0]) ** 2).sum(axis=0))  # (m, B)
    n_states = comp.shape[-1]
    out = np.empty((n_states, n_pairs))
    if n_pairs == 0 or n_states == 0:
        return out.reshape((*batch, n_pairs))
    states_per_block = max(1, _BLOCK // n_pairs)
    ws = _Workspace(min(states_per_block, n_states) * n_pairs)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for lo in range(0, n_states, states_per_block):
            hi = min(lo + states_per_block, n_states)
            out[lo:hi] = _state_block(comp[..., lo:hi], length[:, lo:hi], i, j, clip, ws).T
    return out.reshape((*batch, n_pairs))


def _state_block(
    comp: NDArray[np.float64],
    length: NDArray[np.float64],
    i: NDArray[np.intp],
    j: NDArray[np.intp],
    clip: float,
    ws: _Workspace,
) -> NDArray[np.float64]:
    """Clipped dGLI (P, nb) of the pairs ``(i, j)`` of a block of nb states.

    ``comp`` (2, 3, m, nb) holds the segments' endpoints (start, end), component-major,
    states last; ``length`` (m, nb) their lengths. Computed in the workspace ``ws``.
    """
    n_pairs, nb = len(i), comp.shape[-1]
    small = nb * n_pairs <= _SMALL
    w = None if small else ws.view(nb * n_pairs)
    start = comp[0]  # (3, m, nb)
    end = comp[1]
    # Corners p, q, r, s as (3, P, nb) views of workspace rows.
    corners = np.empty((4, 3, n_pairs, nb)) if w is None else w[:12].reshape(4, 3, n_pairs, nb)
    s_i, e_i = start.take(i, axis=1), end.take(i, axis=1)  # (3, P, nb)
    s_j, e_j = start.take(j, axis=1), end.take(j, axis=1)
    _load_corners(corners, s_i, e_i, s_j, e_j)
    if w is None:
        raw = _dgli_z_small(corners.reshape(4, 3, -1)).reshape(n_pairs, nb)
    else:
        raw = _dgli_z(w).reshape(n_pairs, nb)
    bound = length.take(i, axis=0)  # (P, nb)
    bound += length.take(j, axis=0)
    np.divide(2.0 * clip, bound, out=bound)
    bound[np.isnan(bound)] = np.inf
    nan_in = None
    if np.isnan(raw).any():
        missing = np.isnan(comp).any(axis=(0, 1))  # (m, nb)
        nan_in = missing[i] | missing[j]
    return _finish(raw, bound, nan_in)
