"""Episodes of the project's own simulator written as other simulators would write them.

Used to check ``dgli label`` against the simulator's truth (tests, the bench,
docs/simulation.md): any rigid motion on the table, any up axis and unit, the particle
grid or a remeshed cloth without one, in each input format.
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import Delaunay

from ..sim.cloth.mesh import ClothMesh
from .episodes import UNITS, parse_up_axis, up_rotation

__all__ = [
    "Remesh",
    "SequenceEpisode",
    "npz_bytes",
    "remesh",
    "rigid_motion",
    "sequence_episode",
    "to_simulator",
    "write_mat",
    "write_meshes",
    "write_npz",
]


def rigid_motion(
    positions: NDArray[np.float64], rng: np.random.Generator, *, shift_m: float = 0.5
) -> NDArray[np.float64]:
    """Positions (T, N, 3), z up, turned about the vertical and moved on the table by one
    random rigid motion (the same for every frame)."""
    a = float(rng.uniform(0, 2 * np.pi))
    c, s = np.cos(a), np.sin(a)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    shift = np.append(rng.uniform(-shift_m, shift_m, 2), rng.uniform(0, shift_m))
    return positions @ rot.T + shift


def to_simulator(positions: NDArray[np.float64], up_axis: str, units: str) -> NDArray[np.float64]:
    """Positions (..., 3) in metres, z up, as a simulator with ``up_axis`` and ``units``
    stores them (the inverse of :func:`~.episodes.read_episode`'s conversion)."""
    rot = up_rotation(parse_up_axis(up_axis))
    return positions @ rot / UNITS[units]


class Remesh:
    """A cloth resampled at scattered material points, with no grid.

    Attributes
    ----------
    uv : ndarray, shape (n, 2)
        Material points, mm: the four corners first (A, B, C, D), then the border, then
        the inside (jittered, so that no two rows line up).
    faces : ndarray, shape (F, 3)
        Delaunay triangles in (u, v).
    border : ndarray, shape (E, 2)
        The border edges, in order round the cloth.
    """

    def __init__(self, uv: NDArray, faces: NDArray, border: NDArray) -> None:
        self.uv, self.faces, self.border = uv, faces, border

    def positions(self, meshes: list[ClothMesh]) -> NDArray[np.float64]:
        """Positions (T, n, 3) of the points on each simulated mesh."""
        return np.stack([m.interpolate(self.uv) for m in meshes])


def remesh(size_mm: tuple[float, float], n_vertices: int, rng: np.random.Generator) -> Remesh:
    """About ``n_vertices`` scattered points on a W x H cloth and their triangles."""
    w, h = size_mm
    step = float(np.sqrt(w * h / n_vertices))
    corners = np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]])
    border = []
    for k in range(4):
        a, b = corners[k], corners[(k + 1) % 4]
        n = max(2, round(float(np.linalg.norm(b - a)) / step))
        t = np.sort(rng.uniform(0.5, n - 0.5, n - 1)) / n
        border.append(a + t[:, None] * (b - a))
    nu, nv = round(w / step) - 1, round(h / step) - 1
    gu, gv = np.meshgrid((np.arange(nu) + 1) * w / (nu + 1), (np.arange(nv) + 1) * h / (nv + 1))
    inside = np.column_stack([gu.ravel(), gv.ravel()])
    inside += rng.uniform(-0.35, 0.35, inside.shape) * step
    uv = np.concatenate([corners, *border, inside])
    faces = Delaunay(uv, qhull_options="QJ").simplices.astype(np.int64)
    ring = [0]
    for k in range(4):
        start = 4 + sum(len(b) for b in border[:k])
        ring += [*range(start, start + len(border[k])), (k + 1) % 4]
    ring = np.array(ring[:-1])
    return Remesh(uv, faces, np.column_stack([ring, np.roll(ring, -1)]))


