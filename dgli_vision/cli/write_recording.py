"""``dgli write-recording``: a folder of PNG pairs as a ROS bag or a RealSense recording."""

from __future__ import annotations

import click

from ..core.words import counted
from .errors import handle_errors
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
@handle_errors
def write_recording_cmd(folder: str, out: str, fmt: str | None, fps: float) -> None:
    """Write the frames of FOLDER (PNG pairs, in the order of its frames.csv or by name)
    to OUT as a recording: a ROS 1 bag (.bag), a ROS 2 bag (.mcap, .db3 with --format
    ros2-sqlite3, or a bag folder) or a RealSense SDK recording (.db3).

    The recording has the RealSense ROS driver's topics (colour, depth aligned to colour
    in millimetres, the colour CameraInfo with FOLDER's intrinsics.json) and reads back
    with dgli track, evaluate and extract. OUT must not exist.
    """
    from ..sources.recording import read_recording
    from ..sources.write_recording import write_recording

    count = len(list(read_recording(folder).frames))
    with progress_bar(count, "writing") as bar:
        path, n = write_recording(folder, out, fmt=fmt, fps=fps,
                                  on_frame=lambda: bar.update(1))
    click.echo(f"wrote {counted(n, 'frame')} to {path}", err=True)
