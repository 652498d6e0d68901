"""One run per output folder, and a resume only of the same run.

A command that keeps its work in a folder (``dgli evaluate --report``, ``dgli track
--report``, ``dgli render``) takes :class:`RunLock` on it before its first write and
gives it back when it ends: a second run into the same folder stops at once, naming the
first one's process, instead of interleaving its lines with the first's. The lock is an
advisory ``flock`` on :data:`LOCK_NAME`, so a run killed outright leaves nothing that
blocks the next one (the stale file, naming a dead process, is taken over).

A run's journal (``results.jsonl``) starts with a header that records what defines the
run (:func:`run_header`): the inputs, references, colours, labels and intrinsics by
checksum, and the options that change the results. ``--resume`` goes on with a journal
only when the header matches the run being started (:func:`check_resume`); otherwise it
stops and names what differs. Each result in it records the size and modification time
of the images it was read from (:func:`files_stamp`): a pair captured again under the
same names since is classified again (:func:`current_results`).
"""

from __future__ import annotations

import hashlib
import json
import os
import socket
import stat
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from .errors import OutputError, ResumeMismatchError, RunBusyError

__all__ = [
    "LOCK_NAME",
    "RESULTS_FORMAT",
    "RunLock",
    "check_resume",
    "current_results",
    "file_digest",
    "files_stamp",
    "intrinsics_digest",
    "listing_digest",
    "repair_journal",
    "run_header",
]

#: The lock file a run keeps in its output folder while it works.
LOCK_NAME = ".dgli-lock"
#: ``format`` of the first line of a run's ``results.jsonl``.
RESULTS_FORMAT = "dgli-run"

#: What each recorded field of a run is, for the message naming a difference.
FIELD_NAMES = {
    "command": "command",
    "input": "input folder or recording",
    "labels": "labels",
    "pairs": "list of pairs",
    "references": "reference set",
    "colours": "sticker colours (--colours)",
    "intrinsics": "camera intrinsics",
    "options": "options",
}


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # alive, someone else's
        return True
    return True


