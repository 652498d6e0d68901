"""Material coordinates of a simulated cloth: where each vertex lies on the flat napkin.

With a particle grid, the grid gives them (its spacing measured on the rest frame). A
mesh without a grid is flattened: its rest frame (the first frame, or another file's)
is projected onto its best plane, the border is the edges used by one triangle only,
and the corners are the four sharpest turns of the border. Corner A is the grid's first
vertex (or the corner with the lowest vertex index); B, C and D follow
counter-clockwise seen from above, so the face looking up at rest is the front.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import Delaunay, cKDTree

from ..core.errors import InvalidInputError
from .episodes import ClothEpisode

__all__ = [
    "CORNER_TURN_TOLERANCE_DEG",
    "FLAT_TOLERANCE",
    "MAX_SIDE_MM",
    "RECTANGLE_TOLERANCE",
    "REST_FRONT_SHARE",
    "REST_OUTLINE_SHARE",
    "SIZE_TOLERANCE",
    "VISIBILITY_VERTICES",
    "ClothMaterial",
    "cloth_material",
    "front_share",
    "locate",
]

#: A rest frame whose points leave its best plane by more than this share of the
#: cloth's longer side is not flat (wrinkles of a few mm on 400 mm pass).
FLAT_TOLERANCE = 0.05
#: Each of the four corners must turn the border by 90 degrees within this.
CORNER_TURN_TOLERANCE_DEG = 25.0
#: The border may leave the quadrilateral of the corners by this share of the shorter
#: side, and opposite sides may differ by this share, for the cloth to be a rectangle.
RECTANGLE_TOLERANCE = 0.06
#: A cloth measured longer than this (mm) on a side is taken for wrong units (a napkin
#: in mm read as metres measures hundreds of metres).
MAX_SIDE_MM = 10_000.0
#: A flat rest frame shows its front over this share of its area at least: the signed
#: area of its triangles seen from above over their area (a flap folded over counts
#: against it twice; wrinkles of a few mm leave it above 0.99).
REST_FRONT_SHARE = 0.95
#: A flat rest frame's outline (the convex hull of its points on its best plane) covers
#: this share of the cloth's own area (its triangles' area) at least: a corner folded
#: over leaves about 0.9, a strip 0.66, a half fold 0.5; wrinkles of a few mm, 0.998.
REST_OUTLINE_SHARE = 0.95
#: ``--size`` may differ from the size the rest frame measures in ``--units`` by this
#: share when that size is a napkin's (each side :func:`~dgli_vision.core.layout.
#: smallest_side_mm` to :data:`LARGEST_NAPKIN_MM`): beyond it one of the two is wrong.
SIZE_TOLERANCE = 0.05
#: The longest napkin side ``--size`` takes, mm (as ``dgli render --size``).
LARGEST_NAPKIN_MM = 1000.0
#: About this many vertices make the coarse mesh that is raycast for visibility: about
#: 15 mm apart on a 400 mm napkin, half a sticker, and 0.3 ms a frame.
VISIBILITY_VERTICES = 700


@dataclass(frozen=True, eq=False)
class ClothMaterial:
    """Where the vertices of a cloth lie on the flat napkin, and its coarse mesh.

    Attributes
    ----------
    uv : ndarray, shape (N, 2)
        Material coordinates, mm: A at (0, 0), u towards B, v towards D.
    faces : ndarray of int, shape (F, 3)
        Triangles, counter-clockwise in (u, v) (their normal is the front face's).
    size_mm : tuple of float
        The cloth's size (W, H), mm.
    corners : ndarray of int, shape (4,)
        Vertex ids of corners A, B, C, D.
    scale : float
        Factor the positions are multiplied by to measure ``size_mm`` (1 unless the size
        was given).
    coarse_ids : ndarray of int, shape (M,)
        Vertices of the coarse mesh raycast for visibility.
    coarse_faces : ndarray of int, shape (Fc, 3)
        Its triangles, indices into ``coarse_ids``.
    spacing_mm : float
        The coarse mesh's vertex spacing, mm.
    """

    uv: NDArray[np.float64]
    faces: NDArray[np.int64]
    size_mm: tuple[float, float]
    corners: NDArray[np.int64]
    scale: float
    coarse_ids: NDArray[np.int64]
    coarse_faces: NDArray[np.int64]
    spacing_mm: float


def locate(
    uv: NDArray[np.float64], faces: NDArray[np.int64], points: NDArray[np.float64]
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The triangle holding each material point and its barycentric weights.

    Parameters
    ----------
    uv : ndarray, shape (N, 2)
    faces : ndarray, shape (F, 3)
    points : ndarray, shape (k, 2)

    Returns
    -------
    face : ndarray of int, shape (k,)
    weights : ndarray, shape (k, 3)
        Of the face's three vertices, summing to 1 (a point just outside every face,
        on the border, gets the nearest face's clipped weights).
    """
    a, b, c = (uv[faces[:, i]] for i in range(3))
    m = np.stack([b - a, c - a], axis=-1)  # (F, 2, 2)
    det = m[:, 0, 0] * m[:, 1, 1] - m[:, 0, 1] * m[:, 1, 0]
    ok = np.abs(det) > 1e-12
    inv = np.zeros_like(m)
    inv[ok, 0, 0], inv[ok, 1, 1] = m[ok, 1, 1] / det[ok], m[ok, 0, 0] / det[ok]
    inv[ok, 0, 1], inv[ok, 1, 0] = -m[ok, 0, 1] / det[ok], -m[ok, 1, 0] / det[ok]
    pts = np.asarray(points, dtype=np.float64)
    # candidates: the faces whose centres are nearest each point (all of them for small
    # meshes); a point inside none of them (or with no candidates) tries every face
    near = min(len(faces), 24)
    cand = cKDTree((a + b + c) / 3).query(pts, k=near)[1].reshape(len(pts), near)
    face = np.empty(len(pts), np.int64)
    weights = np.empty((len(pts), 3))
    for k, q in enumerate(pts):
        for ids in (cand[k], np.arange(len(faces))):
            lam = np.einsum("fij,fj->fi", inv[ids], q - a[ids])  # (f, 2)
            bary = np.column_stack([1 - lam.sum(axis=1), lam])
            worst = np.where(ok[ids], bary.min(axis=1), -np.inf)
            best = int(np.argmax(worst))
            if worst[best] >= -1e-9:
                break
        face[k] = ids[best]
        w = np.clip(bary[best], 0.0, None)
        weights[k] = w / w.sum()
    return face, weights


def _grid_material(ep: ClothEpisode, rest: NDArray) -> tuple[NDArray, NDArray, tuple]:
    """uv (N, 2), corner ids and size from a particle grid and its rest frame."""
    rows, cols = ep.grid
    g = rest.reshape(rows, cols, 3)
    du = float(np.linalg.norm(np.diff(g, axis=1), axis=-1).mean()) * 1e3
    dv = float(np.linalg.norm(np.diff(g, axis=0), axis=-1).mean()) * 1e3
    # which way the grid runs seen from above: the sign of its cells' summed area (a
    # flap folded over turns its cells round, but it is never most of the cloth)
    e_row, e_col = g[:-1, 1:] - g[:-1, :-1], g[1:, :-1] - g[:-1, :-1]
    ccw = (e_row[..., 0] * e_col[..., 1] - e_row[..., 1] * e_col[..., 0]).sum() > 0
    r, c = np.divmod(np.arange(rows * cols), cols)
    if ccw:  # u along the first row, v along the first column
        uv = np.column_stack([c * du, r * dv])
        corners = np.array([0, cols - 1, rows * cols - 1, (rows - 1) * cols])
        size = ((cols - 1) * du, (rows - 1) * dv)
    else:
        uv = np.column_stack([r * dv, c * du])
        corners = np.array([0, (rows - 1) * cols, rows * cols - 1, cols - 1])
        size = ((rows - 1) * dv, (cols - 1) * du)
    return uv, corners, size


def _check_up(path: str, rest: NDArray) -> None:
    """Refuse a flat rest frame that does not lie on the table (a wrong up axis)."""
    centred = rest - rest.mean(axis=0)
    vt = np.linalg.svd(centred, full_matrices=False)[2]
    flat = np.abs(centred @ vt[2]).max() <= FLAT_TOLERANCE * float(np.ptp(centred @ vt[0]))
    if flat and abs(vt[2][2]) < np.cos(np.radians(60)):
        raise InvalidInputError(
            f"'{path}': the rest frame is flat but stands on its edge (its plane is "
            f"{np.degrees(np.arccos(abs(vt[2][2]))):.0f} degrees from the table's): "
            "is --up-axis right?"
        )


def _check_spread(path: str, rest: NDArray) -> None:
    """Refuse a rest frame whose vertices all coincide or lie on one line."""
    centred = rest - rest.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    if not sv[0] > 1e-9:
        raise InvalidInputError(
            f"'{path}': all {len(rest)} vertices of the rest frame lie at one point"
        )
    if not sv[1] > 1e-6 * sv[0]:
        raise InvalidInputError(f"'{path}': the rest frame's vertices lie on one line")


def _plane(path: str, rest: NDArray) -> tuple[NDArray, NDArray, NDArray]:
    """The rest frame centred, and its best plane's axes (e1, normal up), after
    checking that it is flat to :data:`FLAT_TOLERANCE` of its side."""
    centred = rest - rest.mean(axis=0)
    vt = np.linalg.svd(centred, full_matrices=False)[2]
    normal = vt[2] if vt[2][2] >= 0 else -vt[2]
    off = np.abs(centred @ normal).max()
    extent = float(np.ptp(centred @ vt[0]))
    if off > FLAT_TOLERANCE * extent:
        raise InvalidInputError(
            f"'{path}': the rest frame is not flat (points {off * 1e3:.0f} mm off its plane); "
            "give the flat cloth with --rest FILE"
        )
    return centred, vt[0], normal


def _flatten(path: str, rest: NDArray) -> NDArray[np.float64]:
    """The rest frame projected on its best plane, 2D (N, 2) metres, seen from above."""
    centred, e1, normal = _plane(path, rest)
    e2 = np.cross(normal, e1)
    return np.column_stack([centred @ e1, centred @ e2])


def front_share(positions: NDArray[np.float64], faces: NDArray[np.int64]) -> NDArray:
    """Signed area of the triangles seen from above over their area, per frame: 1 for a
    cloth lying flat with the face of its triangles' winding up, -1 turned over, about 0
    folded in half.

    Parameters
    ----------
    positions : ndarray, shape (..., N, 3)
        z up.
    faces : ndarray of int, shape (F, 3)
    """
    a, b, c = (positions[..., faces[:, i], :] for i in range(3))
    n = np.cross(b - a, c - a)
    total = np.linalg.norm(n, axis=-1).sum(axis=-1)
    up = n[..., 2].sum(axis=-1)
    return np.divide(up, total, out=np.zeros_like(up), where=total > 0)


def _oriented(faces: NDArray[np.int64]) -> NDArray[np.int64] | None:
    """The triangles with one winding throughout (each edge inside the mesh run both
    ways by its two triangles), turned from the first of each piece; None when the
    mesh cannot be oriented."""
    faces = np.asarray(faces, dtype=np.int64)
    by_edge: dict[tuple[int, int], list[int]] = {}
    for f, tri in enumerate(faces.tolist()):
        for k in range(3):
            a, b = tri[k], tri[(k + 1) % 3]
            by_edge.setdefault((min(a, b), max(a, b)), []).append(f)
    flip = np.full(len(faces), -1, dtype=np.int8)
    for seed in range(len(faces)):
        if flip[seed] >= 0:
            continue
        flip[seed] = 0
        todo = [seed]
        while todo:
            f = todo.pop()
            tri = faces[f][::-1] if flip[f] else faces[f]
            for k in range(3):
                a, b = int(tri[k]), int(tri[(k + 1) % 3])
                for g in by_edge[(min(a, b), max(a, b))]:
                    if g == f:
                        continue
                    other = faces[g].tolist()
                    i = other.index(a)
                    same_way = other[(i + 1) % 3] == b  # g runs a -> b too: turn it
                    want = 1 if same_way else 0
                    if flip[g] < 0:
                        flip[g] = want
                        todo.append(g)
                    elif flip[g] != want:
                        return None
    out = faces.copy()
    out[flip == 1] = out[flip == 1][:, ::-1]
    return out


def _rest_layers(rest: NDArray, faces: NDArray) -> tuple[float, float]:
    """How far the rest frame is from lying flat in one layer: the share of its area
    turned over (from its triangles' winding made consistent; 0 when it cannot be made
    so) and the share of its own area its outline covers on its best plane."""
    from scipy.spatial import ConvexHull, QhullError

    oriented = _oriented(faces)
    turned = 0.0 if oriented is None else (1.0 - abs(float(front_share(rest, oriented)))) / 2
    a, b, c = (rest[faces[:, i]] for i in range(3))
    area = 0.5 * float(np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())
    centred = rest - rest.mean(axis=0)
    vt = np.linalg.svd(centred, full_matrices=False)[2]
    try:  # (2D: the hull's "volume" is its area)
        outline = float(ConvexHull(centred @ vt[:2].T).volume)
    except QhullError:  # all on one line: _check_spread has refused it before
        outline = 0.0
    return turned, (outline / area if area > 0 else 1.0)


def _check_rest_flat(path: str, rest: NDArray, faces: NDArray) -> None:
    """Refuse a rest frame that is not the cloth lying flat in one layer: a part of it
    turned over (a fold settled on the table lies as flat as the cloth), or an outline
    smaller than the cloth (a fold, a flap held up, a crumple)."""
    turned, outline = _rest_layers(rest, faces)
    if 1.0 - 2.0 * turned < REST_FRONT_SHARE or outline < REST_OUTLINE_SHARE:
        raise InvalidInputError(
            f"'{path}': the rest frame is folded ({turned:.0%} of the cloth lies turned "
            f"over; its outline covers {outline:.0%} of the cloth's area, a flat cloth's "
            f"{REST_OUTLINE_SHARE:.0%} or more), and every state is measured from the flat "
            "cloth: give it with --rest FILE"
        )


def _check_size(path: str, size: tuple[float, float], given: tuple[float, float],
                units: str) -> None:
    """Refuse a ``--size`` that a napkin-sized rest frame contradicts (see
    :data:`SIZE_TOLERANCE`); a rest frame of no napkin's size in ``units`` is in other
    units, and ``--size`` scales it."""
    from ..core.layout import smallest_side_mm

    lo = smallest_side_mm() * (1 - SIZE_TOLERANCE)
    if not all(lo <= s <= LARGEST_NAPKIN_MM * (1 + SIZE_TOLERANCE) for s in size):
        return
    off = max(abs(g / s - 1.0) for g, s in zip(given, size))
    if off > SIZE_TOLERANCE:
        raise InvalidInputError(
            f"'{path}': --size {given[0]:g}x{given[1]:g} mm, but the cloth measures "
            f"{size[0]:.0f} x {size[1]:.0f} mm at rest in --units {units} "
            f"({off:.0%} apart, more than {SIZE_TOLERANCE:.0%}): leave --size out, or give "
            "the unit the positions are in with --units"
        )


def _border_loop(path: str, faces: NDArray, border: NDArray | None, n: int) -> NDArray:
    """The border's vertices in order round its single loop."""
    if border is None:
        e = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), 1)
        edges, counts = np.unique(e, axis=0, return_counts=True)
        if (counts > 2).any():
            raise InvalidInputError(
                f"'{path}': the mesh is non-manifold ({int((counts > 2).sum())} edges shared "
                "by more than two triangles)"
            )
        border = edges[counts == 1]
    if len(border) == 0:
        raise InvalidInputError(f"'{path}': the mesh is closed: it has no border")
    nbrs: dict[int, list[int]] = {}
    for a, b in border:
        nbrs.setdefault(int(a), []).append(int(b))
        nbrs.setdefault(int(b), []).append(int(a))
    if any(len(v) != 2 for v in nbrs.values()):
        raise InvalidInputError(
            f"'{path}': the mesh's border is not a simple loop (a non-manifold or open mesh)"
        )
    start = min(nbrs)
    loop, prev, cur = [start], -1, start
    while True:
        nxt = nbrs[cur][0] if nbrs[cur][0] != prev else nbrs[cur][1]
        if nxt == start:
            break
        loop.append(nxt)
        prev, cur = cur, nxt
    if len(loop) != len(nbrs):
        raise InvalidInputError(
            f"'{path}': the mesh's border has more than one loop (holes or pieces): "
            "not one rectangular cloth"
        )
    return np.array(loop, dtype=np.int64)


