"""Each fold's geometry from a simulated cloth's mesh, and the distance from a goal.

A mesh knows every vertex's material place, so a fold's crease comes straight from it:
the vertices turned over (their front face looking down) make the flaps, one connected
piece of the flat napkin each; the vertices lying face up make the napkin that stays.
Folding is an isometry, so the same fit as the stickers'
(:mod:`dgli_vision.classifier.fold_geometry`: the napkin that stays placed on the
table by a rigid map, each flap its mirror image across its crease) finds every crease
at once, here from hundreds of points instead of a few stickers. The cloth bent round
its crease (neither face up nor down, and the vertices next to it) is left out, and
the crease is moved back by a
quarter turn's worth of the layers' gap (the flap lands short of its mirror image by
about pi / 2 thicknesses). What is left is the mesh's resolution.

A flap is matched to a fold word by the corners it carries (``"B over"``: B;
``"CD strip over"`` and ``"CD half"``: C and D; ``"B diagonal"``: B), the flap with
fewest other corners. A fold whose
flap is not turned over (in progress, held up) has no sizes, and ``why`` says so.

:func:`goal_distance` is the simulation benchmarks' measure of a fold: the goal's ideal
folded configuration (the flat cloth of the rest frame, each flap mirrored across the
goal's crease) against the cloth, the largest distance of any vertex.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..classifier.fold_geometry import (
    FoldGeometry,
    empty_geometry,
    geometry_from_crease,
    mirror_crease_fit,
    rigid_fit_2d,
    rotation_2d,
    solve_flaps,
)
from ..core.classes import CORNERS
from ..core.fold_measure import Crease, fold_kind
from ..core.layout import NapkinLayout
from .material import ClothMaterial

__all__ = [
    "FACE_DOWN_COS",
    "FACE_UP_COS",
    "MAX_FIT_POINTS",
    "MeshFlap",
    "goal_distance",
    "mesh_flaps",
    "mesh_fold_geometry",
]

#: A vertex whose front face's normal has a cosine with the up axis below this lies
#: turned over: on a flap laid flat (25 degrees from flat at most).
FACE_DOWN_COS = -0.9
#: ... and above this, face up: the napkin that stays (wrinkles tilt it a few degrees).
FACE_UP_COS = 0.9
#: A flap of fewer vertices than this is not a fold (a crumple).
MIN_FLAP_VERTICES = 6
#: A corner is on a flap when a vertex of the flap lies within this (mm, on the napkin).
CORNER_REACH_MM = 40.0
#: The floor of a vertex's misfit (mm, one coordinate) in the crease's uncertainty: the
#: vertices are exact, the bend round the crease is not (a quarter turn of the gap).
MESH_SD_MM = 0.5
#: The fit uses at most about this many vertices (evenly taken): a few thousand points
#: fix a crease far below the mesh's resolution.
MAX_FIT_POINTS = 1000


@dataclass(frozen=True)
class MeshFlap:
    """One flap found on a frame's mesh.

    Attributes
    ----------
    corners : str
        The napkin's corners on the flap (``"B"``, ``"CD"``), in ABCD order.
    crease : tuple
        ``((u, v), (du, dv))``: a point of the crease and its direction, material mm.
    cov : tuple
        The 2 x 2 covariance of the crease's normal angle (rad) and offset (mm).
    vertices : int
        Vertices of the flap used by the fit.
    rms_mm : float
        RMS distance of the flap's vertices from where the fit puts them.
    """

    corners: str
    crease: tuple[tuple[float, float], tuple[float, float]]
    cov: tuple[tuple[float, float], tuple[float, float]]
    vertices: int
    rms_mm: float

    def to_json(self) -> dict[str, Any]:
        """A plain dict (it travels between processes and through results.jsonl)."""
        return {"corners": self.corners, "crease": [list(p) for p in self.crease],
                "cov": [list(r) for r in self.cov], "vertices": self.vertices,
                "rms_mm": self.rms_mm}


def _vertex_up_cos(pos: NDArray[np.float64], faces: NDArray[np.int64]) -> NDArray[np.float64]:
    """Cosine of each vertex's front normal (area-weighted over its triangles, which
    run counter-clockwise in (u, v)) with the up axis, shape (N,)."""
    a, b, c = (pos[faces[:, i]] for i in range(3))
    n = np.cross(b - a, c - a)
    idx = faces.T.ravel()
    acc = np.stack([np.bincount(idx, weights=np.tile(n[:, k], 3), minlength=len(pos))
                    for k in range(3)], axis=1)
    norm = np.linalg.norm(acc, axis=1)
    return np.divide(acc[:, 2], norm, out=np.zeros(len(pos)), where=norm > 0)


def _inner(flags: NDArray[np.bool_], faces: NDArray[np.int64]) -> NDArray[np.bool_]:
    """The vertices ``flags`` whose triangles all have every vertex flagged."""
    mixed = ~flags[faces].all(axis=1) & flags[faces].any(axis=1)
    touched = np.bincount(faces[mixed].ravel(), minlength=len(flags)) > 0
    return flags & ~touched


def _pieces(
    flags: NDArray[np.bool_], faces: NDArray[np.int64], n: int
) -> tuple[int, NDArray[np.intp]]:
    """Connected pieces of the vertices ``flags`` over the mesh's edges: their count and
    each vertex's piece (-1 for a vertex not flagged)."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = e[flags[e[:, 0]] & flags[e[:, 1]]]
    graph = coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    label = np.where(flags, label, -1)
    # renumber the flagged pieces 0..k-1
    ids, inverse = np.unique(label[flags], return_inverse=True)
    out = np.full(n, -1, dtype=np.intp)
    out[flags] = inverse
    return len(ids), out


