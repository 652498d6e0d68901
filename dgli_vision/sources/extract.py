"""Write a recording's frames as a folder of PNG pairs (``dgli extract``): the
labelled-folder format with a ``frames.csv`` of times, which every command reads.

Frames are decoded and written one at a time (two writer threads; PNG encoding releases
the GIL), so memory does not grow with the episode.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..core.camera import Intrinsics
from ..core.errors import DgliError, InvalidInputError, OutputError, UnreadableInputError
from ..core.frame import RGBDFrame
from ..core.io import (
    csv_table,
    guard_outputs,
    record_outputs,
    remove_earlier_outputs,
    write_json,
    write_text,
)
from .frames import write_color, write_depth
from .labelled import LabelledPair, listed_files
from .recording import Recording, select_frames

__all__ = ["ExtractResult", "extract_recording", "listing_files"]


@dataclass
class ExtractResult:
    """What :func:`extract_recording` wrote.

    Attributes
    ----------
    written : int
        Frames written.
    skipped : list of str
        Frames that could not be written (no depth near them, an image that does not
        decode), one line each.
    frames_csv : Path
    """

    written: int = 0
    skipped: list[str] = field(default_factory=list)
    frames_csv: Path | None = None


def listing_files(out: str | Path) -> list[Path]:
    """The files :func:`extract_recording` lists its frames in (``frames.csv``,
    ``intrinsics.json``, ``labels.csv``)."""
    root = Path(out)
    return [root / "frames.csv", root / "intrinsics.json", root / "labels.csv"]


def extract_recording(
    recording: Recording,
    out: str | Path,
    *,
    every: int = 1,
    start: float | None = None,
    end: float | None = None,
    overwrite: bool = False,
    command: str = "",
    on_progress: Callable[[int], None] | None = None,
) -> ExtractResult:
    """Write ``recording``'s frames to ``out`` as ``frame_NNNNNN_color.png`` /
    ``_depth.png``, ``intrinsics.json``, ``frames.csv`` (``color,depth,time``, seconds
    from the start) and, for a labelled recording, ``labels.csv``.

    Parameters
    ----------
    recording : Recording
    out : str or Path
    every : int, keyword-only
        Keep every N-th frame (frame numbers keep counting all frames).
    start, end : float, keyword-only, optional
        Seconds from the start of the recording.
    overwrite : bool, keyword-only
        Replace files dgli did not write. The files an earlier run listed in ``out``'s
        ``frames.csv`` and ``labels.csv`` (and those lists) are removed first when dgli
        wrote them (any of them with ``overwrite``), so that a rerun that keeps fewer
        frames leaves none of the earlier ones beside its list.
    command : str, keyword-only
        Recorded beside the files.
    on_progress : callable, keyword-only
        Called with 1 per frame read.

    Raises
    ------
    OverwriteError, InvalidInputError
        A file in the way; frames of different sizes or intrinsics in one recording; no
        frame to write (none in the time window, or none that decodes).
    OutputError
        A file that cannot be written (a full disk...): the frames written before it are
        kept, recorded and named in the message.
    """
    root = Path(out)
    # (and makes OUT: an impossible OUT fails here)
    guard_outputs(listing_files(root), overwrite=overwrite)
    # an earlier extract's frames and lists go first: none is left beside the new list
    remove_earlier_outputs(root, listed_files(root), overwrite=overwrite)
    result = ExtractResult()
    written: list[Path] = []
    window = {"every": every, "start": start, "end": end}
    done = _write_frames(recording, root, window, overwrite, command, on_progress, result, written)
    if not done.rows:
        if done.failure is not None:
            raise done.failure
        raise InvalidInputError(_nothing_to_extract(recording, done.seen, start, end, result))
    _write_listing(root, recording, done, written)
    record_outputs(written, command)
    result.written = len(done.rows)
    result.frames_csv = root / "frames.csv"
    if done.failure is not None:  # what was read is a listed folder, never an unlisted half
        n = len(done.rows)
        raise UnreadableInputError(
            f"{done.failure}; the {n} frame{'s' if n != 1 else ''} read before it "
            f"{'are' if n != 1 else 'is'} written to '{root}' and listed in frames.csv"
        )
    return result


@dataclass(frozen=True)
class _FramesWritten:
    """The image pairs written: one row ``(colour, depth, time, label, variant)`` each,
    the recording's intrinsics (None when no frame decoded), the frames read and, when
    the recording could not be read to its end (truncated, corrupt), why."""

    rows: list[tuple[str, str, str, str, str]]
    intrinsics: Intrinsics | None
    seen: int
    failure: UnreadableInputError | None = None


def _same_intrinsics(pair: LabelledPair, frame: RGBDFrame, intr: Intrinsics | None) -> Intrinsics:
    """The recording's intrinsics: the first frame's, which every frame must share."""
    if intr is None:
        return frame.intrinsics
    if frame.intrinsics != intr:
        raise InvalidInputError(
            f"{pair.color}: the camera intrinsics change within the recording; a "
            "folder holds one intrinsics.json: extract each part with --start/--end"
        )
    return intr


def _write_frames(
    recording: Recording,
    root: Path,
    window: dict[str, Any],
    overwrite: bool,
    command: str,
    on_progress: Callable[[int], None] | None,
    result: ExtractResult,
    written: list[Path],
) -> _FramesWritten:
    """Decode the frames in ``window`` (``every``, ``start``, ``end``) one at a time and
    write their PNGs with two threads; undecodable frames go to ``result.skipped``; a
    recording that cannot be read further ends the frames (its error is kept)."""
    rows: list[tuple[str, str, str, str, str]] = []
    intr = None
    seen = 0
    failure = None
    jobs: list[tuple[Future, Path]] = []
    selected = select_frames(recording.frames, **window)
    with ThreadPoolExecutor(2) as pool:
        try:
            while True:
                try:
                    index, pair = next(selected)
                except StopIteration:
                    break
                except UnreadableInputError as exc:
                    failure = exc
                    break
                seen += 1
                if on_progress:
                    on_progress(1)
                try:
                    frame = pair.load()
                except DgliError as exc:
                    result.skipped.append(str(exc))
                    continue
                intr = _same_intrinsics(pair, frame, intr)
                name = f"frame_{index:06d}"
                color, depth = root / f"{name}_color.png", root / f"{name}_depth.png"
                guard_outputs([color, depth], overwrite=overwrite)
                while len(jobs) >= 4:  # a few frames in flight, never the whole episode
                    _finish(jobs.pop(0), written)
                jobs.append((pool.submit(write_color, color, frame.color), color))
                jobs.append((pool.submit(write_depth, depth, frame.depth_mm), depth))
                t = "" if pair.time is None else f"{pair.time:.6f}"
                rows.append((color.name, depth.name, t, pair.label, pair.variant or ""))
            while jobs:
                _finish(jobs.pop(0), written)
        except OutputError as exc:
            raise _kept_frames(exc, jobs, written, root, command) from None
    return _FramesWritten(rows, intr, seen, failure)


def _write_listing(
    root: Path, recording: Recording, done: _FramesWritten, written: list[Path]
) -> None:
    """``intrinsics.json``, ``frames.csv`` and, for a labelled recording, ``labels.csv``."""
    rows = done.rows
    if done.intrinsics is not None:
        write_json(root / "intrinsics.json", done.intrinsics.to_open3d_dict())
        written.append(root / "intrinsics.json")
    write_text(root / "frames.csv", csv_table(["color", "depth", "time"], [r[:3] for r in rows]))
    written.append(root / "frames.csv")
    if recording.labelled and rows and all(r[3] for r in rows):
        labels = [(c, d, lab, var) for c, d, _, lab, var in rows]
        write_text(root / "labels.csv", csv_table(["color", "depth", "label", "variant"], labels))
        written.append(root / "labels.csv")


def _finish(job: tuple[Future, Path], written: list[Path]) -> None:
    """Wait for one image write; the file is then written (or its OutputError raised)."""
    job[0].result()
    written.append(job[1])


def _kept_frames(
    exc: OutputError,
    jobs: list[tuple[Future, Path]],
    written: list[Path],
    root: Path,
    command: str,
) -> OutputError:
    """The error of a write that failed midway, naming the frames written before it;
    they are recorded as dgli's own (a rerun replaces them without --overwrite)."""
    for future, path in jobs:  # the writes still in flight end one way or the other
        try:
            future.result()
            written.append(path)
        except DgliError:
            pass
    names = {p.name for p in written}
    frames = sorted(
        p.name[: -len("_color.png")]
        for p in written
        if p.name.endswith("_color.png") and p.name.replace("_color", "_depth") in names
    )
    try:
        record_outputs(written, command)
    except DgliError:
        pass  # the disk that is full cannot take the record either
    if not frames:
        return OutputError(f"{exc}; no frame was written before it")
    return OutputError(
        f"{exc}; the {len(frames)} frame(s) written before it are kept in '{root}' "
        f"({frames[0]} to {frames[-1]}), without frames.csv"
    )


def _nothing_to_extract(
    recording: Recording,
    seen: int,
    start: float | None,
    end: float | None,
    result: ExtractResult,
) -> str:
    """Why no frame was written (nothing is written then, not even an empty frames.csv)."""
    if seen == 0:
        window = [
            f"from {start:g} s" if start is not None else "",
            f"to {end:g} s" if end is not None else "",
        ]
        span = " ".join(w for w in window if w)
        window_text = f" {span}" if span else ""
        return f"recording '{recording.source}' holds no frame{window_text}: nothing written"
    first = f" (the first: {result.skipped[0]})" if result.skipped else ""
    return (
        f"{'not even the one frame' if seen == 1 else f'none of the {seen} frames'} of "
        f"recording '{recording.source}' could be written"
        f"{first}: nothing written"
    )
