"""Reading and writing files: the only module of the library that touches the disk."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .database import StateRecords
from .dgli import cloth_coordinates
from .errors import InvalidInputError, UnreadableInputError
from .references import ReferenceSet, references_from_dict, references_to_dict

if TYPE_CHECKING:
    from .cloth.states import ClothState

__all__ = [
    "file_sha256",
    "read_database",
    "read_json",
    "read_mesh_ply",
    "read_references",
    "write_database",
    "write_json",
    "write_mesh_ply",
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


# --- simulated databases -------------------------------------------------------------

DB_FORMAT = "dgli-simulated-db"


def write_database(
    out: str | Path, states: list[tuple[str, ClothState]], provenance: dict[str, Any]
) -> Path:
    """Write states as ``meshes/<id>.ply``, ``truth/<id>.json`` and ``index.json``.

    Returns
    -------
    Path
        The index file.
    """
    root = Path(out)
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
    return index


def read_database(path: str | Path) -> tuple[StateRecords, dict[str, Any]]:
    """Read a database folder (or its ``index.json``) into records and provenance.

    Raises
    ------
    UnreadableInputError, InvalidInputError
        Naming the file that is missing or wrong.
    """
    p = Path(path)
    index_path = p / "index.json" if p.is_dir() else p
    index = read_json(index_path, what="database index")
    if not isinstance(index, dict) or index.get("format") != DB_FORMAT:
        raise InvalidInputError(f"'{index_path}' is not a dgli simulated database index")
    root = index_path.parent
    ids, classes, variants, points, vis, frac, corners, boundary = ([] for _ in range(8))
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
    )
    return records, dict(index.get("provenance") or {})


def read_references(path: str | Path) -> ReferenceSet:
    """Load a reference set file (see :mod:`dgli_vision.references`)."""
    return references_from_dict(read_json(path, what="reference set"), source=str(path))


def write_references(path: str | Path, refs: ReferenceSet) -> None:
    """Write a reference set as JSON."""
    write_json(path, references_to_dict(refs))


def write_png(path: str | Path, image_bgr: NDArray[np.uint8]) -> None:
    """Write a BGR uint8 image as PNG, creating parent folders."""
    import cv2

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(p), image_bgr):
        raise UnreadableInputError(f"cannot write image '{p}'")
