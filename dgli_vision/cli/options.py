"""Options, decorators and parameter types shared by the ``dgli`` commands: one name,
one help text, one validation each."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import click

from ..sim.condition_names import CONDITION_HELP

F = TypeVar("F", bound=Callable[..., Any])


# Options shared by several commands: one name, one help text, one validation.
intrinsics_option = click.option(
    "--intrinsics",
    type=click.Path(),
    help='Camera intrinsics: Open3D JSON (with optional lens "distortion"), an OpenCV '
    "calibration file or a ROS camera_info YAML (default: intrinsics.json beside COLOR, else "
    "nominal Kinect).",
)


#: ``--extrinsics FILE``: every 3D point of the answer in the robot's base frame
#: (:mod:`dgli_vision.core.extrinsics`), read in the command (errors: one line, exit 2).
extrinsics_option = click.option(
    "--extrinsics",
    "extrinsics_path",
    type=click.Path(),
    help="Camera-to-base transform: a JSON 4x4 matrix (row-major, metres) or a ROS "
    "TransformStamped YAML; every 3D point of the answer is then in the robot's base "
    'frame, named by "frame" in the JSON [default: the camera frame].',
)


#: ``--mirroring no|yes|unknown``: the camera's handedness
#: (:func:`dgli_vision.core.handedness.camera_mirroring`); None: as the intrinsics declare.
mirroring_option = click.option(
    "--mirroring",
    type=click.Choice(["no", "yes", "unknown"]),
    default=None,
    help="Whether the camera mirrors its image left to right: no; yes (its frames are "
    "read un-mirrored); unknown (02, 03, 09 and 10 then never reach confidence 0.5: a "
    "napkin back face up under a mirroring camera shows their twin) [default: as the "
    'intrinsics declare ("mirrored", written by dgli calibrate), else no].',
)


colours_option = click.option(
    "--colours",
    "colours_path",
    type=click.Path(),
    help="Sticker colours measured by 'dgli calibrate' [default: the printed nominal ones].",
)


params_option = click.option(
    "--params",
    "params_path",
    type=click.Path(),
    help='Perception parameters to change: a JSON file {"stage": {"field": value}} '
    '(docs/params.md; e.g. {"detector": {"min_saturation": 100}}) [default: the defaults].',
)


references_option = click.option(
    "--references",
    "references_path",
    type=click.Path(),
    help="Reference set file [default: references/default.json or $DGLI_REFERENCES].",
)


#: The largest napkin side ``--size`` takes, mm. The simulated cloth is a 5 mm grid, so
#: memory and time grow with the area: a 1000 mm napkin's database (``dgli simulate
#: --per-class 1``) takes about a minute and 1.7 GB.
MAX_NAPKIN_MM = 1000.0


def parse_size(
    ctx: click.Context, param: click.Parameter, value: str | None
) -> tuple[float, float] | None:
    """The callback of a ``--size W[xH]`` option: the sides in mm, each within
    :func:`~dgli_vision.core.layout.smallest_side_mm` and :data:`MAX_NAPKIN_MM`."""
    from ..core.layout import parse_size

    if value is None:
        return None
    try:  # each side within the range, named with it when not (1e30 was too small for H)
        return parse_size(value, largest_mm=MAX_NAPKIN_MM)
    except ValueError as exc:
        raise click.BadParameter(str(exc)) from None


#: ``--size W[xH]``: the napkin's size in mm (the stickers keep their distances from the
#: corners; fold sizes scale with the cloth).
size_option = click.option(
    "--size",
    "size_mm",
    callback=parse_size,
    default=None,
    metavar="W[xH]",
    help="Napkin size in mm, e.g. 300 or 500x700 [default: 400]. The stickers keep their "
    "distances from the corners; fold sizes scale with the cloth.",
)


def per_class_option(
    default: int, maximum: int, help_text: str, *, minimum: int = 1
) -> Callable[[F], F]:
    """``--per-class N``: how many of each class, ``minimum`` (1) to ``maximum``: bounded,
    so that a slip of the keyboard (100000) stops at once with a clear message instead of
    running for hours and out of memory."""
    return click.option(
        "--per-class",
        default=default,
        show_default=True,
        type=click.IntRange(minimum, maximum),
        help=f"{help_text} (at most {maximum}).",
    )


#: ``-j/--jobs N``: worker processes, all cores by default.
jobs_option = click.option(
    "-j",
    "--jobs",
    type=click.IntRange(1),
    default=None,
    help="Worker processes [default: all cores].",
)

#: ``-j N`` of the commands that make data (``render``, ``simulate``): one process unless
#: asked, since every worker's results (images, meshes) travel back whole to this one.
make_jobs_option = click.option(
    "-j",
    "--jobs",
    type=click.IntRange(1),
    default=1,
    show_default=True,
    help="Worker processes (the same results as one).",
)


def report_option(help_text: str) -> Callable[[F], F]:
    """``--report DIR``: a folder to write a report into."""
    return click.option("--report", "report_dir", type=click.Path(file_okay=False), help=help_text)


overwrite_option = click.option(
    "--overwrite",
    is_flag=True,
    help="Replace existing files that dgli did not write (never needed for its own output).",
)

#: ``--overwrite`` of the commands that keep a run's results (``results.jsonl``) in their
#: report folder: a second run there needs ``--resume`` (go on) or this (start again).
run_overwrite_option = click.option(
    "--overwrite",
    is_flag=True,
    help="Start again: replace the results.jsonl an earlier run left in the report folder "
    "(without it, or --resume to go on with it, a second run there is refused), and files "
    "dgli did not write. Its own other report files are replaced without asking.",
)


def output_option(help_text: str) -> Callable[[F], F]:
    """``-o/--output FILE``: the file a command writes."""
    return click.option("-o", "--output", required=True, type=click.Path(), help=help_text)


def json_option(help_text: str = "Print one JSON object.") -> Callable[[F], F]:
    """``--json``: machine-readable output on stdout."""
    return click.option("--json", "as_json", is_flag=True, help=help_text)


def recording_options(fn: F) -> F:
    """Options for reading a recorded episode (a ROS or RealSense bag)."""
    options = [
        click.option(
            "--color-topic",
            help="A bag's colour image topic [default: found by type "
            "and name, e.g. /camera/color/image_raw].",
        ),
        click.option(
            "--depth-topic",
            help="A bag's depth topic, aligned to colour [default: "
            "e.g. /camera/aligned_depth_to_color/image_raw].",
        ),
        click.option(
            "--info-topic",
            help="A bag's CameraInfo topic [default: the colour camera's camera_info].",
        ),
        click.option(
            "--tolerance",
            "tolerance_ms",
            type=click.FloatRange(0, min_open=True),
            default=20.0,
            show_default=True,
            help="Largest time between a colour image and its depth, in ms.",
        ),
        click.option(
            "--labels",
            "labels_path",
            type=click.Path(),
            help="A bag's labels: CSV with frame (from 0) or time (s from the start), "
            "label and optionally variant.",
        ),
    ]
    for option in reversed(options):
        fn = option(fn)
    return fn


def parse_conditions(ctx: click.Context, param: click.Parameter, value: str) -> tuple[str, ...]:
    names = tuple(n.strip().lower() for n in value.split(",") if n.strip())  # as Choice
    unknown = [n for n in names if n not in CONDITION_HELP and n != "clean"]
    if unknown:
        raise click.BadParameter(
            f"unknown condition {unknown[0]!r}; expected some of {', '.join(CONDITION_HELP)}"
        )
    return names


def finite_seconds(
    ctx: click.Context, param: click.Parameter, value: float | None
) -> float | None:
    """A time in seconds from the start of a recording: a number, not NaN or infinite."""
    import math

    if value is not None and not math.isfinite(value):
        raise click.BadParameter(f"{value} is not a time in seconds; expected a number")
    return value


def image_output(ctx: click.Context, param: click.Parameter, value: str | None) -> str | None:
    """An image file to write: its extension must name a format OpenCV writes."""
    from pathlib import Path

    if value is not None and Path(value).suffix.lower() not in (".png", ".jpg", ".jpeg"):
        raise click.BadParameter(f"'{value}': name the image *.png or *.jpg")
    return value
