"""What a camera above sees of the stickers on a simulated cloth, for many frames at once.

The sixteen stickers are placed where the layout puts them for the cloth's size and
interpolated on the mesh in every frame (13 points of each disc, as the simulator's
references were made). A point of a disc is covered when the first cloth a ray cast
straight down (along the up axis) meets above it lies far from it on the cloth (more
than :data:`FAR_MM`): another layer. A sticker is seen when at least half of its disc
is uncovered, as in :func:`dgli_vision.sim.cloth.states.sticker_visibility`. Rays are
cast with Open3D's ``RaycastingScene`` on a coarse copy of the mesh (about 700
vertices), :data:`BLOCK` frames side by side in one scene.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..classifier.evidence import Evidence
from ..core.classes import LIFTED_MM, PAST_BAND_DEG
from ..core.dgli import cloth_coordinates
from ..core.handedness import back_face_up, corner_turns
from ..core.layout import NapkinLayout, layout_of_size, sticker_spreads_mm
from ..sim.cloth.states import VISIBLE_FRACTION, disc_samples
from .distances import FrameEvidence
from .material import ClothMaterial, locate

__all__ = ["BLOCK", "FAR_MM", "Placement", "observe_frames", "place_stickers"]

#: Frames raycast together in one scene (and the unit every split of an episode is
#: aligned to, so that any split gives the same numbers).
BLOCK = 64
#: A ray's first hit this far (mm, on the cloth) from the disc point it was cast at is
#: another layer over it: the simulator's references use three 5 mm cells.
FAR_MM = 15.0
#: A disc point on cloth this steep (its normal's cosine with the up axis below this) is
#: not seen either: the simulator's references hide it (cloth 15 mm further along a flap
#: steeper than 70.5 degrees lies within their 5 mm of it, across), as the detector
#: does (it reads ellipses down to an axis ratio of 0.25).
STEEP_COS = 1.0 / 3.0
#: Frames of a block are laid out on a square of this many a side in the scene.
_ACROSS = 8


@dataclass(frozen=True, eq=False)
class Placement:
    """The stickers on one cloth: where their disc points lie on its triangles.

    Attributes
    ----------
    layout : NapkinLayout
        The layout for the cloth's size.
    face : ndarray of int, shape (16 * 13,)
        Triangle of each disc point (13 per sticker, the centre first).
    weights : ndarray, shape (16 * 13, 3)
        Its barycentric weights.
    sample_uv : ndarray, shape (16 * 13, 2)
        The disc points in material coordinates, mm.
    metric_scale : float
        Lengths (heights, distances between stickers) are multiplied by this before
        they are compared with references made for another napkin size.
    """

    layout: NapkinLayout
    face: NDArray[np.int64]
    weights: NDArray[np.float64]
    sample_uv: NDArray[np.float64]
    metric_scale: float = 1.0


def place_stickers(
    material: ClothMaterial, reference_mm: tuple[float, float] | None = None
) -> Placement:
    """The sticker discs of the layout for the cloth's size, located on its mesh.

    ``reference_mm``: the napkin size the references were made for (None: the layout's
    nominal size); lengths are scaled to it when the cloth's size differs.
    """
    layout = layout_of_size(material.size_mm)
    uv = (layout.sticker_uv[:, None, :] + disc_samples(layout)[None]).reshape(-1, 2)
    face, weights = locate(material.uv, material.faces, uv)
    ref = reference_mm or layout.nominal_mm
    scale = float(np.sqrt(ref[0] * ref[1] / (material.size_mm[0] * material.size_mm[1])))
    return Placement(layout, face, weights, uv, round(scale, 6))


def _reachable(
    tri_xy: NDArray[np.float64], samples_xy: NDArray[np.float64], n_discs: int
) -> NDArray[np.bool_]:
    """Triangles (t, F) whose box in the table plane meets the box of a sticker's disc
    points: no other can be the first hit of a ray cast down at one of them (most of
    the cloth carries no sticker, and the scene's build time grows with its triangles).

    On a grid of cells at least as large as every box, two boxes that meet share a cell
    that holds a corner of each: the test is a look-up per triangle corner."""
    t = len(tri_xy)
    lo, hi = tri_xy.min(axis=2), tri_xy.max(axis=2)  # (t, F, 2)
    discs = samples_xy.reshape(t, n_discs, -1, 2)
    d_lo, d_hi = discs.min(axis=2), discs.max(axis=2)  # (t, 16, 2)
    cell = float(max((hi - lo).max(), (d_hi - d_lo).max())) * 1.001 + 1e-9
    origin = np.minimum(lo.min(axis=1), d_lo.min(axis=1))[:, None, :]  # (t, 1, 2)

    def cells(x: NDArray) -> NDArray[np.intp]:
        return ((x - origin) / cell).astype(np.intp)  # non-negative: floor

    (dl, dh), (tl, th) = (cells(d_lo), cells(d_hi)), (cells(lo), cells(hi))
    size = int(max(dh.max(), th.max())) + 1
    marked = np.zeros((t, size, size), dtype=bool)
    f = np.arange(t)[:, None]
    for a, b in ((dl, dl), (dh, dh), (dl, dh), (dh, dl)):
        marked[f, a[..., 0], b[..., 1]] = True
    keep = marked[f, tl[..., 0], tl[..., 1]]
    for a, b in ((th, th), (tl, th), (th, tl)):
        keep |= marked[f, a[..., 0], b[..., 1]]
    return keep


def _covered(
    coarse: NDArray[np.float64],
    faces: NDArray[np.int64],
    coarse_uv: NDArray[np.float64],
    samples: NDArray[np.float64],
    sample_uv: NDArray[np.float64],
    far_mm: float,
    n_discs: int,
) -> NDArray[np.bool_]:
    """Which disc points (t, S) have another layer over them, for a block of frames
    (``coarse`` (t, M, 3) the coarse mesh, ``samples`` (t, S, 3) the points)."""
    from ..core.optional import open3d

    o3d = open3d("dgli label")

    t, s = len(coarse), samples.shape[1]
    centre = coarse[:, :, :2].mean(axis=1)  # (t, 2)
    reach = float(np.abs(coarse[:, :, :2] - centre[:, None]).max()) + 0.05
    slot = np.arange(t)
    offset = np.column_stack([slot % _ACROSS, slot // _ACROSS]) * 2 * reach - centre
    verts = coarse.copy()
    verts[:, :, :2] += offset[:, None]
    keep = _reachable(coarse[:, faces, :2], samples[..., :2], n_discs)  # (t, F)
    frame, local = np.nonzero(keep)
    covered = np.zeros((t, s), dtype=bool)
    if not len(frame):
        return covered
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(verts.reshape(-1, 3).astype(np.float32)),
        o3d.core.Tensor((faces[local] + (frame * coarse.shape[1])[:, None]).astype(np.uint32)),
    )
    rays = np.zeros((t, s, 6), np.float32)
    rays[..., :2] = samples[..., :2] + offset[:, None]
    rays[..., 2] = float(coarse[:, :, 2].max()) + 1.0
    rays[..., 5] = -1.0
    hit = scene.cast_rays(o3d.core.Tensor(rays.reshape(-1, 6)))
    found = np.isfinite(hit["t_hit"].numpy().reshape(t, s))
    prim = np.where(found, hit["primitive_ids"].numpy().reshape(t, s).astype(np.int64), 0)
    bary = hit["primitive_uvs"].numpy().reshape(t, s, 2).astype(np.float64)
    corner = coarse_uv[faces[local[prim]]]  # (t, s, 3, 2)
    w = np.stack([1.0 - bary.sum(axis=-1), bary[..., 0], bary[..., 1]], axis=-1)
    hit_uv = np.einsum("tsk,tskc->tsc", w, corner)
    far = np.linalg.norm(hit_uv - sample_uv[None], axis=-1) > far_mm
    return found & far


def _interpolate(pos: NDArray, faces: NDArray, face: NDArray, weights: NDArray) -> NDArray:
    """Positions (t, k, 3) of material points on triangles ``face`` with ``weights``."""
    corners = pos[:, faces[face]]  # (t, k, 3, 3)
    return np.einsum("tkjc,kj->tkc", corners, weights)


def _up_cosine(pos: NDArray, faces: NDArray, face: NDArray) -> NDArray[np.float64]:
    """Cosine between the front face's normal and the up axis at points on triangles
    ``face``, shape (t, k): 1 lying front face up, 0 standing, -1 turned over."""
    a, b, c = (pos[:, faces[face, i]] for i in range(3))
    n = np.cross(b - a, c - a)
    norm = np.linalg.norm(n, axis=-1)
    return np.clip(np.divide(n[..., 2], norm, out=np.ones_like(norm), where=norm > 0), -1, 1)


def observe_frames(
    positions: NDArray[np.float64], material: ClothMaterial, placement: Placement
) -> FrameEvidence:
    """The classifier's evidence for a block of frames as a camera above would see it.

    Parameters
    ----------
    positions : ndarray, shape (t, N, 3)
        Metres, z up, already scaled by ``material.scale``.
    material : ClothMaterial
    placement : Placement

    Returns
    -------
    FrameEvidence
    """
    layout = placement.layout
    n_st = layout.n_stickers
    samples = _interpolate(positions, material.faces, placement.face, placement.weights)
    covered = _covered(
        positions[:, material.coarse_ids],
        material.coarse_faces,
        material.uv[material.coarse_ids],
        samples,
        placement.sample_uv,
        max(FAR_MM, material.spacing_mm),
        layout.n_stickers,
    )
    cos = _up_cosine(positions, material.faces, placement.face)  # (t, 16 * 13)
    covered |= np.abs(cos) < STEEP_COS
    t = len(positions)
    seen_share = 1.0 - covered.reshape(t, n_st, -1).mean(axis=2)
    visible = seen_share >= VISIBLE_FRACTION
    centres = samples.reshape(t, n_st, -1, 3)[:, :, 0]  # (t, 16, 3)
    table = positions[..., 2].min(axis=1)
    heights = (centres[..., 2] - table[:, None]) * 1e3
    standing = heights > LIFTED_MM
    unknown = ~visible & standing
    told = visible | unknown
    # how far the cloth at each sticker centre has turned from flat, degrees
    deg = np.degrees(np.arccos(cos.reshape(t, n_st, -1)[:, :, 0]))
    past = np.clip(0.5 + (deg - 90.0) / (2 * PAST_BAND_DEG), 0.0, 1.0)
    segments = centres.reshape(t, -1, 2, 3).copy()
    segments[~visible.reshape(t, -1, 2).all(axis=2)] = np.nan
    seen_xyz = np.where(visible[..., None], centres, np.nan)
    scale = placement.metric_scale
    return FrameEvidence(
        coords=cloth_coordinates(segments),
        evidence=Evidence(
            visible=visible,
            unknown=unknown,
            lifted=np.where(told, standing.astype(float), np.nan),
            heights_mm=np.where(told, heights * scale, np.nan),
            past=np.where(unknown, past, np.nan),
            back=back_face_up(corner_turns(seen_xyz[..., :2], layout)),
            spread_mm=sticker_spreads_mm(seen_xyz * 1e3) * scale,
        ),
        points_m=centres,
    )
