"""``dgli extract``: the frames of a recording as a folder of PNG pairs."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from ..core.words import counted
from .errors import handle_errors
from .options import finite_seconds, overwrite_option, recording_options
from .output import command_line, echo, progress_bar
from .runs import folder_lock, open_recording_with, recording_notes


@click.command()
@click.argument("recording_path", metavar="RECORDING", type=click.Path())
@click.argument("out", type=click.Path(file_okay=False))
@click.option(
    "--every", default=1, show_default=True, type=click.IntRange(1), help="Keep every N-th frame."
)
@click.option(
    "--start",
    type=float,
    default=None,
    callback=finite_seconds,
    help="First second to keep, from the start of the recording.",
)
@click.option(
    "--end",
    type=float,
    default=None,
    callback=finite_seconds,
    help="Last second to keep, from the start of the recording.",
)
@recording_options
@overwrite_option
@handle_errors
def extract(
    recording_path: str,
    out: str,
    every: int,
    start: float | None,
    end: float | None,
    overwrite: bool,
    **recording_opts: Any,
) -> None:
    """Write the frames of RECORDING (a ROS or RealSense bag) to OUT as PNG pairs.

    OUT gets frame_NNNNNN_color.png / _depth.png (NNNNNN: the frame's number in the
    recording), intrinsics.json, frames.csv (color,depth,time in seconds from the start)
    and, with --labels, labels.csv: the folder format every command reads. Frames that
    cannot be written (no depth near them in time) are listed, not lost silently. One
    run at a time writes into OUT (a second stops at once, naming the first).
    """
    from ..core.errors import InvalidInputError
    from ..core.io import guard_outputs
    from ..sources.extract import extract_recording, listing_files

    if start is not None and end is not None and end < start:
        raise InvalidInputError(f"--end {end} is before --start {start}")
    recording = open_recording_with(recording_path, recording_opts)
    # an OUT that cannot be written stops here; then one run at a time writes into it,
    # as with every command that writes a folder
    guard_outputs(listing_files(out), overwrite=overwrite)
    with folder_lock(Path(out)), progress_bar(recording.count, "extracting") as bar:
        result = extract_recording(
            recording,
            out,
            every=every,
            start=start,
            end=end,
            overwrite=overwrite,
            command=command_line(),
            on_progress=bar.update,
        )
    recording_notes(recording)
    for line in result.skipped:
        click.echo(f"skipped: {line}", err=True)
    echo(f"wrote {counted(result.written, 'frame')} to {out} (frames: {result.frames_csv})")