class RunLock:
    """The lock of one output folder, held from :meth:`acquire` to :meth:`release` (or
    the end of a ``with`` block, or the process's end, whichever comes first).

    Parameters
    ----------
    folder : path
        The output folder (made if missing).
    command : str
        Recorded in the lock file, for the message another run gives.

    Raises
    ------
    RunBusyError
        From :meth:`acquire`: a live process holds the folder's lock.
    OutputError
        From :meth:`acquire`: the lock file cannot be written (a full disk), naming it.
    """

    def __init__(self, folder: str | Path, command: str = "") -> None:
        self.folder = Path(folder)
        self.path = self.folder / LOCK_NAME
        self.command = command
        self._fd: int | None = None
        self.took_over: dict[str, Any] | None = None

    def __enter__(self) -> RunLock:
        self.acquire()
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()

    def acquire(self) -> None:
        """Take the lock, or raise :class:`RunBusyError` naming the holder."""
        import fcntl

        for _ in range(20):  # the holder may remove the file between our open and flock
            try:
                self.folder.mkdir(parents=True, exist_ok=True)
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as exc:
                raise RunBusyError(f"cannot write into '{self.folder}': {exc.strerror}") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                holder = _read_holder(fd)
                os.close(fd)
                raise RunBusyError(self._busy_message(holder)) from None
            try:
                same = os.stat(self.path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if not same:  # locked a file its holder had just removed: try again
                os.close(fd)
                continue
            earlier = _read_holder(fd)
            if earlier.get("pid") and not _pid_alive(int(earlier["pid"])):
                self.took_over = earlier
            record = {
                "pid": os.getpid(),
                "host": socket.gethostname(),
                "started": time.strftime("%Y-%m-%dT%H:%M:%S"),
                "command": self.command,
            }
            try:
                os.ftruncate(fd, 0)
                os.pwrite(fd, (json.dumps(record) + "\n").encode(), 0)
            except OSError as exc:  # a full disk: not even the lock's line fits
                self._fd = fd
                self.release()
                raise OutputError(
                    f"cannot write '{self.path}': {exc.strerror or exc}; nothing was written"
                ) from None
            self._fd = fd
            return
        raise RunBusyError(f"cannot take the lock '{self.path}': it keeps changing")

    def _busy_message(self, holder: dict[str, Any]) -> str:
        who = f"pid {holder['pid']}" if holder.get("pid") else "another process"
        if holder.get("host") and holder["host"] != socket.gethostname():
            who += f" on {holder['host']}"
        since = f", since {holder['started']}" if holder.get("started") else ""
        what = f": {holder['command']}" if holder.get("command") else ""
        return (
            f"'{self.folder}' is in use by another dgli run ({who}{since}{what}); "
            "wait for it to end, or write to another folder"
        )

    def release(self) -> None:
        """Give the lock back and remove its file (nothing if not held)."""
        if self._fd is None:
            return
        try:
            self.path.unlink()
        except FileNotFoundError:
            pass
        os.close(self._fd)  # closing drops the flock
        self._fd = None


def _read_holder(fd: int) -> dict[str, Any]:
    """The record a lock file holds (empty if none or unreadable)."""
    try:
        data = json.loads(os.pread(fd, 4096, 0).decode() or "{}")
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


# --- what defines a run --------------------------------------------------------------


def file_digest(path: str | Path | None) -> str | None:
    """SHA-256 of a file's bytes (hex), or None when there is no such file."""
    if path is None:
        return None
    p = Path(path)
    if not p.is_file():
        return None
    digest = hashlib.sha256()
    with p.open("rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def listing_digest(rows: Iterable[Iterable[object]]) -> str:
    """SHA-256 of rows of values (e.g. each pair's paths and labels), in order."""
    digest = hashlib.sha256()
    for row in rows:
        digest.update(json.dumps([None if v is None else str(v) for v in row]).encode())
        digest.update(b"\n")
    return digest.hexdigest()


def intrinsics_digest(color_paths: Iterable[str | Path]) -> str | None:
    """One SHA-256 over the ``intrinsics.json`` files beside the colour images (the ones
    :func:`~dgli_vision.sources.frames.read_frame` reads); None when there are none (nominal)."""
    folders = sorted({str(Path(p).resolve().parent) for p in color_paths})
    found = [(f, file_digest(Path(f) / "intrinsics.json")) for f in folders]
    found = [(f, d) for f, d in found if d is not None]
    return listing_digest(found) if found else None


def files_stamp(*paths: str | Path) -> list[int] | None:
    """``[size, mtime_ns]`` of each file, one after the other: what a result in a journal
    records of the images it was read from (cheap: no file is read). None when any is
    not a file (a recording's frame, named but not a file of its own)."""
    out: list[int] = []
    for path in paths:
        try:
            st = os.stat(path)
        except (OSError, ValueError):
            return None
        if not stat.S_ISREG(st.st_mode):
            return None
        out += [st.st_size, st.st_mtime_ns]
    return out


def current_results(items: list[Any]) -> tuple[list[Any], int]:
    """The results of a journal (after its header) whose images are still those they
    were read from, and how many are not: a pair whose colour or depth file has another
    size or time now (captured again under the same name), or a result that does not
    record them (an older dgli's), is left out, so that it is classified again."""
    kept, stale = [], 0
    for item in items:
        pair = item.get("pair") if isinstance(item, dict) else None
        if not isinstance(pair, dict):
            kept.append(item)  # not a result: left for the caller to skip
            continue
        now = files_stamp(pair.get("color", ""), pair.get("depth", ""))
        if now is not None and item.get("files") != now:
            stale += 1
            continue
        kept.append(item)
    return kept, stale


def run_header(kind: str, fields: dict[str, Any]) -> dict[str, Any]:
    """The first line of a run's ``results.jsonl``: ``kind`` (``"evaluate"``,
    ``"track"``) and the fields that define the run (JSON values)."""
    return {"format": RESULTS_FORMAT, "version": 1, "kind": kind, "run": fields}


def _short(value: Any) -> str:
    text = json.dumps(value, sort_keys=True) if not isinstance(value, str) else value
    if isinstance(value, str) and len(value) == 64:  # a checksum
        text = f"sha256 {value[:12]}"
    return text if len(text) <= 60 else text[:57] + "..."


def check_resume(journal: str | Path, first: Any, header: dict[str, Any]) -> None:
    """Check that the journal whose first object is ``first`` was written by the run
    ``header`` describes.

    Raises
    ------
    ResumeMismatchError
        Naming the first field that differs (references, labels, ...) with both values,
        or saying that the journal records no run (written by another dgli version, or
        not by dgli).
    """
    again = "; start again with --overwrite, or report into another folder"
    if not isinstance(first, dict) or first.get("format") != RESULTS_FORMAT:
        raise ResumeMismatchError(
            f"cannot resume '{journal}': it does not record which run wrote it "
            f"(an older dgli, or not dgli){again}"
        )
    if first.get("kind") != header["kind"]:
        raise ResumeMismatchError(
            f"cannot resume '{journal}': it holds the results of 'dgli {first.get('kind')}', "
            f"not 'dgli {header['kind']}'{again}"
        )
    was, now = first.get("run") or {}, header["run"]
    for key in sorted(set(was) | set(now), key=lambda k: (k not in FIELD_NAMES, k)):
        if was.get(key) != now.get(key):
            if isinstance(was.get(key), dict) and isinstance(now.get(key), dict):
                inner = sorted(set(was[key]) | set(now[key]))
                sub = next(k for k in inner if was[key].get(k) != now[key].get(k))
                name = f"option {sub}"
                before, after = was[key].get(sub), now[key].get(sub)
            else:
                name = FIELD_NAMES.get(key, key)
                if key == "pairs" and header["kind"] == "track":  # a recording's frames
                    name = "list of frames"
                before, after = was.get(key), now.get(key)
            raise ResumeMismatchError(
                f"cannot resume '{journal}': {name} changed since its run "
                f"(then {_short(before)}, now {_short(after)}){again}"
            )


def repair_journal(path: str | Path) -> None:
    """Cut a last line left half-written (a run killed while writing it), so that lines
    appended next start on a line of their own."""
    p = Path(path)
    try:
        with p.open("rb+") as fh:
            size = fh.seek(0, os.SEEK_END)
            if size == 0:
                return
            fh.seek(size - 1)
            if fh.read(1) == b"\n":
                return
            step, end = 4096, size
            while end > 0:
                start = max(0, end - step)
                fh.seek(start)
                block = fh.read(end - start)
                cut = block.rfind(b"\n")
                if cut >= 0:
                    fh.truncate(start + cut + 1)
                    return
                end = start
            fh.truncate(0)
    except FileNotFoundError:
        return


def run_header_of(
    kind: str,
    folder: str,
    pairs: Any,
    *,
    labels_path: str | None,
    refs_path: Any,
    colours_path: str | None,
    options: dict[str, Any],
) -> dict[str, Any]:
    """What defines a run of ``kind`` on ``folder``, for its results.jsonl: the input (a
    folder by path, its pairs by their list, labels and intrinsics files by checksum; a
    recording file by path, size and time), the references and colours by checksum, and
    the options that change results.

    ``pairs`` are the folder's pairs, None for a recording file."""
    root = Path(folder).resolve()
    if pairs is None:
        st = root.stat()  # a recording is known by its size and time, not read twice
        source = listing_digest([(str(root), st.st_size, st.st_mtime_ns)])
        listing, intrinsics = None, None
    else:
        source = str(root)
        listing = listing_digest(
            (os.path.relpath(p.color, root), os.path.relpath(p.depth, root)) for p in pairs
        )
        intrinsics = intrinsics_digest(p.color for p in pairs)
    labels = file_digest(labels_path) if labels_path else file_digest(root / "labels.csv")
    if labels is None and pairs is not None:  # class folders
        labels = listing_digest((p.label, p.variant) for p in pairs)
    fields = {
        "input": source,
        "pairs": listing,
        "labels": labels,
        "references": file_digest(refs_path),
        "colours": file_digest(colours_path),
        "intrinsics": intrinsics,
        "options": {k: v for k, v in sorted(options.items()) if k != "labels_path"},
    }
    return run_header(kind, fields)
