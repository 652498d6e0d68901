"""Writing and reading files in general: text, JSON, JSON lines, PNG and PLY files, and the
record of what the tool wrote (never replace a user's file).

The readers of each file format live by what they read: :mod:`.frames` (RGB-D pairs and
intrinsics), :mod:`.labelled` (labelled folders), :mod:`.database_files` (simulated
databases), :mod:`.colours_file` (calibrated colours) and :mod:`.references` (reference sets).
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .errors import (
    DgliError,
    InvalidInputError,
    OutputError,
    OverwriteError,
    UnreadableInputError,
)
from .words import counted

__all__ = [
    "JsonLinesWriter",
    "check_input_file",
    "csv_table",
    "display_path",
    "failed_part_way",
    "file_sha256",
    "guard_outputs",
    "image_bytes",
    "mesh_ply_bytes",
    "read_json",
    "read_jsonl",
    "read_mesh_ply",
    "record_outputs",
    "remove_earlier_outputs",
    "write_files",
    "write_json",
    "write_mesh_ply",
    "write_outputs",
    "write_png",
    "write_recorded",
    "write_text",
]


def display_path(path: str | Path, limit: int = 160) -> str:
    """A path for a one-line message: a very long one keeps its start and its end."""
    text = str(path)
    return text if len(text) <= limit else f"{text[:80]}...{text[-60:]}"


def _unwritable(p: Path, reason: str) -> OutputError:
    return OutputError(f"cannot write '{display_path(p)}': {reason}")


def _remove_partial(p: Path) -> None:
    """Remove what a failed write left of a regular file (never a device such as
    /dev/full, nor what a symbolic link points to)."""
    try:
        if p.is_file() and not p.is_symlink():
            p.unlink()
    except OSError:
        pass


def _write_bytes(p: Path, data: bytes) -> None:
    """Write ``data`` to ``p``, creating parent folders, whole or not at all: into a
    temporary file beside it, renamed over ``p`` once complete (a full disk, a kill
    part-way leave the earlier file as it was, or none, and never a truncated one).
    A device or FIFO (``/dev/stdout``) and what a symbolic link points to are written in
    place.

    Raises
    ------
    OutputError
        Naming the file and the operating system's reason (no space left on device,
        permission denied, file name too long...).
    """
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _unwritable(p, f"cannot make its folder ({exc.strerror or exc})") from None
    try:
        st = p.lstat()
    except OSError:
        st = None
    if st is not None and not stat.S_ISREG(st.st_mode):  # a device, FIFO or link
        try:
            with p.open("wb") as fh:
                fh.write(data)
        except OSError as exc:
            _remove_partial(p)
            raise _unwritable(p, exc.strerror or str(exc)) from None
        return
    _write_whole(p, data, None if st is None else stat.S_IMODE(st.st_mode))


def _write_whole(p: Path, data: bytes, mode: int | None) -> None:
    """``data`` into a temporary file in ``p``'s folder, renamed to ``p`` when complete;
    the file gets ``mode`` (a replaced file's), or the usual mode of a new file."""
    import tempfile

    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{p.name[:100]}.", suffix=".part", dir=p.parent)
    except OSError as exc:
        raise _unwritable(p, exc.strerror or str(exc)) from None
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.chmod(tmp, mode if mode is not None else 0o666 & ~_umask())
        os.replace(tmp, p)
    except OSError as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise _unwritable(p, exc.strerror or str(exc)) from None


def _umask() -> int:
    """The process's file-creation mask (read by setting it and setting it back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_text(path: str | Path, text: str) -> None:
    """Write ``text`` to ``path`` (UTF-8), creating parent folders.

    Raises
    ------
    OutputError
        If the file cannot be written (a truncated file is not left behind).
    """
    _write_bytes(Path(path), text.encode("utf-8"))


def check_input_file(path: str | Path, what: str) -> os.stat_result:
    """The status of an input file that must exist and be a regular file.

    Raises
    ------
    UnreadableInputError
        Missing; a directory; a FIFO, device or socket (reading it would block or never
        end); or a path the system cannot look up (too long, a symbolic link loop, no
        permission), each said so.
    """
    p = Path(path)
    try:
        st = p.stat()
    except FileNotFoundError:
        raise UnreadableInputError(f"{what} '{display_path(p)}' does not exist") from None
    except OSError as exc:
        raise UnreadableInputError(
            f"{what} '{display_path(p)}' cannot be read: {exc.strerror or exc}"
        ) from None
    if stat.S_ISDIR(st.st_mode):
        raise UnreadableInputError(f"{what} '{p}' is a directory; expected a file")
    if not stat.S_ISREG(st.st_mode):
        kind = "a FIFO (named pipe)" if stat.S_ISFIFO(st.st_mode) else "a device or socket"
        raise UnreadableInputError(f"{what} '{p}' is {kind}, not a regular file")
    return st


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
    check_input_file(p, what)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise UnreadableInputError(f"cannot read {what} '{p}': {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
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
    """Write a triangle mesh (vertices in metres) as a binary little-endian PLY: float64
    x, y, z per vertex, a uchar count and uint32 indices per face (the layout Open3D
    writes and reads), whole or not at all (:func:`_write_bytes`).

    Raises
    ------
    OutputError
        Naming the file and the reason (a full disk...); no partial file is left.
    """
    data = mesh_ply_bytes(xyz, triangles)
    _write_bytes(Path(path), data)


def mesh_ply_bytes(xyz: NDArray, triangles: NDArray) -> bytes:
    """The bytes of :func:`write_mesh_ply`'s file: ``xyz`` (n, 3) vertices and
    ``triangles`` (k, 3) vertex indices."""
    v = np.ascontiguousarray(xyz, dtype="<f8").reshape(-1, 3)
    t = np.asarray(triangles).reshape(-1, 3)
    faces = np.empty(len(t), dtype=[("n", "u1"), ("v", "<u4", (3,))])
    faces["n"] = 3
    faces["v"] = t
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment Created by dgli_vision\n"
        f"element vertex {len(v)}\nproperty double x\nproperty double y\n"
        f"property double z\nelement face {len(t)}\n"
        "property list uchar uint vertex_indices\nend_header\n"
    )
    return header.encode("ascii") + v.tobytes() + faces.tobytes()


def read_mesh_ply(path: str | Path) -> tuple[NDArray[np.float64], NDArray[np.int32]]:
    """Read a PLY triangle mesh: vertices (n, 3) and triangles (k, 3)."""
    from .optional import open3d

    o3d = open3d("reading a PLY mesh")

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


def _ours(entry: Any, path: Path) -> bool:
    """Whether a record's entry vouches for the file at ``path`` as it is now: its
    checksum, or the one it had when the entry was written just before replacing it
    (``"before"``: a process killed between the record and the rename)."""
    if not isinstance(entry, dict):
        return False
    sha = file_sha256(path)
    return entry.get("sha256") == sha or entry.get("before") == sha


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
    """Refuse to replace an existing file that dgli did not write, and make the folders
    the files go to: a command calls this before its work, so that an output it could
    never write stops it at once rather than after the work.

    A file may be replaced when it does not exist, when ``overwrite`` is set, or when the
    record of its folder (:data:`MANIFEST_NAME`, kept by :func:`record_outputs`) lists it
    with the checksum it still has: the tool's own earlier output, untouched since.

    Raises
    ------
    OverwriteError
        Naming the first file that would be replaced.
    OutputError
        A folder that cannot be made or written into, or a path the system cannot look
        up (too long...).
    """
    manifests: dict[Path, dict[str, Any]] = {}
    folders: dict[Path, Path] = {}
    for path in paths:
        p = Path(path)
        try:
            is_dir, exists = p.is_dir(), p.exists()
        except OSError as exc:
            raise _unwritable(p, exc.strerror or str(exc)) from None
        if is_dir:
            raise OverwriteError(f"'{p}' is a directory; expected a file to write")
        folders.setdefault(p.parent, p)
        if overwrite or not exists:
            continue
        folder = p.parent
        if folder not in manifests:
            manifests[folder] = _manifest(folder)
        if _ours(manifests[folder].get(p.name), p) or signed_ours(p):
            continue
        raise OverwriteError(
            f"refusing to replace '{p}': dgli did not write it (or it was changed since); "
            "use --overwrite to replace it"
        )
    for folder, first in folders.items():
        _make_writable_folder(folder, first)


def _make_writable_folder(folder: Path, first: Path) -> None:
    """Make ``folder`` (and its parents); ``first`` is a file to go there, for messages."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise _unwritable(first, f"cannot make its folder ({exc.strerror or exc})") from None
    if not os.access(folder, os.W_OK):
        raise _unwritable(first, f"its folder '{display_path(folder)}' is not writable")


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


def write_recorded(files: Sequence[tuple[Path, bytes]], command: str) -> None:
    """Write files whole (each renamed into place once complete), recording each in its
    folder's record (:func:`record_outputs`) *before* it is written, with the checksum
    it is to have and, under ``"before"``, the one it has: a process killed at any
    instant leaves each file old or new, and the record vouching for it either way (so
    that ``--resume`` replaces it without ``--overwrite``). The caller has checked the
    files with :func:`guard_outputs`.

    Raises
    ------
    OutputError
        Naming the file that could not be written (or its folder's record).
    """
    by_folder: dict[Path, list[tuple[Path, bytes]]] = {}
    for path, data in files:
        by_folder.setdefault(Path(path).parent, []).append((Path(path), data))
    for folder, items in by_folder.items():
        listed = _manifest(folder)
        for p, data in items:
            entry: dict[str, Any] = {"sha256": hashlib.sha256(data).hexdigest(),
                                     "command": command}
            try:
                now = file_sha256(p) if p.is_file() else None
            except OSError:
                now = None
            if now is not None and now != entry["sha256"]:
                entry["before"] = now
            listed[p.name] = entry
        write_json(
            folder / MANIFEST_NAME,
            {"format": MANIFEST_FORMAT, "version": 1, "files": dict(sorted(listed.items()))},
        )
    for path, data in files:
        _write_bytes(Path(path), data)


def remove_earlier_outputs(
    folder: str | Path, names: Iterable[str], *, overwrite: bool = False
) -> list[Path]:
    """Remove the files an earlier run listed in ``folder`` (``names``, relative to it)
    that dgli wrote and that are unchanged since (any of them with ``overwrite``), and
    drop them from their folders' records: a rerun that writes fewer files (``extract
    --every 3``, a smaller ``render``) leaves none of the earlier ones beside its new
    list. A name outside ``folder``, a file dgli did not write (without ``overwrite``) or
    one that is not there is left alone.

    Returns
    -------
    list of Path
        The files removed.

    Raises
    ------
    OutputError
        A file that cannot be removed (no permission...), naming it.
    """
    root = Path(folder)
    try:
        base = root.resolve()
    except OSError:
        return []
    by_folder: dict[Path, list[Path]] = {}
    for name in dict.fromkeys(names):
        p = root / name
        try:
            inside = p.resolve().is_relative_to(base) and p.resolve() != base
            if not inside or p.is_symlink() or not p.is_file():
                continue
        except (OSError, ValueError):
            continue
        by_folder.setdefault(p.parent, []).append(p)
    removed: list[Path] = []
    for sub, files in by_folder.items():
        listed = _manifest(sub)
        gone = []
        for p in files:
            if not (_ours(listed.get(p.name), p) or overwrite):
                continue
            try:
                p.unlink()
            except FileNotFoundError:
                pass
            except OSError as exc:
                raise OutputError(
                    f"cannot remove '{display_path(p)}', listed by the earlier run: "
                    f"{exc.strerror or exc}"
                ) from None
            gone.append(p)
        if gone and listed:
            for p in gone:
                listed.pop(p.name, None)
            write_json(
                sub / MANIFEST_NAME,
                {"format": MANIFEST_FORMAT, "version": 1, "files": dict(sorted(listed.items()))},
            )
        removed += gone
    return removed


def _kept(written: list[Path]) -> str:
    """``the 3 files written before it are kept: a, b, c`` (a few named, the rest counted)."""
    if not written:
        return "nothing was written before it"
    names = ", ".join(f"'{p}'" for p in written[:3])
    more = f" and {len(written) - 3} more" if len(written) > 3 else ""
    if len(written) == 1:
        return f"the file written before it is kept: {names}"
    return f"the {len(written)} files written before it are kept: {names}{more}"


def write_files(
    files: Iterable[tuple[Path, str | dict | bytes | NDArray[np.uint8]]], *, command: str
) -> list[Path]:
    """Write files (text, JSON, bytes or a BGR image each) in order and record them
    (:func:`record_outputs`); the caller has checked them with :func:`guard_outputs`.

    Raises
    ------
    OutputError
        On the first file that cannot be written, naming it, the reason and the files
        written before it, which are kept and recorded as dgli's own (so that running
        the command again replaces them without ``--overwrite``).
    """
    written: list[Path] = []
    try:
        for path, content in files:
            p = Path(path)
            if isinstance(content, str):
                write_text(p, content)
            elif isinstance(content, dict):
                write_json(p, content)
            elif isinstance(content, bytes):
                _write_bytes(p, content)
            else:
                write_png(p, content)
            written.append(p)
    except OutputError as exc:
        raise failed_part_way(exc, written, command) from None
    try:
        record_outputs(written, command)
    except OutputError as exc:
        raise OutputError(
            f"{exc}; the {counted(len(written), 'file')} are written and kept, but a later "
            "run needs --overwrite to replace them"
        ) from None
    return written


def failed_part_way(exc: OutputError, written: list[Path], command: str) -> OutputError:
    """The error of a set of files that failed part-way: ``exc`` naming the files written
    before it, which are kept and recorded as dgli's own (so that running the command
    again replaces them without ``--overwrite``)."""
    try:
        record_outputs(written, command)
    except DgliError:
        pass  # the disk that is full cannot take the record either
    return OutputError(f"{exc}; {_kept(written)}")


def write_outputs(
    files: dict[Path, str | dict | bytes | NDArray[np.uint8]], *, overwrite: bool,
    command: str,
) -> None:
    """Write a set of report files (text, JSON, bytes or a BGR image each), after checking with
    :func:`guard_outputs` that none replaces a user's file, and record them.

    Raises
    ------
    OverwriteError, OutputError
        See :func:`write_files`.
    """
    guard_outputs(files, overwrite=overwrite)
    write_files(files.items(), command=command)


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
    """Appends one JSON object per line, each line whole or not at all, so that whatever
    stops the process (Ctrl-C, a kill, a full disk) keeps every line written before it
    and no torn one: a line goes to the file in one ``os.write`` of all its bytes
    (nothing of it is buffered in the process), and a write that fails or takes only
    part of them is cut back off the file (the file's length before it is restored)."""

    def __init__(self, path: str | Path, *, append: bool) -> None:
        p = Path(path)
        flags = os.O_WRONLY | os.O_CREAT | (os.O_APPEND if append else os.O_TRUNC)
        try:
            p.parent.mkdir(parents=True, exist_ok=True)
            self._fd: int | None = os.open(p, flags, 0o666)
            self._size = os.fstat(self._fd).st_size
        except OSError as exc:
            raise _unwritable(p, exc.strerror or str(exc)) from None
        self.path = p
        self.lines = 0
        self._failed = False

    def write(self, obj: Any) -> None:
        """Append ``obj`` as one line, whole, to the operating system's copy of the file.

        Raises
        ------
        OutputError
            Naming the file, the reason and how many lines before it are kept (the
            line that failed is not left in part).
        """
        data = (json.dumps(obj) + "\n").encode("utf-8")
        try:
            if self._fd is None:
                raise OSError(9, "the file is closed")
            n = os.write(self._fd, data)
            if n != len(data):  # a filling disk took part of it
                raise OSError(28, os.strerror(28))
        except OSError as exc:
            self._failed = True
            self._cut_back()
            if self.lines == 0:
                kept = "no line was written before it"
            else:
                lines = "1 line" if self.lines == 1 else f"{self.lines} lines"
                kept = f"the {lines} written before it are kept"
            raise _unwritable(self.path, f"{exc.strerror or exc}; {kept}") from None
        self._size += len(data)
        self.lines += 1

    def _cut_back(self) -> None:
        """Restore the file's length before the failed line (best effort: a file that
        cannot be truncated keeps the part, which :func:`read_jsonl` leaves out)."""
        if self._fd is None:
            return
        try:
            os.ftruncate(self._fd, self._size)
        except OSError:
            pass

    def close(self) -> None:
        """Close the file (after a failed write, quietly: that failure was reported)."""
        fd, self._fd = self._fd, None
        if fd is None:
            return
        try:
            os.close(fd)
        except OSError as exc:
            if not self._failed:
                raise _unwritable(self.path, exc.strerror or str(exc)) from None


def write_png(path: str | Path, image_bgr: NDArray[np.uint8]) -> None:
    """Write a BGR (or single-channel) image, PNG or JPEG by the file's extension,
    creating parent folders.

    Raises
    ------
    OutputError
        An extension OpenCV has no writer for, an image it cannot encode, or a file that
        cannot be written (with the operating system's reason).
    """
    _write_bytes(Path(path), image_bytes(path, image_bgr))


def image_bytes(path: str | Path, image_bgr: NDArray[np.uint8]) -> bytes:
    """A BGR (or single-channel) image encoded as the file ``path`` would hold it (PNG
    or JPEG by its extension); see :func:`write_png`.

    Raises
    ------
    OutputError
        An extension OpenCV has no writer for, or an image it cannot encode.
    """
    import cv2

    p = Path(path)
    ext = p.suffix.lower()
    if not ext or not cv2.haveImageWriter(f"x{ext}"):
        raise _unwritable(
            p, f"no image writer for '{ext or p.name}' files; name it *.png or *.jpg"
        )
    try:
        ok, encoded = cv2.imencode(ext, image_bgr)
    except cv2.error as exc:
        raise _unwritable(p, f"OpenCV cannot encode the image ({exc.err})") from None
    if not ok:
        raise _unwritable(p, "OpenCV cannot encode the image")
    return encoded.tobytes()


#: The keyword of the text a picture written to a path of the user's choosing carries
#: (``dgli classify --overlay x.png``): the checksum of the rest of the file, so that
#: dgli knows its own picture, untouched since, without a record beside it.
SIGNATURE_KEY = b"dgli-output"


def signed_image(data: bytes) -> bytes:
    """A PNG or JPEG file's bytes with a text carrying the checksum of the file without
    it (a PNG ``tEXt`` chunk after its header, a JPEG comment after its start): what
    :func:`signed_ours` checks. Another format is returned as it is."""
    import hashlib
    import struct
    import zlib

    sha = hashlib.sha256(data).hexdigest().encode()
    if data.startswith(b"\x89PNG\r\n\x1a\n") and data[12:16] == b"IHDR":
        body = b"tEXt" + SIGNATURE_KEY + b"\0" + b"sha256=" + sha
        chunk = struct.pack(">I", len(body) - 4) + body + struct.pack(">I", zlib.crc32(body))
        return data[:33] + chunk + data[33:]
    if data.startswith(b"\xff\xd8"):
        text = SIGNATURE_KEY + b" sha256=" + sha
        return data[:2] + b"\xff\xfe" + struct.pack(">H", len(text) + 2) + text + data[2:]
    return data


def signed_ours(path: Path) -> bool:
    """Whether ``path`` is a picture :func:`signed_image` wrote, unchanged since (its
    bytes without the signature have the checksum the signature gives)."""
    import hashlib
    import struct

    try:
        with path.open("rb") as f:
            head = f.read(33 + 12 + len(SIGNATURE_KEY) + 8 + 64)
            if head.startswith(b"\x89PNG\r\n\x1a\n"):
                (n,) = struct.unpack(">I", head[33:37])
                body = head[37 : 41 + n]
                prefix = b"tEXt" + SIGNATURE_KEY + b"\0sha256="
                if not body.startswith(prefix):
                    return False
                want, cut = body[len(prefix) :], (33, 33 + 12 + n)
            elif head.startswith(b"\xff\xd8\xff\xfe"):
                (n,) = struct.unpack(">H", head[4:6])
                body = head[6 : 4 + n]
                prefix = SIGNATURE_KEY + b" sha256="
                if not body.startswith(prefix):
                    return False
                want, cut = body[len(prefix) :], (2, 4 + n)
            else:
                return False
            f.seek(0)
            data = f.read()
    except (OSError, struct.error):
        return False
    rest = data[: cut[0]] + data[cut[1] :]
    return hashlib.sha256(rest).hexdigest().encode() == want


def write_picture(path: str | Path, image_bgr: NDArray[np.uint8], *, overwrite: bool) -> None:
    """Write one picture to a path the user named (``--overlay OUT.png``), PNG or JPEG by
    its extension, signed (:func:`signed_image`) instead of recorded beside it: no
    ``.dgli-outputs.json`` is left in the user's folder. An existing file is replaced
    when ``overwrite`` is set or when it is dgli's own signed picture, untouched since.

    Raises
    ------
    OverwriteError, OutputError
        As :func:`guard_outputs` and :func:`write_png`.
    """
    p = Path(path)
    guard_outputs([p], overwrite=overwrite)
    _write_bytes(p, signed_image(image_bytes(p, image_bgr)))


def csv_table(header: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """A CSV table (RFC 4180 quoting)."""
    import csv
    import io as _io

    buf = _io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    return buf.getvalue()
