"""``dgli write-recording``: a folder of PNG pairs as a ROS bag or a RealSense recording."""

from __future__ import annotations

import click

from ..core.words import counted
from .errors import handle_errors
from .options import overwrite_option
from .output import progress_bar


@click.command("write-recording")
@click.argument("folder", type=click.Path())
@click.argument("out", type=click.Path())
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["ros1", "ros2-mcap", "ros2-sqlite3", "realsense"]),
    default=None,
    help="The recording's format [default: by OUT's suffix: .bag ROS 1, .mcap ROS 2 "
    "(MCAP), .db3 RealSense, no suffix a ROS 2 bag folder].",
)
@click.option(
    "--fps",
    default=30.0,
    show_default=True,
    type=click.FloatRange(min=0.001),
    help="Frames a second, for frames without a time in frames.csv.",
)
@click.option(
    "--uncompressed",
    is_flag=True,
    help="A ROS 2 MCAP recording's chunks as they are (default: each compressed with "
    "zstd, which every MCAP reader reads).",
)
@overwrite_option
@handle_errors
def write_recording_cmd(
    folder: str, out: str, fmt: str | None, fps: float, uncompressed: bool, overwrite: bool
) -> None:
    """Write the frames of FOLDER (PNG pairs, in the order of its frames.csv or by name)
    to OUT as a recording: a ROS 1 bag (.bag), a ROS 2 bag (.mcap, .db3 with --format
    ros2-sqlite3, or a bag folder) or a RealSense SDK recording (.db3).

    The recording has the RealSense ROS driver's topics (colour, depth aligned to colour
    in millimetres, the colour CameraInfo with FOLDER's intrinsics.json) and reads back
    with dgli track, evaluate and extract. A ROS 2 MCAP recording's chunks are
    compressed with zstd. OUT must not exist, unless --overwrite is given (it is then
    replaced once the new recording is whole).
    """
    from ..sources.recording import read_recording
    from ..sources.write_recording import write_recording

    count = len(list(read_recording(folder).frames))
    with progress_bar(count, "writing") as bar:
        path, n = write_recording(folder, out, fmt=fmt, fps=fps,
                                  on_frame=lambda: bar.update(1), overwrite=overwrite,
                                  compress=not uncompressed)
    click.echo(f"wrote {counted(n, 'frame')} to {path}", err=True)