def write_npz(
    path: str | Path,
    positions: NDArray[np.float64],
    *,
    grid: tuple[int, int] | None = None,
    faces: NDArray | None = None,
    softgym: bool = False,
    compress: bool = True,
) -> None:
    """An NPZ episode: ``positions`` (float32, with SoftGym's inverse-mass column when
    ``softgym``) and ``grid`` or ``faces``, zip-compressed or not."""
    pos = np.asarray(positions, dtype=np.float32)
    if softgym:
        pos = np.concatenate([pos, np.ones((*pos.shape[:-1], 1), np.float32)], axis=-1)
    extra = {"grid": np.array(grid)} if grid is not None else {"faces": np.asarray(faces)}
    (np.savez_compressed if compress else np.savez)(path, positions=pos, **extra)


def write_mat(path: str | Path, positions: NDArray[np.float64], border: NDArray) -> None:
    """A CloSE MATLAB file: ``phiPositions`` (1 x T cell of N x 3) and ``Eb`` (border
    edges, 1-based)."""
    import scipy.io

    cells = np.empty((1, len(positions)), dtype=object)
    for t, p in enumerate(positions):
        cells[0, t] = np.asarray(p, dtype=np.float64)
    scipy.io.savemat(path, {"phiPositions": cells, "Eb": np.asarray(border) + 1})


def write_meshes(
    folder: str | Path, positions: NDArray[np.float64], faces: NDArray, *, suffix: str = ".obj"
) -> None:
    """One mesh per frame, ``frame_00000.obj`` (or ``.ply``), written by Open3D."""
    from ..core.optional import open3d

    o3d = open3d("writing cloth meshes")

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    for t, p in enumerate(positions):
        mesh = o3d.geometry.TriangleMesh(
            o3d.utility.Vector3dVector(np.asarray(p, dtype=np.float64)),
            o3d.utility.Vector3iVector(np.asarray(faces, dtype=np.int32)),
        )
        o3d.io.write_triangle_mesh(str(out / f"frame_{t:05d}{suffix}"), mesh, write_ascii=False)


@dataclass(frozen=True)
class SequenceEpisode:
    """A folding sequence of the simulator as another simulator's episode.

    Attributes
    ----------
    name : str
        ``"I"``, ``"II"`` or ``"III"``.
    positions : ndarray, shape (T, N, 3)
        The cloth's particles, metres, z up, the table at z = 0.
    grid : (int, int)
        The particle grid's (rows, cols), row-major: what ``dgli label`` needs to know
        where each particle is on the napkin.
    truth : list of dict
        Each frame's state by SPEC's 90-degree rule: ``{"frame", "class", "variant",
        "progress"}``.
    """

    name: str
    positions: NDArray[np.float64]
    grid: tuple[int, int]
    truth: list[dict[str, Any]]


def sequence_episode(
    name: str, n_frames: int, rng: np.random.Generator, layout: Any = None
) -> SequenceEpisode:
    """The frames of folding sequence ``name`` (its fold sizes and placement drawn from
    ``rng``), spread evenly from flat to its last fold laid flat.

    Raises
    ------
    InvalidValueError
        An unknown sequence, or fewer than 2 frames.
    """
    from ..core.layout import default_layout
    from ..sim.cloth.sequences import sequence_progress, sequence_state, sequence_steps

    layout = layout or default_layout()
    steps = sequence_steps(name, layout, rng=rng)
    yaw = float(rng.uniform(0, 2 * np.pi))
    states = [
        sequence_state(name, t, steps=steps, layout=layout, yaw=yaw)
        for t in sequence_progress(name, n_frames)
    ]
    rows, cols = states[0].mesh.shape
    truth = [
        {"frame": k, "class": s.class_id, "variant": s.variant,
         "progress": s.params["progress"]}
        for k, s in enumerate(states)
    ]
    return SequenceEpisode(name, np.stack([s.mesh.xyz for s in states]), (rows, cols), truth)


def npz_bytes(positions: NDArray[np.float64], grid: tuple[int, int]) -> bytes:
    """The bytes of an NPZ episode as :func:`write_npz` writes it (``positions`` as
    float32 and ``grid``), for a writer that writes files whole."""
    buf = io.BytesIO()
    np.savez_compressed(buf, positions=np.asarray(positions, np.float32), grid=np.array(grid))
    return buf.getvalue()
