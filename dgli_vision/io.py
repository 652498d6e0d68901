"""Reading and writing files: the only module of the library that touches the disk."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .camera import DEFAULT_INTRINSICS, Intrinsics
from .errors import CalibrationError, InvalidInputError, OverwriteError, UnreadableInputError
from .references import ReferenceSet, references_from_dict, references_to_dict

if TYPE_CHECKING:
    from .cloth.states import ClothState
    from .database import StateRecords

__all__ = [
    "JsonLinesWriter",
    "LabelProblem",
    "LabelledPair",
    "RGBDFrame",
    "file_sha256",
    "find_labelled_pairs",
    "find_pairs",
    "guard_outputs",
    "labelled_folder_files",
    "parse_intrinsics",
    "read_color",
    "read_database",
    "read_depth",
    "read_frame",
    "read_intrinsics",
    "read_json",
    "read_jsonl",
    "read_mesh_ply",
    "read_references",
    "record_outputs",
    "write_color",
    "write_database",
    "write_depth",
    "write_json",
    "write_labelled_folder",
    "write_mesh_ply",
    "write_outputs",
    "write_png",
    "write_references",
    "write_text",
]


def write_text(path: str | Path, text: str) -> None:
    """Write ``text`` to ``path`` (UTF-8), creating parent folders.

    Raises
    ------
    UnreadableInputError
        If the file cannot be written.
    """
    p = Path(path)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise UnreadableInputError(f"cannot write '{p}': {exc.strerror}") from None


def read_json(path: str | Path, *, what: str = "JSON file") -> Any:
    """Parse a JSON file.

    Raises
    ------
    UnreadableInputError
        Missing or unreadable file.
    InvalidInputError
        Not valid JSON (with the line and column).
    """
    p = Path(path)
    if not p.exists():
        raise UnreadableInputError(f"{what} '{p}' does not exist")
    if p.is_dir():
        raise UnreadableInputError(f"{what} '{p}' is a directory; expected a file")
    try:
        text = p.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise UnreadableInputError(f"cannot read {what} '{p}': {exc}") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise InvalidInputError(
            f"{what} '{p}' is not valid JSON (line {exc.lineno}, column {exc.colno}: {exc.msg})"
        ) from None


def write_json(path: str | Path, data: Any) -> None:
    """Write ``data`` as indented JSON (UTF-8), creating parent folders."""
    write_text(path, json.dumps(data, indent=1) + "\n")


def write_mesh_ply(path: str | Path, xyz: NDArray, triangles: NDArray) -> None:
    """Write a triangle mesh (vertices in metres) as a binary PLY through Open3D."""
    import open3d as o3d

    mesh = o3d.geometry.TriangleMesh(
        o3d.utility.Vector3dVector(np.asarray(xyz, dtype=np.float64)),
        o3d.utility.Vector3iVector(np.asarray(triangles, dtype=np.int32)),
    )
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    if not o3d.io.write_triangle_mesh(str(p), mesh, write_ascii=False, compressed=False):
        raise UnreadableInputError(f"cannot write mesh '{p}'")


def read_mesh_ply(path: str | Path) -> tuple[NDArray[np.float64], NDArray[np.int32]]:
    """Read a PLY triangle mesh: vertices (n, 3) and triangles (k, 3)."""
    import open3d as o3d

    p = Path(path)
    if not p.is_file():
        raise UnreadableInputError(f"mesh '{p}' does not exist")
    mesh = o3d.io.read_triangle_mesh(str(p))
    if len(mesh.vertices) == 0:
        raise InvalidInputError(f"mesh '{p}' has no vertices (not a PLY mesh?)")
    return np.asarray(mesh.vertices), np.asarray(mesh.triangles, dtype=np.int32)


def file_sha256(path: str | Path) -> str:
    """SHA-256 of a file's bytes, hex."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


# --- what the tool wrote: never replace a user's file ----------------------------------

#: Each folder a command writes into keeps this record of the files the tool wrote there
#: and their checksums; a file listed with the checksum it still has may be replaced.
MANIFEST_NAME = ".dgli-outputs.json"
MANIFEST_FORMAT = "dgli-outputs"


