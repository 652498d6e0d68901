"""Writing and reading files in general: text, JSON, JSON lines, PNG and PLY files, and the
record of what the tool wrote (never replace a user's file).

The readers of each file format live by what they read: :mod:`.frames` (RGB-D pairs and
intrinsics), :mod:`.labelled` (labelled folders), :mod:`.database_files` (simulated
databases), :mod:`.colours_file` (calibrated colours) and :mod:`.references` (reference sets).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .errors import InvalidInputError, OverwriteError, UnreadableInputError

__all__ = [
    "JsonLinesWriter",
    "file_sha256",
    "guard_outputs",
    "read_json",
    "read_jsonl",
    "read_mesh_ply",
    "record_outputs",
    "write_json",
    "write_mesh_ply",
    "write_outputs",
    "write_png",
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


def write_png(path: str | Path, image_bgr: NDArray[np.uint8]) -> None:
    """Write a BGR uint8 image as PNG, creating parent folders."""
    import cv2

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(p), image_bgr):
        raise UnreadableInputError(f"cannot write image '{p}'")