def _turns_deg(pts: NDArray) -> NDArray[np.float64]:
    """How far the closed polyline ``pts`` (m, 2) turns at each point, degrees, measured
    between points a fiftieth of its length before and after (left turns positive)."""
    seg = np.linalg.norm(np.roll(pts, -1, axis=0) - pts, axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    length = s[-1]
    closed = np.vstack([pts, pts[:1]])
    delta = length / 50

    def at(x: NDArray) -> NDArray:
        x = np.mod(x, length)
        return np.column_stack([np.interp(x, s, closed[:, i]) for i in range(2)])

    before, after = at(s[:-1] - delta), at(s[:-1] + delta)
    a, b = pts - before, after - pts
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return np.degrees(np.arctan2(cross, (a * b).sum(axis=1)))


def _corners(path: str, p2: NDArray, loop: NDArray) -> NDArray[np.int64]:
    """Positions in ``loop`` of the four sharpest turns, in loop order."""
    pts = p2[loop]
    turn = _turns_deg(pts)
    seg = np.linalg.norm(np.roll(pts, -1, axis=0) - pts, axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])[:-1]
    length = seg.sum()
    order, picked = np.argsort(-turn, kind="stable"), []
    for k in order:
        d = np.abs(s[k] - s[picked])
        if not picked or (np.minimum(d, length - d) > length / 8).all():
            picked.append(int(k))
        if len(picked) == 4:
            break
    picked.sort()
    bad = [turn[k] for k in picked if abs(turn[k] - 90) > CORNER_TURN_TOLERANCE_DEG]
    if len(picked) < 4 or bad:
        raise InvalidInputError(
            f"'{path}': the cloth is not rectangular (its border's four sharpest turns are "
            f"{', '.join(f'{turn[k]:.0f}' for k in picked)} degrees, not 90; the rest frame "
            "must be the flat cloth: give it with --rest FILE)"
        )
    return np.array(picked, dtype=np.int64)


