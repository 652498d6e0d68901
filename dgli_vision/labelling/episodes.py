"""Cloth episodes from other simulators: NPZ arrays, CloSE's MATLAB files, mesh folders.

Every reader returns a :class:`ClothEpisode`: vertex positions of every frame in metres
in a frame whose z axis is the up axis, with the mesh's triangles (or its particle
grid). Bad input raises :class:`~dgli_vision.core.errors.InvalidInputError` (or
:class:`~dgli_vision.core.errors.UnreadableInputError`) naming the file and, where it
is one frame's fault, the frame.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ..core.errors import InvalidInputError, UnreadableInputError
from .formats import FORMATS, UNITS

__all__ = [
    "FORMATS",
    "UNITS",
    "ClothEpisode",
    "ReadOptions",
    "detect_format",
    "grid_faces",
    "parse_up_axis",
    "read_episode",
    "up_rotation",
]

#: Mesh file types a mesh folder may hold (one file per frame, in name order).
MESH_SUFFIXES = (".obj", ".ply")
#: An NPZ member that would inflate beyond this many bytes is refused (before reading).
MAX_NPZ_BYTES = 4_000_000_000
#: ... as is one (over 1 MB) that inflates more than this many times its stored size:
#: positions compress 1-3 times, a zero-filled bomb a thousand times.
MAX_NPZ_RATIO = 200
#: Positions beyond this (in any unit) are refused: scaled to metres and mm they overflow.
MAX_ABS_VALUE = 1e12


@dataclass(frozen=True)
class ReadOptions:
    """How to read an episode.

    Attributes
    ----------
    format : str or None
        One of :data:`FORMATS`; None: from the path (``.npz``, ``.mat``, a folder).
    up_axis : str
        The simulator's up axis: ``x``, ``y``, ``z``, optionally signed (``-y``).
    units : str
        The positions' length unit, a key of :data:`UNITS`.
    size_mm : tuple of float or None
        The cloth's real size (W, H) in mm; None: measured from the rest frame.
    rest : str or None
        A file whose (first) frame is the flat cloth at rest; None: the episode's first.
    geometry : bool
        Measure each frame's folds on the mesh (:mod:`.fold_mesh`); False leaves every
        frame's ``folds`` empty (a faster run).
    """

    format: str | None = None
    up_axis: str = "z"
    units: str = "m"
    size_mm: tuple[float, float] | None = None
    rest: str | None = None
    geometry: bool = True


@dataclass(frozen=True, eq=False)
class ClothEpisode:
    """The frames of one cloth episode.

    Attributes
    ----------
    path : str
        The file or folder it was read from.
    positions : ndarray, shape (T, N, 3)
        Vertex positions as stored (the simulator's units and axes, its dtype);
        :meth:`frames` gives them in metres, z up.
    faces : ndarray of int, shape (F, 3)
        Triangles (from the file, from the grid, or empty for a CloSE file without them).
    grid : tuple of int or None
        (rows, cols) of a particle grid, row-major.
    border : ndarray of int, shape (E, 2), optional
        Border edges given by the file (CloSE's ``Eb``, 0-based); None: from the faces.
    transform : ndarray, shape (3, 3), optional
        Takes a stored position to metres, z up (None: it already is).
    """

    path: str
    positions: NDArray
    faces: NDArray[np.int64]
    grid: tuple[int, int] | None = None
    border: NDArray[np.int64] | None = None
    transform: NDArray[np.float64] | None = None

    @property
    def n_frames(self) -> int:
        """Number of frames T."""
        return int(self.positions.shape[0])

    @property
    def n_vertices(self) -> int:
        """Number of vertices N."""
        return int(self.positions.shape[1])

    def frames(self, start: int, stop: int) -> NDArray[np.float64]:
        """Frames ``start..stop`` in metres, z up, shape (stop - start, N, 3) (converted
        here, a block at a time, so that a long episode is held once, as stored)."""
        pos = np.asarray(self.positions[start:stop], dtype=np.float64)
        return pos if self.transform is None else pos @ self.transform.T


def parse_up_axis(text: str) -> NDArray[np.float64]:
    """The up vector of ``x``, ``y``, ``z`` with an optional sign (``-y``, ``+z``)."""
    m = re.fullmatch(r"\s*([+-]?)([xyzXYZ])\s*", text)
    if m is None:
        raise InvalidInputError(f"up axis {text!r} is not one of x, y, z, -x, -y, -z")
    up = np.zeros(3)
    up["xyz".index(m.group(2).lower())] = -1.0 if m.group(1) == "-" else 1.0
    return up


def up_rotation(up: NDArray[np.float64]) -> NDArray[np.float64]:
    """A proper rotation (3, 3) taking ``up`` to +z (rows: new x, y, z axes)."""
    z = np.asarray(up, dtype=np.float64) / np.linalg.norm(up)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = helper - (helper @ z) * z
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z])


def grid_faces(rows: int, cols: int) -> NDArray[np.int64]:
    """Two triangles per cell of a row-major (rows, cols) grid, shape (2 (r-1)(c-1), 3)."""
    idx = np.arange(rows * cols).reshape(rows, cols)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    return np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).astype(np.int64)


def detect_format(path: str | Path, given: str | None = None) -> str:
    """The format of ``path``: ``given``, else by its extension (or a folder: meshes)."""
    if given is not None:
        if given not in FORMATS:
            raise InvalidInputError(f"format {given!r} is not one of {', '.join(FORMATS)}")
        return given
    p = Path(path)
    if p.is_dir():
        return "meshes"
    suffix = p.suffix.lower()
    if suffix in (".npz", ".mat"):
        return suffix[1:]
    if suffix in MESH_SUFFIXES:  # one mesh: an episode of one frame (or a rest frame)
        return "meshes"
    raise InvalidInputError(
        f"'{path}': cannot tell the format from its name; expected .npz, .mat or a folder "
        "of .obj/.ply meshes (or give --format)"
    )


def _check_positions(path: str, pos: NDArray, first: int = 0) -> NDArray:
    """Positions (T, N, 3) as floats, refusing complex or non-numeric values and NaN or
    infinite ones (naming the frame)."""
    pos = np.asarray(pos)
    if np.iscomplexobj(pos):
        raise InvalidInputError(f"'{path}': positions are complex numbers, not real ones")
    if pos.dtype.kind not in "fiub":
        raise InvalidInputError(f"'{path}': positions are not numbers (dtype {pos.dtype})")
    if not np.issubdtype(pos.dtype, np.floating):
        pos = pos.astype(np.float64)
    if pos.shape[0] == 0:
        raise InvalidInputError(f"'{path}': the episode has no frames")
    with np.errstate(over="ignore", invalid="ignore"):
        bad = ~np.isfinite(pos).all(axis=(1, 2))
        # beyond MAX_ABS_M a conversion to metres and millimetres overflows
        bad |= (np.abs(np.nan_to_num(pos)) > MAX_ABS_VALUE).any(axis=(1, 2))
    if bad.any():
        raise InvalidInputError(
            f"'{path}': frame {first + int(np.argmax(bad))}: positions are NaN, infinite "
            f"or beyond {MAX_ABS_VALUE:.0e}"
        )
    if pos.shape[1] < 4:
        raise InvalidInputError(f"'{path}': {pos.shape[1]} vertices is not a cloth mesh")
    return pos


def _check_faces(path: str, faces: NDArray, n: int) -> NDArray[np.int64]:
    f = np.asarray(faces)
    if f.ndim != 2 or f.shape[1] != 3 or not np.issubdtype(f.dtype, np.integer):
        raise InvalidInputError(f"'{path}': faces must be integers of shape (F, 3), got {f.shape}")
    if len(f) == 0 or f.min() < 0 or f.max() >= n:
        raise InvalidInputError(f"'{path}': faces index vertices outside 0..{n - 1}")
    return f.astype(np.int64)


def _npz_members(path: str) -> dict[str, NDArray]:
    """The arrays of an NPZ file that ``dgli label`` uses (``positions``, ``grid``,
    ``faces``), after checking the sizes its zip directory declares: no member is
    inflated that is not used, and none that would inflate beyond :data:`MAX_NPZ_BYTES`
    or more than :data:`MAX_NPZ_RATIO` times its stored size (a zip bomb)."""
    import zipfile
    import zlib

    try:
        with zipfile.ZipFile(path) as zf:
            infos = {i.filename.removesuffix(".npy"): i for i in zf.infolist()}
            used = {k: infos[k] for k in ("positions", "grid", "faces") if k in infos}
            if "positions" not in used:
                raise InvalidInputError(
                    f"'{path}': no 'positions' array (has {sorted(infos)})"
                )
            for name, info in used.items():
                big = info.file_size > MAX_NPZ_BYTES
                bomb = info.file_size > 1 << 20 and (
                    info.file_size > MAX_NPZ_RATIO * max(info.compress_size, 1)
                )
                if big or bomb:
                    raise InvalidInputError(
                        f"'{path}': its '{name}' array would inflate to "
                        f"{info.file_size / 1e9:.1f} GB from {info.compress_size / 1e6:.1f} MB "
                        f"stored; refused (limit {MAX_NPZ_BYTES / 1e9:.0f} GB, "
                        f"{MAX_NPZ_RATIO}x)"
                    )
            arrays = {}
            for name, info in used.items():
                with zf.open(info) as fh:
                    arrays[name] = np.lib.format.read_array(fh, allow_pickle=False)
            return arrays
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        raise UnreadableInputError(f"'{path}': cannot read as NPZ: {exc}") from None


def _read_npz(path: str) -> ClothEpisode:
    arrays = _npz_members(path)
    if "positions" not in arrays:
        raise InvalidInputError(f"'{path}': no 'positions' array (has {sorted(arrays)})")
    pos = arrays["positions"]
    if pos.ndim == 2:
        pos = pos[None]
    if pos.ndim != 3 or pos.shape[2] not in (3, 4):
        raise InvalidInputError(
            f"'{path}': positions must be (T, N, 3), (N, 3) or SoftGym's (T, N, 4), "
            f"got {arrays['positions'].shape}"
        )
    pos = _check_positions(path, pos[..., :3])  # SoftGym's 4th column: inverse mass
    n = pos.shape[1]
    grid = None
    if "grid" in arrays:
        g = np.asarray(arrays["grid"]).ravel()
        if g.dtype.kind not in "iuf" or not np.isfinite(g).all() or (g != np.round(g)).any():
            raise InvalidInputError(f"'{path}': grid must be two whole numbers (rows, cols)")
        if g.size != 2 or int(g[0]) * int(g[1]) != n or min(int(g[0]), int(g[1])) < 2:
            raise InvalidInputError(
                f"'{path}': grid {g.tolist()} does not match the {n} vertices (rows x cols)"
            )
        grid = (int(g[0]), int(g[1]))
        faces = grid_faces(*grid)
    elif "faces" in arrays:
        faces = _check_faces(path, arrays["faces"], n)
    else:
        raise InvalidInputError(f"'{path}': neither 'grid' (rows, cols) nor 'faces' (F, 3)")
    return ClothEpisode(path, pos, faces, grid)


def _read_mat(path: str) -> ClothEpisode:
    import scipy.io
    import scipy.sparse

    try:
        data = scipy.io.loadmat(path)
    except (
        OSError, ValueError, TypeError, NotImplementedError, EOFError, IndexError, KeyError,
        scipy.io.matlab.MatReadError,
    ) as exc:
        raise UnreadableInputError(f"'{path}': cannot read as a MATLAB file: {exc}") from None
    for key in ("phiPositions", "Eb"):
        if key not in data:
            raise InvalidInputError(f"'{path}': no '{key}' variable (CloSE's format)")
    cells = np.asarray(data["phiPositions"], dtype=object).ravel()
    frames = []
    for t, cell in enumerate(cells):
        x = cell.toarray() if scipy.sparse.issparse(cell) else np.asarray(cell)
        if np.iscomplexobj(x) or x.dtype.kind not in "fiub":
            raise InvalidInputError(
                f"'{path}': frame {t}: positions are not real numbers (dtype {x.dtype})"
            )
        x = x.astype(np.float64)
        if x.ndim != 2 or x.shape[1] != 3 or (frames and x.shape != frames[0].shape):
            raise InvalidInputError(f"'{path}': frame {t}: positions of shape {x.shape}")
        frames.append(x)
    if not frames:
        raise InvalidInputError(f"'{path}': phiPositions holds no frame")
    pos = _check_positions(path, np.stack(frames))
    eb = np.asarray(data["Eb"])
    n = pos.shape[1]
    if eb.ndim != 2 or eb.shape[1] < 2 or eb.size == 0 or eb.min() < 1 or eb.max() > n:
        raise InvalidInputError(
            f"'{path}': Eb must be 1-based border edges (E, 2) of the {n} vertices"
        )
    faces = np.zeros((0, 3), np.int64)
    for key in ("faces", "F", "T"):
        if key in data and np.asarray(data[key]).ndim == 2:
            faces = _check_faces(path, np.asarray(data[key]).astype(np.int64) - 1, n)
            break
    return ClothEpisode(path, pos, faces, None, eb[:, :2].astype(np.int64) - 1)


def _mesh_files(path: str) -> list[Path]:
    if Path(path).is_file():
        return [Path(path)]
    files = sorted(p for p in Path(path).iterdir() if p.suffix.lower() in MESH_SUFFIXES)
    if not files:
        raise InvalidInputError(f"'{path}': no .obj or .ply meshes in the folder")
    return files


def _read_obj(path: Path) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Vertices and triangles of an OBJ file in the file's own vertex order (Open3D's
    reader renumbers them, and corner A is the first vertex of the cloth); polygons are
    fanned into triangles."""
    verts, tris = [], []
    try:
        with path.open(encoding="utf-8", errors="replace") as fh:
            for line in fh:
                if line.startswith("v "):
                    verts.append(line.split()[1:4])
                elif line.startswith("f "):
                    ids = [int(w.split("/")[0]) for w in line.split()[1:]]
                    ids = [i - 1 if i > 0 else len(verts) + i for i in ids]
                    tris += [(ids[0], ids[k], ids[k + 1]) for k in range(1, len(ids) - 1)]
        return np.array(verts, dtype=np.float64).reshape(-1, 3), np.array(tris, np.int64)
    except (OSError, ValueError) as exc:
        raise UnreadableInputError(f"'{path}': cannot read as OBJ: {exc}") from None


def _read_mesh_file(path: Path) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Vertices and triangles of one OBJ or PLY file (PLY through Open3D)."""
    if path.suffix.lower() == ".obj":
        return _read_obj(path)
    from ..core.optional import open3d

    o3d = open3d("reading cloth meshes")

    mesh = o3d.io.read_triangle_mesh(str(path), enable_post_processing=False, print_progress=False)
    return np.asarray(mesh.vertices, np.float64), np.asarray(mesh.triangles, np.int64)


def _read_meshes(path: str) -> ClothEpisode:
    frames, faces = [], None
    for t, f in enumerate(_mesh_files(path)):
        v, tri = _read_mesh_file(f)
        if len(v) == 0 or len(tri) == 0:
            raise UnreadableInputError(f"'{f}': frame {t}: no triangle mesh could be read")
        if faces is None:
            faces = tri
        elif v.shape != frames[0].shape or not np.array_equal(tri, faces):
            raise InvalidInputError(
                f"'{f}': frame {t}: the mesh differs from the first frame's ({len(v)} "
                f"vertices, {len(tri)} triangles; expected {len(frames[0])}, {len(faces)})"
            )
        frames.append(v)
    pos = _check_positions(path, np.stack(frames))
    return ClothEpisode(path, pos, _check_faces(path, faces, pos.shape[1]))


_READERS = {"npz": _read_npz, "mat": _read_mat, "meshes": _read_meshes}


def read_raw(path: str | Path, fmt: str | None = None) -> ClothEpisode:
    """An episode as stored (simulator units and axes)."""
    p = Path(path)
    if not p.exists():
        raise UnreadableInputError(f"'{path}': no such file or folder")
    return _READERS[detect_format(p, fmt)](str(path))


def read_episode(path: str | Path, options: ReadOptions = ReadOptions()) -> ClothEpisode:
    """Read an episode and bring it to metres, z up.

    Parameters
    ----------
    path : str or Path
    options : ReadOptions

    Returns
    -------
    ClothEpisode
    """
    if options.units not in UNITS:
        raise InvalidInputError(f"units {options.units!r} are not one of {', '.join(UNITS)}")
    raw = read_raw(path, options.format)
    rot = up_rotation(parse_up_axis(options.up_axis)) * UNITS[options.units]
    same = np.array_equal(rot, np.eye(3))
    transform = None if same else rot
    return ClothEpisode(raw.path, raw.positions, raw.faces, raw.grid, raw.border, transform)


def read_rest(options: ReadOptions) -> NDArray[np.float64] | None:
    """The rest frame of ``options.rest`` (its first frame, metres, z up), or None."""
    if options.rest is None:
        return None
    ep = read_episode(options.rest, ReadOptions(None, options.up_axis, options.units))
    return ep.frames(0, 1)[0]
