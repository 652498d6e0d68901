"""A folder of PNG pairs written as a recording: a ROS 1 bag, a ROS 2 bag (an MCAP or
SQLite file, or a bag folder) or a RealSense SDK recording, with the writers of
:mod:`~dgli_vision.sources.bag_writer` and :mod:`~dgli_vision.sources.realsense_writer`
(what ``dgli write-recording`` runs)."""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from ..core.errors import InvalidInputError, OverwriteError, UnreadableInputError

__all__ = ["RECORDING_FORMATS", "format_of", "write_recording"]

RecordingFormat = Literal["ros1", "ros2-mcap", "ros2-sqlite3", "realsense"]

#: The formats, by what they are.
RECORDING_FORMATS: dict[str, str] = {
    "ros1": "ROS 1 bag (.bag)",
    "ros2-mcap": "ROS 2 bag, MCAP storage (.mcap, or a bag folder)",
    "ros2-sqlite3": "ROS 2 bag, SQLite storage (.db3, or a bag folder)",
    "realsense": "RealSense SDK recording (.db3; the realsense extra)",
}

_BY_SUFFIX: dict[str, RecordingFormat] = {
    ".bag": "ros1", ".mcap": "ros2-mcap", ".db3": "realsense", "": "ros2-mcap",
}


def format_of(out: str | Path, fmt: str | None = None) -> RecordingFormat:
    """The format to write ``out`` in: ``fmt`` when given, else by its suffix (``.bag``:
    ROS 1, ``.mcap``: ROS 2 MCAP, ``.db3``: RealSense, none: a ROS 2 MCAP bag folder).

    Raises
    ------
    InvalidInputError
        An unknown suffix, or a format that cannot have it.
    """
    suffix = Path(out).suffix.lower()
    if fmt is None:
        if suffix not in _BY_SUFFIX:
            raise InvalidInputError(
                f"'{out}': cannot tell the format from '{suffix}'; name it .bag (ROS 1), "
                ".mcap (ROS 2) or .db3 (RealSense), or give --format"
            )
        return _BY_SUFFIX[suffix]
    allowed = {"ros1": (".bag",), "ros2-mcap": (".mcap", ""), "ros2-sqlite3": (".db3", ""),
               "realsense": (".db3", ".bag")}[fmt]
    if suffix not in allowed:
        raise InvalidInputError(
            f"'{out}': a {RECORDING_FORMATS[fmt]} is named "
            + " or ".join(f"*{s}" if s else "a folder" for s in allowed)
        )
    return fmt  # type: ignore[return-value]


def write_recording(
    folder: str | Path,
    out: str | Path,
    *,
    fmt: str | None = None,
    fps: float = 30.0,
    on_frame: Callable[[], None] | None = None,
    overwrite: bool = False,
    compress: bool = True,
) -> tuple[Path, int]:
    """Write the frames of a folder of PNG pairs (in the order of its ``frames.csv``, or
    by name) as a recording.

    Parameters
    ----------
    folder : str or Path
        Read as ``dgli track`` reads a folder; its ``intrinsics.json`` (else the nominal
        intrinsics) goes into the recording.
    out : str or Path
        A new file (or bag folder); its suffix gives the format (:func:`format_of`).
    fmt : str, optional, keyword-only
        One of :data:`RECORDING_FORMATS`.
    fps : float, keyword-only
        Frames a second, for the frames without a time in ``frames.csv``.
    on_frame : callable, optional, keyword-only
        Called after each frame is read (a progress bar).
    overwrite : bool, keyword-only
        Replace ``out`` when it exists (it is replaced only once the new recording is
        whole: a failure keeps the old one).
    compress : bool, keyword-only
        A ROS 2 MCAP recording's chunks compressed with zstd (the default: a tenth of the
        size, or less, for rendered frames); False writes them as they are.

    Returns
    -------
    (Path, int)
        The recording and the frames written.

    Raises
    ------
    OverwriteError
        ``out`` exists (without ``overwrite``).
    InvalidInputError, UnreadableInputError, CalibrationError
        A frame cannot be read, or the frames differ in intrinsics.
    """
    from .frames import read_frame
    from .recording import read_recording

    out = Path(out)
    kind = format_of(out, fmt)
    if out.exists() and not overwrite:
        raise OverwriteError(f"'{out}' exists; choose a new path, or add --overwrite")
    if out.is_dir() and kind != "ros2-mcap" and kind != "ros2-sqlite3":
        raise OverwriteError(f"'{out}' is a folder; a {kind} recording is one file")
    pairs = list(read_recording(folder).frames)
    first = read_frame(pairs[0].color, pairs[0].depth, pairs[0].intrinsics_file)
    intrinsics = first.intrinsics

    def frames() -> Iterator[tuple[float, NDArray[np.uint8], NDArray[np.uint16]]]:
        for k, p in enumerate(pairs):
            frame = first if k == 0 else read_frame(p.color, p.depth, p.intrinsics_file)
            if frame.intrinsics != intrinsics:
                raise InvalidInputError(
                    f"'{p.color}': its intrinsics differ from the first frame's; a "
                    "recording has one camera"
                )
            if on_frame:
                on_frame()
            yield (k / fps if p.time is None else float(p.time)), frame.color, frame.depth_mm

    with tempfile.TemporaryDirectory(prefix=".dgli-recording-", dir=out.parent or ".") as tmp:
        new = Path(tmp) / out.name  # written whole here, then put in place
        _write_as(kind, new, frames(), intrinsics, compress)
        _replace(new, out)
    return out, len(pairs)


def _write_as(
    kind: str, out: Path, frames: Iterator[Any], intrinsics: Any, compress: bool
) -> None:
    """The frames as a new recording of ``kind`` at ``out``."""
    if kind == "realsense":
        from .realsense_writer import write_realsense_recording

        # millimetre depth units (a D400's default): the depth reads back exactly
        write_realsense_recording(out, frames, intrinsics, depth_step=1, depth_scale_m=0.001)
        return
    import importlib.util

    if importlib.util.find_spec("rosbags") is None:
        raise UnreadableInputError(
            "writing a ROS bag needs the 'recordings' extra: pip install "
            "'dgli_vision[recordings]'"
        )
    from .bag_writer import write_bag

    if kind == "ros1" or out.suffix == "":
        write_bag(out, frames, intrinsics, fmt=kind, compress=compress)  # type: ignore[arg-type]
        return
    # one storage file: the bag folder is written beside it, its storage file kept
    bag = out.parent / f"{out.stem}.bag-folder"
    write_bag(bag, frames, intrinsics, fmt=kind, compress=compress)  # type: ignore[arg-type]
    (storage,) = bag.glob(f"*{out.suffix}")
    shutil.move(str(storage), out)


def _replace(new: Path, out: Path) -> None:
    """Put the recording ``new`` (a file or a bag folder) at ``out``, replacing what is
    there only now that the new one is whole."""
    if out.is_dir():
        old = out.with_name(f".{out.name}.old")
        out.rename(old)
        new.rename(out)
        shutil.rmtree(old)
    else:
        os.replace(new, out)