def _check_rectangle(path: str, p2: NDArray, loop: NDArray, at: NDArray) -> tuple[float, float]:
    """Side lengths (W, H) in metres of the quadrilateral of the corners, after checking
    that the border follows it (``at``: the corners' positions in ``loop``)."""
    q = p2[loop[at]]
    sides = np.linalg.norm(np.roll(q, -1, axis=0) - q, axis=1)
    worst = 0.0
    for k in range(4):
        i, j = at[k], at[(k + 1) % 4]
        run = loop[i : j + 1] if j > i else np.concatenate([loop[i:], loop[: j + 1]])
        a, b = q[k], q[(k + 1) % 4]
        t = (b - a) / np.linalg.norm(b - a)
        rel = p2[run] - a
        worst = max(worst, float(np.abs(rel[:, 0] * t[1] - rel[:, 1] * t[0]).max()))
    w, h = (sides[0] + sides[2]) / 2, (sides[1] + sides[3]) / 2
    tol = RECTANGLE_TOLERANCE
    if worst > tol * min(w, h) or abs(sides[0] - sides[2]) > tol * w or (
        abs(sides[1] - sides[3]) > tol * h
    ):
        raise InvalidInputError(
            f"'{path}': the cloth is not rectangular (sides "
            f"{', '.join(f'{s * 1e3:.0f}' for s in sides)} mm; its border leaves the "
            f"corners' quadrilateral by {worst * 1e3:.0f} mm; the rest frame must be the "
            "flat cloth: give it with --rest FILE)"
        )
    return float(w), float(h)