def mesh_flaps(
    position: NDArray[np.float64],
    material: ClothMaterial,
    *,
    coarse: bool = True,
) -> list[MeshFlap]:
    """The flaps of one frame and their creases (see the module's description).

    Parameters
    ----------
    position : ndarray, shape (N, 3)
        The frame's vertices, metres, z up, scaled by ``material.scale``.
    material : ClothMaterial
    coarse : bool
        Work on the material's coarse mesh (about 700 of its vertices, 15 mm apart on a
        400 mm napkin: the positions are the vertices' own, so the fit is as exact, at
        a tenth of the time) rather than on every vertex.

    Returns
    -------
    list of MeshFlap
        Empty when nothing lies turned over, or too little lies face up to place the
        napkin that stays.
    """
    position, uv, faces = _mesh_of(position, material, coarse)
    n = len(position)
    cos = _vertex_up_cos(position, faces)
    down, up = cos < FACE_DOWN_COS, cos > FACE_UP_COS
    if not down.any():
        return []
    # a vertex next to the bend is left out too: its triangles span the bend (and on a
    # remeshed cloth a vertex there may have been placed on their chord, off the cloth)
    down, up = _inner(down, faces), _inner(up, faces)
    k, piece = _pieces(down, faces, n)
    sizes = np.bincount(piece[down], minlength=k)
    keep = [j for j in range(k) if sizes[j] >= MIN_FLAP_VERTICES]
    if not keep or np.count_nonzero(up) < 3:
        return []
    lut = np.full(k + 1, -1)
    lut[keep] = np.arange(len(keep))
    part = np.where(down, lut[piece], -1)
    use = up | (part >= 0)
    stride = max(1, int(np.count_nonzero(use)) // MAX_FIT_POINTS)
    ids = np.flatnonzero(use)[::stride]
    m = uv[ids]
    p = position[ids, :2] * 1e3
    g = part[ids]
    if np.count_nonzero(g < 0) < 3 or any(np.count_nonzero(g == j) < 2 for j in range(len(keep))):
        return []
    th, tau = rigid_fit_2d(m[g < 0], p[g < 0])
    rot, _ = rotation_2d(th)
    q = (p - tau) @ rot  # back onto the flat napkin
    x = [th, float(tau[0]), float(tau[1])]
    for j in range(len(keep)):
        fit = mirror_crease_fit(m[g == j], q[g == j])
        if fit is None:
            return []
        x += list(fit)
    x, jtj, res = solve_flaps(m, p, g, np.asarray(x, dtype=float), len(keep))
    d2 = (res * res).sum(axis=1)
    # the vertices lie exactly on the cloth: what is left is how the bend is modelled
    var = max(float(d2.mean()) / 2.0, MESH_SD_MM**2)
    try:
        cov = var * np.linalg.inv(jtj)
    except np.linalg.LinAlgError:
        return []
    z = position[:, 2] * 1e3
    face_up = np.flatnonzero(up)
    below = cKDTree(position[face_up, :2])
    corner_piece = _corner_pieces(uv, part, material)
    out = []
    for j in range(len(keep)):
        mine = g == j
        a, c = float(x[3 + 2 * j]), float(x[4 + 2 * j])
        # the bend takes cloth: move the mirror's axis back by a quarter turn of the
        # layers' gap (the flap's height over the cloth face up beneath it)
        flap_ids = ids[mine]
        under = face_up[below.query(position[flap_ids, :2])[1]]
        gap = abs(float(np.median(z[flap_ids] - z[under])))
        side = float(np.mean(m[mine] @ np.array([math.cos(a), math.sin(a)]) - c))
        c -= math.copysign(0.25 * math.pi * min(gap, 10.0), side)
        line = Crease.from_normal(a, c)
        corners = "".join(name for name, pc in zip(CORNERS, corner_piece) if pc == j)
        block = cov[3 + 2 * j : 5 + 2 * j, 3 + 2 * j : 5 + 2 * j]
        out.append(MeshFlap(
            corners,
            (tuple(float(v) for v in line.point), tuple(float(v) for v in line.direction)),
            tuple(tuple(float(v) for v in r) for r in block),  # type: ignore[arg-type]
            int(np.count_nonzero(mine)),
            round(float(np.sqrt(d2[mine].mean())), 3),
        ))
    return out


def _mesh_of(
    position: NDArray[np.float64], material: ClothMaterial, coarse: bool
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.intp]]:
    """The vertices (positions, material uv) and triangles a frame's flaps are fitted
    on: every vertex, or the material's coarse mesh."""
    if not coarse:
        return position, material.uv, material.faces
    uv, faces = _coarse_mesh(material)
    return position[material.coarse_ids], uv, faces