def _manifest(folder: Path) -> dict[str, Any]:
    path = folder / MANIFEST_NAME
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    if not isinstance(data, dict) or data.get("format") != MANIFEST_FORMAT:
        return {}
    files = data.get("files")
    return files if isinstance(files, dict) else {}


def guard_outputs(paths: Iterable[str | Path], *, overwrite: bool = False) -> None:
    """Refuse to replace an existing file that dgli did not write.

    A file may be replaced when it does not exist, when ``overwrite`` is set, or when the
    record of its folder (:data:`MANIFEST_NAME`, kept by :func:`record_outputs`) lists it
    with the checksum it still has: the tool's own earlier output, untouched since.

    Raises
    ------
    OverwriteError
        Naming the first file that would be replaced.
    """
    manifests: dict[Path, dict[str, Any]] = {}
    for path in paths:
        p = Path(path)
        if p.is_dir():
            raise OverwriteError(f"'{p}' is a directory; expected a file to write")
        if overwrite or not p.exists():
            continue
        folder = p.parent
        if folder not in manifests:
            manifests[folder] = _manifest(folder)
        entry = manifests[folder].get(p.name)
        if isinstance(entry, dict) and entry.get("sha256") == file_sha256(p):
            continue
        raise OverwriteError(
            f"refusing to replace '{p}': dgli did not write it (or it was changed since); "
            "use --overwrite to replace it"
        )


def record_outputs(paths: Iterable[str | Path], command: str) -> None:
    """Add written files, with their checksums and the command, to their folders' records."""
    by_folder: dict[Path, list[Path]] = {}
    for path in paths:
        p = Path(path)
        by_folder.setdefault(p.parent, []).append(p)
    for folder, files in by_folder.items():
        listed = _manifest(folder)
        for p in files:
            if p.is_file():
                listed[p.name] = {"sha256": file_sha256(p), "command": command}
        write_json(
            folder / MANIFEST_NAME,
            {"format": MANIFEST_FORMAT, "version": 1, "files": dict(sorted(listed.items()))},
        )


def write_outputs(
    files: dict[Path, str | dict | NDArray[np.uint8]], *, overwrite: bool, command: str
) -> None:
    """Write a set of report files (text, JSON or a BGR image each), after checking with
    :func:`guard_outputs` that none replaces a user's file, and record them."""
    guard_outputs(files, overwrite=overwrite)
    for path, content in files.items():
        if isinstance(content, str):
            write_text(path, content)
        elif isinstance(content, dict):
            write_json(path, content)
        else:
            write_png(path, content)
    record_outputs(files, command)


def read_jsonl(path: str | Path) -> list[Any]:
    """The objects of a JSON-lines file; a line that is not valid JSON (the last one of
    a file whose writer was killed) is left out."""
    out = []
    try:
        with Path(path).open(encoding="utf-8") as fh:
            for line in fh:
                try:
                    out.append(json.loads(line))
                except ValueError:
                    continue
    except FileNotFoundError:
        return []
    except (OSError, UnicodeDecodeError) as exc:
        raise UnreadableInputError(f"cannot read '{path}': {exc}") from None
    return out


class JsonLinesWriter:
    """Appends one JSON object per line and flushes each, so that whatever stops the
    process (Ctrl-C, a kill, a full disk) keeps every line written before it."""

    def __init__(self, path: str | Path, *, append: bool) -> None:
        p = Path(path)
        try:
            p.parent.mkdir(parents=True, exist_ok=True)
            self._fh = p.open("a" if append else "w", encoding="utf-8")
        except OSError as exc:
            raise UnreadableInputError(f"cannot write '{p}': {exc.strerror}") from None
        self.path = p

    def write(self, obj: Any) -> None:
        """Append ``obj`` as one line and flush it to the operating system."""
        try:
            self._fh.write(json.dumps(obj) + "\n")
            self._fh.flush()
        except OSError as exc:
            raise UnreadableInputError(f"cannot write '{self.path}': {exc.strerror}") from None

    def close(self) -> None:
        """Close the file."""
        self._fh.close()


# --- simulated databases -------------------------------------------------------------

DB_FORMAT = "dgli-simulated-db"