def _triangulate(p2: NDArray) -> NDArray[np.int64]:
    """Delaunay triangles of 2D points, every point a vertex (joggled: a regular grid
    has points on the hull's edges that qhull would leave out)."""
    return Delaunay(p2, qhull_options="QJ").simplices.astype(np.int64)


def _mesh_material(ep: ClothEpisode, rest: NDArray) -> tuple[NDArray, NDArray, tuple, NDArray]:
    """uv, corner ids, size and faces of a mesh without a grid, from its flat rest."""
    p2 = _flatten(ep.path, rest)
    faces = ep.faces if len(ep.faces) else _triangulate(p2)
    loop = _border_loop(ep.path, faces, ep.border, len(rest))
    ring, nxt = p2[loop], np.roll(p2[loop], -1, axis=0)
    if (ring[:, 0] * nxt[:, 1] - nxt[:, 0] * ring[:, 1]).sum() < 0:  # clockwise: reverse
        loop = loop[::-1].copy()
    at = _corners(ep.path, p2, loop)
    w, h = _check_rectangle(ep.path, p2, loop, at)
    first = int(np.argmin(loop[at]))
    at = np.roll(at, -first)
    corners = loop[at]
    target = np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]]) * 1e3
    src = np.column_stack([p2[corners], np.ones(4)])
    affine, *_ = np.linalg.lstsq(src, target, rcond=None)
    uv = np.column_stack([p2, np.ones(len(p2))]) @ affine
    return uv, corners, (w * 1e3, h * 1e3), faces