@lru_cache(maxsize=8)
def _coarse_mesh(material: ClothMaterial) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """The material's coarse vertices (uv) and triangles, worked out once per material
    (every frame of an episode shares them). The Delaunay triangles of the coarse
    vertices include slivers along the border, which would join two flaps: only
    triangles of its spacing are kept."""
    uv, faces = material.uv[material.coarse_ids], material.coarse_faces
    edge = np.stack([np.linalg.norm(uv[faces[:, i]] - uv[faces[:, (i + 1) % 3]], axis=1)
                     for i in range(3)]).max(axis=0)
    faces = faces[edge <= 2.5 * material.spacing_mm]
    uv.flags.writeable = faces.flags.writeable = False  # (shared by every frame)
    return uv, faces


def _corner_pieces(
    uv: NDArray[np.float64], part: NDArray[np.intp], material: ClothMaterial
) -> NDArray[np.intp]:
    """Each corner's flap (4,), -1 for none: the one of the flap vertex nearest it on
    the napkin (the corner itself may lie next to a bend, or be left out as one)."""
    on_flap = np.flatnonzero(part >= 0)
    w, h = material.size_mm
    near_d, near_i = cKDTree(uv[on_flap]).query([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]])
    return np.where(near_d <= CORNER_REACH_MM, part[on_flap[near_i]], -1)


def _flap_corners(word: str) -> str:
    """The corners a fold's flap carries, in ABCD order."""
    _, name = fold_kind(word)
    return "".join(c for c in CORNERS if c in name)


def mesh_fold_geometry(
    words: list[str] | tuple[str, ...], flaps: list[dict[str, Any]], layout: NapkinLayout
) -> list[FoldGeometry]:
    """The geometry of each fold word from a frame's flaps (:meth:`MeshFlap.to_json`),
    ``geometry_from`` ``"mesh"``; a fold without its flap has None sizes and a why."""
    out = []
    for word in words:
        # the flap that carries the fold's corners with fewest others (a diagonal
        # fold's flap reaches the two corners on its crease too)
        want = set(_flap_corners(word))
        fits = [f for f in flaps if want <= set(f["corners"])]
        f = min(fits, key=lambda f: len(f["corners"])) if fits else None
        if f is None:
            g = empty_geometry(word, "no flap carrying its corners lies turned over on the mesh "
                             "(a fold in progress, or held up)")
            out.append(FoldGeometry(g.word, g.kind, g.values, g.sd, why=g.why, source="mesh"))
            continue
        crease = Crease(tuple(f["crease"][0]), tuple(f["crease"][1]))
        out.append(geometry_from_crease(
            word, crease, layout, np.asarray(f["cov"], dtype=float),
            stickers=int(f["vertices"]), rms_mm=float(f["rms_mm"]), source="mesh",
        ))
    return out


def goal_distance(
    position: NDArray[np.float64],
    rest: NDArray[np.float64],
    uv: NDArray[np.float64],
    creases: list[tuple[Crease, tuple[float, float]]],
) -> dict[str, float]:
    """How far a frame's cloth lies from the goal's ideal folded configuration, as the
    simulation benchmarks measure it.

    The ideal configuration is the flat cloth of the rest frame with each flap (the
    material points on the flap's side of its crease) mirrored across the crease, in
    the order given, placed on the table where the rest frame lies (the rigid map in
    the table plane that best takes the material coordinates to it). It is compared
    with the frame vertex by vertex, in the world's coordinates (as SoftGym does: a
    cloth that slid on the table is that far from its goal).

    Parameters
    ----------
    position : ndarray, shape (N, 3)
        The frame, metres, z up.
    rest : ndarray, shape (N, 3)
        The flat cloth, metres, z up.
    uv : ndarray, shape (N, 2)
        Material coordinates, mm.
    creases : list of (Crease, flap point)
        The goal's creases with a material point on each flap's side.

    Returns
    -------
    dict
        ``{"max_mm", "mean_mm"}``: the largest and the mean distance of a vertex from
        its ideal place.
    """
    ideal = np.asarray(uv, dtype=float).copy()
    for crease, flap in creases:
        (px, py), (tx, ty) = crease.point, crease.direction
        nrm = np.array([-ty, tx])
        s = (ideal - np.array([px, py])) @ nrm
        s_flap = (np.asarray(flap) - np.array([px, py])) @ nrm
        on = s * s_flap > 0
        ideal[on] = crease.reflect(ideal[on])
    th, tau = rigid_fit_2d(np.asarray(uv, dtype=float), rest[:, :2] * 1e3)
    rot, _ = rotation_2d(th)
    ideal_xy = ideal @ rot.T + tau
    table = float(np.median(rest[:, 2])) * 1e3
    ideal_3d = np.column_stack([ideal_xy, np.full(len(ideal_xy), table)])
    d = np.linalg.norm(position * 1e3 - ideal_3d, axis=1)
    return {"max_mm": float(d.max()), "mean_mm": float(d.mean())}