def write_database(
    out: str | Path,
    states: list[tuple[str, ClothState]],
    provenance: dict[str, Any],
    *,
    overwrite: bool = False,
) -> Path:
    """Write states as ``meshes/<id>.ply``, ``truth/<id>.json`` and ``index.json``.

    Existing files are replaced only if dgli wrote them or with ``overwrite``
    (:func:`guard_outputs`).

    Returns
    -------
    Path
        The index file.

    Raises
    ------
    OverwriteError
    """
    root = Path(out)
    planned = [
        *(root / "meshes" / f"{sid}.ply" for sid, _ in states),
        *(root / "truth" / f"{sid}.json" for sid, _ in states),
        root / "index.json",
    ]
    guard_outputs(planned, overwrite=overwrite)
    entries = []
    triangles = None
    for sid, state in states:
        if triangles is None:
            triangles = state.mesh.triangles()
        write_mesh_ply(root / "meshes" / f"{sid}.ply", state.mesh.xyz, triangles)
        truth = {
            "id": sid,
            "class": state.class_id,
            "name": state.name,
            "variant": state.variant,
            "sticker_points_m": np.round(state.sticker_points, 7).tolist(),
            "visible": state.visible.tolist(),
            "visible_fraction": np.round(state.visible_fraction, 4).tolist(),
            "coordinates": np.round(state.coordinates(), 10).tolist(),
            "corner_points_m": np.round(state.corner_points, 7).tolist(),
            "boundary_m": np.round(state.boundary, 7).tolist(),
            "params": state.params,
        }
        write_json(root / "truth" / f"{sid}.json", truth)
        entries.append(
            {
                "id": sid,
                "class": state.class_id,
                "variant": state.variant,
                "mesh": f"meshes/{sid}.ply",
                "truth": f"truth/{sid}.json",
            }
        )
    index = root / "index.json"
    write_json(
        index, {"format": DB_FORMAT, "version": 1, "provenance": provenance, "states": entries}
    )
    record_outputs(planned, str(provenance.get("command", "")))
    return index


def read_database(path: str | Path) -> tuple[StateRecords, dict[str, Any]]:
    """Read a database folder (or its ``index.json``) into records and provenance.

    Raises
    ------
    UnreadableInputError, InvalidInputError
        Naming the file that is missing or wrong.
    """
    from .database import StateRecords
    from .dgli import cloth_coordinates

    p = Path(path)
    index_path = p / "index.json" if p.is_dir() else p
    index = read_json(index_path, what="database index")
    if not isinstance(index, dict) or index.get("format") != DB_FORMAT:
        raise InvalidInputError(f"'{index_path}' is not a dgli simulated database index")
    root = index_path.parent
    ids, classes, variants, points, vis, frac, corners, boundary, stages = (
        [] for _ in range(9)
    )
    for entry in index.get("states", []):
        truth_path = root / entry["truth"]
        truth = read_json(truth_path, what="state truth")
        try:
            pts = np.asarray(truth["sticker_points_m"], dtype=np.float64).reshape(16, 3)
            v = np.asarray(truth["visible"], dtype=bool).reshape(16)
            f = np.asarray(truth["visible_fraction"], dtype=np.float64).reshape(16)
            cp = np.asarray(truth["corner_points_m"], dtype=np.float64).reshape(4, 3)
            bd = np.asarray(truth["boundary_m"], dtype=np.float64).reshape(-1, 3)
        except (KeyError, ValueError, TypeError) as exc:
            raise InvalidInputError(f"state truth '{truth_path}' is malformed ({exc})") from None
        ids.append(str(truth["id"]))
        classes.append(str(truth["class"]))
        variants.append(truth.get("variant"))
        params = truth.get("params")
        stages.append(str(params.get("stage", "")) if isinstance(params, dict) else "")
        points.append(pts)
        vis.append(v)
        frac.append(f)
        corners.append(cp)
        boundary.append(bd)
    if not ids:
        raise InvalidInputError(f"database '{index_path}' lists no states")
    pts = np.stack(points)
    records = StateRecords(
        tuple(ids),
        tuple(classes),
        tuple(variants),
        pts,
        np.stack(vis),
        np.stack(frac),
        cloth_coordinates(pts.reshape(len(ids), -1, 2, 3)),
        np.stack(corners),
        np.stack(boundary),
        tuple(stages),
    )
    return records, dict(index.get("provenance") or {})