def _coarse_mesh(uv: NDArray, size: tuple[float, float]) -> tuple[NDArray, NDArray, float]:
    """Vertices nearest a lattice about :data:`VISIBILITY_VERTICES` strong, and their
    Delaunay triangles in (u, v)."""
    w, h = size
    step = float(np.sqrt(w * h / VISIBILITY_VERTICES))
    gu = np.linspace(0, w, max(2, round(w / step) + 1))
    gv = np.linspace(0, h, max(2, round(h / step) + 1))
    lattice = np.stack(np.meshgrid(gu, gv), -1).reshape(-1, 2)
    ids = np.unique(cKDTree(uv).query(lattice)[1]).astype(np.int64)
    tri = _triangulate(uv[ids])
    a, b, c = (uv[ids][tri[:, i]] for i in range(3))
    area = (b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0]
    tri = tri[np.abs(area) > 1e-6 * step * step]
    return ids, tri, step


def _ccw(uv: NDArray, faces: NDArray) -> NDArray[np.int64]:
    """Faces reordered to run counter-clockwise in (u, v)."""
    a, b, c = (uv[faces[:, i]] for i in range(3))
    area = (b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0]
    out = faces.copy()
    out[area < 0] = out[area < 0][:, [0, 2, 1]]
    return out


def cloth_material(
    episode: ClothEpisode,
    rest: NDArray[np.float64] | None = None,
    size_mm: tuple[float, float] | None = None,
    *,
    units: str = "m",
) -> ClothMaterial:
    """Material coordinates of an episode's cloth.

    Parameters
    ----------
    episode : ClothEpisode
    rest : ndarray, shape (N, 3), optional
        The flat cloth at rest (metres, z up); default the episode's first frame.
    size_mm : tuple of float, optional
        The cloth's real size (W, H); default as measured on the rest frame. When given,
        the positions are to be scaled by :attr:`ClothMaterial.scale`.
    units : str, keyword-only
        The unit the positions were read in (named in the message refusing a
        ``size_mm`` the rest frame contradicts).

    Raises
    ------
    InvalidInputError
        The rest frame does not match the mesh, is not flat or lies folded (in layers,
        or with an outline smaller than the cloth), the mesh is open or non-manifold,
        the cloth is not rectangular, or ``size_mm`` differs by more than
        :data:`SIZE_TOLERANCE` from a napkin-sized rest frame's size.
    """
    rest = episode.frames(0, 1)[0] if rest is None else np.asarray(rest, dtype=np.float64)
    if rest.shape != (episode.n_vertices, 3):
        raise InvalidInputError(
            f"'{episode.path}': the rest frame has {len(rest)} vertices, the episode "
            f"{episode.n_vertices}"
        )
    _check_spread(episode.path, rest)
    _check_up(episode.path, rest)
    if size_mm is not None and not all(0 < s <= MAX_SIDE_MM for s in size_mm):
        raise InvalidInputError(
            f"'{episode.path}': --size {size_mm[0]:g} x {size_mm[1]:g} mm: a side must be "
            f"above 0 and at most {MAX_SIDE_MM / 1000:.0f} m"
        )
    _plane(episode.path, rest)  # within FLAT_TOLERANCE of its plane, then in one layer
    if len(episode.faces):
        _check_rest_flat(episode.path, rest, episode.faces)
    if episode.grid is not None:
        uv, corners, size = _grid_material(episode, rest)
        faces = episode.faces
    else:
        uv, corners, size, faces = _mesh_material(episode, rest)
    if size_mm is None and max(size) > MAX_SIDE_MM:
        raise InvalidInputError(
            f"'{episode.path}': the cloth measures {size[0]:.0f} x {size[1]:.0f} mm at rest; "
            "are --units right (or give its real --size)?"
        )
    scale = 1.0
    if size_mm is not None:
        _check_size(episode.path, size, size_mm, units)
        scale = float(np.mean([size_mm[0] / size[0], size_mm[1] / size[1]]))
        uv = uv * np.array([size_mm[0] / size[0], size_mm[1] / size[1]])
        size = (float(size_mm[0]), float(size_mm[1]))
    ids, tri, step = _coarse_mesh(uv, size)
    return ClothMaterial(
        uv=uv,
        faces=_ccw(uv, faces),
        size_mm=(round(float(size[0]), 1), round(float(size[1]), 1)),
        corners=np.asarray(corners, dtype=np.int64),
        scale=scale,
        coarse_ids=ids,
        coarse_faces=_ccw(uv[ids], tri),
        spacing_mm=step,
    )