def read_references(path: str | Path) -> ReferenceSet:
    """Load a reference set file (see :mod:`dgli_vision.references`)."""
    return references_from_dict(read_json(path, what="reference set"), source=str(path))


def write_references(path: str | Path, refs: ReferenceSet, *, overwrite: bool = False) -> None:
    """Write a reference set as JSON (replacing a file only if dgli wrote it, or with
    ``overwrite``)."""
    guard_outputs([path], overwrite=overwrite)
    write_json(path, references_to_dict(refs))
    record_outputs([path], str(refs.provenance.get("command", "")))


COLOURS_FORMAT = "dgli-colours"


def write_colours(
    path: str | Path,
    colours: dict[str, tuple[int, int, int]],
    provenance: dict[str, Any],
    *,
    overwrite: bool = False,
) -> None:
    """Write calibrated sticker colours (``dgli calibrate``) as JSON (replacing a file
    only if dgli wrote it, or with ``overwrite``)."""
    guard_outputs([path], overwrite=overwrite)
    write_json(
        path,
        {
            "format": COLOURS_FORMAT,
            "version": 1,
            "space": "sRGB 0-255, image balanced to the napkin's white",
            "colours": {k: list(v) for k, v in colours.items()},
            "provenance": provenance,
        },
    )
    record_outputs([path], str(provenance.get("command", "")))


def read_colours(path: str | Path) -> dict[str, tuple[int, int, int]]:
    """Read a colours file written by ``dgli calibrate``.

    Raises
    ------
    UnreadableInputError, CalibrationError
    """
    from .layout import default_layout

    data = read_json(path, what="colours file")
    names = set(default_layout().colours_srgb)
    if not isinstance(data, dict) or data.get("format") != COLOURS_FORMAT:
        raise CalibrationError(
            f"'{path}' is not a dgli colours file (no \"format\": \"{COLOURS_FORMAT}\")"
        )
    colours = data.get("colours")
    if not isinstance(colours, dict) or set(colours) != names:
        raise CalibrationError(
            f"'{path}' must give exactly the colours {', '.join(sorted(names))}"
        )
    out = {}
    for name, rgb in colours.items():
        if (
            not isinstance(rgb, list)
            or len(rgb) != 3
            or not all(isinstance(v, int) and 0 <= v <= 255 for v in rgb)
        ):
            raise CalibrationError(f"'{path}': colour {name!r} must be three integers 0-255")
        out[name] = (rgb[0], rgb[1], rgb[2])
    return out


def write_png(path: str | Path, image_bgr: NDArray[np.uint8]) -> None:
    """Write a BGR uint8 image as PNG, creating parent folders."""
    import cv2

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(p), image_bgr):
        raise UnreadableInputError(f"cannot write image '{p}'")


# --- RGB-D input -----------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class RGBDFrame:
    """A registered colour + depth pair, validated.

    Attributes
    ----------
    color : ndarray of uint8, shape (H, W, 3)
        RGB.
    depth_mm : ndarray of uint16, shape (H, W)
        z-depth in mm, 0 = no reading.
    intrinsics : Intrinsics
    color_path, depth_path : str
        Where they came from (for messages and reports).
    intrinsics_source : str
        The intrinsics file, or ``"default"``.
    """

    color: NDArray[np.uint8]
    depth_mm: NDArray[np.uint16]
    intrinsics: Intrinsics
    color_path: str = ""
    depth_path: str = ""
    intrinsics_source: str = "default"


def _check_file(p: Path, what: str) -> None:
    if not p.exists():
        raise UnreadableInputError(f"{what} '{p}' does not exist")
    if p.is_dir():
        raise UnreadableInputError(f"{what} '{p}' is a directory; expected an image file")
    if p.stat().st_size == 0:
        raise UnreadableInputError(f"{what} '{p}' is empty")


def _imread(p: Path, what: str) -> NDArray:
    import cv2

    _check_file(p, what)
    data = np.fromfile(str(p), dtype=np.uint8)
    image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)  # None instead of raising
    if image is None:
        raise UnreadableInputError(f"{what} '{p}' is not an image OpenCV can decode")
    return image


def _describe(image: NDArray) -> str:
    channels = 1 if image.ndim == 2 else image.shape[2]
    return f"{channels}-channel {image.dtype.itemsize * 8}-bit"


def read_color(path: str | Path) -> NDArray[np.uint8]:
    """Read a colour image (8-bit PNG or JPEG, or 16-bit PNG scaled to 8 bits) as RGB
    (H, W, 3).

    Raises
    ------
    UnreadableInputError, InvalidInputError
    """
    import cv2

    p = Path(path)
    image = _imread(p, "colour image")
    if image.dtype == np.uint16 and image.ndim == 3:
        # 16-bit colour (a common camera export): to 8 bits, rounding (65535 -> 255)
        image = ((image.astype(np.uint32) * 255 + 32767) // 65535).astype(np.uint8)
    if image.dtype != np.uint8:
        raise InvalidInputError(
            f"colour image '{p}' is {_describe(image)}; expected an 8-bit RGB image"
            + (" (was the depth image given as colour?)" if image.ndim == 2 else "")
        )
    if image.ndim == 2 or image.shape[2] not in (3, 4):
        raise InvalidInputError(
            f"colour image '{p}' is {_describe(image)}; expected 3-channel RGB"
        )
    code = cv2.COLOR_BGRA2RGB if image.shape[2] == 4 else cv2.COLOR_BGR2RGB
    return cv2.cvtColor(image, code)


def read_depth(path: str | Path) -> NDArray[np.uint16]:
    """Read a 16-bit single-channel depth PNG in mm (H, W).

    Raises
    ------
    UnreadableInputError, InvalidInputError
    """
    p = Path(path)
    image = _imread(p, "depth image")
    if image.ndim == 3 and image.shape[2] > 1:
        raise InvalidInputError(
            f"depth image '{p}' is {_describe(image)} (a colour image?); "
            "expected a 16-bit single-channel PNG in mm"
        )
    image = image.reshape(image.shape[:2])
    if image.dtype != np.uint16:
        raise InvalidInputError(
            f"depth image '{p}' is {image.dtype.itemsize * 8}-bit; expected a 16-bit PNG in mm"
        )
    if not image.any():
        raise InvalidInputError(f"depth image '{p}' has no valid reading (all pixels are 0)")
    return image


def parse_intrinsics(data: Any, source: str) -> Intrinsics:
    """Validate Open3D ``PinholeCameraIntrinsic`` JSON (matrix column-major).

    Raises
    ------
    CalibrationError
        Naming ``source`` and what is wrong.
    """
    if not isinstance(data, dict):
        raise CalibrationError(f"intrinsics '{source}' must be a JSON object")
    missing = [k for k in ("width", "height", "intrinsic_matrix") if k not in data]
    if missing:
        raise CalibrationError(f"intrinsics '{source}' lack {', '.join(missing)}")
    m = data["intrinsic_matrix"]
    try:
        width, height = int(data["width"]), int(data["height"])
        k = np.asarray(m, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise CalibrationError(f"intrinsics '{source}' have non-numeric values") from None
    if k.shape != (9,) or not np.isfinite(k).all():
        raise CalibrationError(
            f"intrinsics '{source}': intrinsic_matrix must be 9 finite numbers, got {m!r}"
        )
    fx, fy, cx, cy = k[0], k[4], k[6], k[7]
    if width <= 0 or height <= 0:
        raise CalibrationError(
            f"intrinsics '{source}': image size {width}x{height} is not positive"
        )
    if fx <= 0 or fy <= 0:
        raise CalibrationError(
            f"intrinsics '{source}': focal lengths fx={fx}, fy={fy} must be positive"
        )
    if abs(k[8] - 1) > 1e-9 or any(abs(k[i]) > 1e-9 for i in (1, 2, 3, 5)):
        raise CalibrationError(
            f"intrinsics '{source}': intrinsic_matrix {k.tolist()} is not a pinhole matrix "
            "[fx, 0, 0, 0, fy, 0, cx, cy, 1] (column-major)"
        )
    if not (0 <= cx <= width and 0 <= cy <= height):
        raise CalibrationError(
            f"intrinsics '{source}': principal point ({cx}, {cy}) lies outside the "
            f"{width}x{height} image"
        )
    return Intrinsics(width, height, float(fx), float(fy), float(cx), float(cy))


def read_intrinsics(path: str | Path) -> Intrinsics:
    """Read an Open3D intrinsics JSON file."""
    try:
        data = read_json(path, what="intrinsics")
    except InvalidInputError as exc:
        raise CalibrationError(str(exc)) from None
    return parse_intrinsics(data, str(path))


def read_frame(
    color_path: str | Path,
    depth_path: str | Path,
    intrinsics_path: str | Path | None = None,
    *,
    threads: bool = True,
) -> RGBDFrame:
    """Read and validate a colour + depth pair and its intrinsics.

    Intrinsics are looked up in SPEC section 4's order: ``intrinsics_path``;
    ``intrinsics.json`` beside the colour image; the nominal Kinect default. With
    ``threads`` the two images are decoded concurrently (PNG decoding releases the GIL).

    Raises
    ------
    UnreadableInputError, InvalidInputError, CalibrationError
        One line naming the file and what is wrong.
    """
    from concurrent.futures import ThreadPoolExecutor

    if threads:
        with ThreadPoolExecutor(2) as pool:
            color_job = pool.submit(read_color, color_path)
            depth_job = pool.submit(read_depth, depth_path)
            color = color_job.result()
            depth = depth_job.result()
    else:
        color, depth = read_color(color_path), read_depth(depth_path)
    if color.shape[:2] != depth.shape:
        raise InvalidInputError(
            f"depth image '{depth_path}' is {depth.shape[1]}x{depth.shape[0]} but colour image "
            f"'{color_path}' is {color.shape[1]}x{color.shape[0]}; expected registered images "
            "of the same size"
        )
    source = "default"
    if intrinsics_path is not None:
        intr = read_intrinsics(intrinsics_path)
        source = str(intrinsics_path)
    elif (Path(color_path).parent / "intrinsics.json").is_file():
        source = str(Path(color_path).parent / "intrinsics.json")
        intr = read_intrinsics(source)
    else:
        intr = DEFAULT_INTRINSICS
    h, w = depth.shape
    if (intr.width, intr.height) != (w, h):
        raise CalibrationError(
            f"intrinsics '{source}' are for {intr.width}x{intr.height} images but "
            f"'{color_path}' is {w}x{h}"
        )
    return RGBDFrame(color, depth, intr, str(color_path), str(depth_path), source)


def write_color(path: str | Path, rgb: NDArray[np.uint8]) -> None:
    """Write an RGB uint8 image (PNG or JPEG by extension)."""
    import cv2

    write_png(path, cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))


def write_depth(path: str | Path, depth_mm: NDArray[np.uint16]) -> None:
    """Write a uint16 depth image in mm as a 16-bit PNG."""
    if depth_mm.dtype != np.uint16:
        raise ValueError(f"depth must be uint16, got {depth_mm.dtype}")
    write_png(path, depth_mm)


def labelled_folder_files(
    out: str | Path, names: Iterable[str], *, frames: bool = False
) -> list[Path]:
    """The files :func:`write_labelled_folder` writes for samples of these names
    (``frames``: with a ``frames.csv``)."""
    root = Path(out)
    pairs = [root / f"{n}_{kind}.png" for n in names for kind in ("color", "depth")]
    extra = [root / "frames.csv"] if frames else []
    return [*pairs, root / "intrinsics.json", root / "labels.csv", root / "truth.json", *extra]


def write_labelled_folder(
    out: str | Path,
    samples: list,
    provenance: dict[str, Any],
    *,
    overwrite: bool = False,
    times: list[float] | None = None,
) -> Path:
    """Write rendered samples as a labelled folder (SPEC section 4) with ``truth.json``.

    ``samples`` are :class:`~dgli_vision.dataset.RenderedSample`; writes
    ``<name>_color.png``, ``<name>_depth.png``, ``intrinsics.json`` (of the first sample;
    all must share it), ``labels.csv`` and ``truth.json``; with ``times`` (seconds, one
    per sample) also ``frames.csv`` (``color,depth,time``: the frames of a recording in
    order). Existing files are replaced only if dgli wrote them or with ``overwrite``
    (:func:`guard_outputs`). Returns the labels file.

    Raises
    ------
    OverwriteError
    """
    root = Path(out)
    planned = labelled_folder_files(root, [s.name for s in samples], frames=times is not None)
    guard_outputs(planned, overwrite=overwrite)
    if times is not None and len(times) != len(samples):
        raise ValueError(f"{len(times)} times for {len(samples)} samples")
    rows = []
    truth = {}
    intr = None
    for s in samples:
        if intr is None:
            intr = s.result.intrinsics
        elif s.result.intrinsics != intr:
            raise ValueError("all samples of a folder must share their intrinsics")
        color, depth = f"{s.name}_color.png", f"{s.name}_depth.png"
        write_color(root / color, s.result.color)
        write_depth(root / depth, s.result.depth_mm)
        rows.append((color, depth, s.state.class_id, s.state.variant or ""))
        truth[s.name] = {
            "color": color,
            "depth": depth,
            "class": s.state.class_id,
            "name": s.state.name,
            "variant": s.state.variant,
            "camera": {**s.camera, **s.result.pose.to_dict()},
            "sticker_points_cam_m": np.round(s.result.sticker_points_cam, 6).tolist(),
            "visible": s.result.visible.tolist(),
            "visible_fraction": np.round(s.result.visible_fraction, 3).tolist(),
            "state_params": s.state.params,
        }
    if intr is None:
        raise ValueError("no samples to write")
    write_json(root / "intrinsics.json", intr.to_open3d_dict())
    from .report import csv_table

    labels = root / "labels.csv"
    write_text(labels, csv_table(["color", "depth", "label", "variant"], rows))
    if times is not None:
        write_text(
            root / "frames.csv",
            csv_table(
                ["color", "depth", "time"],
                [(c, d, f"{t:.3f}") for (c, d, *_), t in zip(rows, times)],
            ),
        )
    write_json(root / "truth.json", {"provenance": provenance, "images": truth})
    record_outputs(planned, str(provenance.get("command", "")))
    return labels


# --- labelled folders ------------------------------------------------------------------


@dataclass(frozen=True)
class LabelledPair:
    """One colour + depth pair of a labelled folder, with its true class and variant.

    ``line`` is the pair's line in ``labels.csv`` (None for class folders).
    """

    color: str
    depth: str
    label: str
    variant: str | None = None
    line: int | None = None


@dataclass(frozen=True)
class LabelProblem:
    """A row of a labelled folder that cannot be used as it stands.

    Attributes
    ----------
    where : str
        ``labels.csv line 7`` or the pair's colour path (class folders).
    kind : str
        ``"unknown class"``, ``"unknown variant"``, ``"duplicate"`` or ``"missing file"``.
    message : str
        One line saying what is wrong.
    """

    where: str
    kind: str
    message: str


def find_pairs(folder: str | Path) -> list[LabelledPair]:
    """The labelled pairs of a folder, strictly checked (see :func:`find_labelled_pairs`).

    Raises
    ------
    UnreadableInputError, InvalidInputError
    """
    return find_labelled_pairs(folder)[0]


def _check_labels(
    pairs: list[LabelledPair], where: list[str]
) -> tuple[list[LabelledPair], list[LabelProblem]]:
    """Split pairs into usable ones and problems (unknown class or variant, duplicates,
    missing files). Pairs with missing files stay usable: reading them fails and is
    reported with the batch."""
    from .classes import CLASS_NAMES, VARIANTS

    keep, problems = [], []
    seen: dict[tuple[str, str], str] = {}
    for pair, at in zip(pairs, where):
        if pair.label not in CLASS_NAMES:
            problems.append(
                LabelProblem(
                    at,
                    "unknown class",
                    f"{at}: class {pair.label!r} is not one of 01-12",
                )
            )
            continue
        if pair.variant is not None and pair.variant not in VARIANTS[pair.label]:
            allowed = ", ".join(v or "(none)" for v in VARIANTS[pair.label])
            problems.append(
                LabelProblem(
                    at,
                    "unknown variant",
                    f"{at}: variant {pair.variant!r} is not one of class {pair.label}'s "
                    f"({allowed})",
                )
            )
            continue
        key = (str(Path(pair.color).resolve()), str(Path(pair.depth).resolve()))
        if key in seen:
            problems.append(
                LabelProblem(at, "duplicate", f"{at}: the same pair as {seen[key]}")
            )
            continue
        seen[key] = at
        for kind, path in (("colour image", pair.color), ("depth image", pair.depth)):
            if not Path(path).is_file():
                problems.append(
                    LabelProblem(at, "missing file", f"{at}: {kind} '{path}' does not exist")
                )
                break
        keep.append(pair)
    return keep, problems


def find_labelled_pairs(
    folder: str | Path, *, lenient: bool = False
) -> tuple[list[LabelledPair], list[LabelProblem]]:
    """The labelled pairs of a folder (SPEC section 4), sorted by colour path, and the
    problems found in its labels.

    Labels come from ``labels.csv`` (``color,depth,label[,variant]``, paths relative to
    the folder) or, without it, from the first directory level below the folder, whose
    name starts with the class id (``02_corner-over/...``); pairs are
    ``<name>_color.png`` + ``<name>_depth.png``.

    Every row is checked: an unknown class id, a variant the class does not have, or a
    pair listed twice is an error unless ``lenient``, which skips the row and lists it;
    a row whose files are missing is listed and kept (reading it fails, and a batch
    reports it among its failures).

    Returns
    -------
    pairs : list of LabelledPair
    problems : list of LabelProblem
        Each problem once, by line of ``labels.csv`` (or by pair for class folders).

    Raises
    ------
    UnreadableInputError, InvalidInputError
        The folder is missing, ``labels.csv`` is malformed, no pair is found, or (not
        ``lenient``) a row has an unknown class or variant or repeats another.
    """
    import csv

    root = Path(folder)
    if not root.is_dir():
        raise UnreadableInputError(f"folder '{root}' does not exist or is not a directory")
    labels = root / "labels.csv"
    pairs = []
    where = []
    if labels.is_file():
        try:
            with labels.open(newline="", encoding="utf-8") as fh:
                reader = csv.DictReader(fh)
                missing = {"color", "depth", "label"} - set(reader.fieldnames or [])
                if missing:
                    raise InvalidInputError(
                        f"labels file '{labels}' lacks column(s) {', '.join(sorted(missing))}; "
                        "expected color,depth,label[,variant]"
                    )
                for k, row in enumerate(reader, start=2):
                    label = (row.get("label") or "").strip()
                    if not row.get("color") or not row.get("depth") or not label:
                        raise InvalidInputError(f"labels file '{labels}' line {k} is incomplete")
                    variant = (row.get("variant") or "").strip() or None
                    pairs.append(
                        LabelledPair(
                            str(root / row["color"]),
                            str(root / row["depth"]),
                            label.zfill(2),
                            variant,
                            k,
                        )
                    )
                    where.append(f"'{labels}' line {k}")
        except (OSError, UnicodeDecodeError, csv.Error) as exc:
            raise UnreadableInputError(f"cannot read labels file '{labels}': {exc}") from None
    else:
        for color in sorted(root.rglob("*_color.png")):
            rel = color.relative_to(root)
            if len(rel.parts) < 2:
                continue  # no class folder: unlabelled
            head = rel.parts[0]
            label = head[:2]
            if not label.isdigit():
                continue
            depth = color.with_name(color.name[: -len("_color.png")] + "_depth.png")
            pairs.append(LabelledPair(str(color), str(depth), label))
            where.append(f"'{color}'")
    if not pairs:
        raise InvalidInputError(
            f"folder '{root}' holds no labelled pairs (no labels.csv and no "
            "<class>_*/<name>_color.png files)"
        )
    pairs, problems = _check_labels(pairs, where)
    fatal = [p for p in problems if p.kind != "missing file"]
    if fatal and not lenient:
        more = f" (and {len(fatal) - 1} more)" if len(fatal) > 1 else ""
        raise InvalidInputError(f"{fatal[0].message}{more}; fix the labels or use --lenient")
    if not pairs:
        raise InvalidInputError(f"folder '{root}' holds no usable labelled pairs")
    return sorted(pairs, key=lambda p: p.color), problems
