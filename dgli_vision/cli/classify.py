"""``dgli classify`` (also ``dgli-classify``): one colour + depth pair."""

from __future__ import annotations

import sys

import click

from .errors import handle_errors
from .options import (
    colours_option,
    extrinsics_option,
    image_output,
    intrinsics_option,
    json_option,
    mirroring_option,
    overwrite_option,
    params_option,
    references_option,
)
from .output import echo, echo_json, verdict_json


@click.command("classify")
@click.argument("color", type=click.Path())
@click.argument("depth", type=click.Path())
@intrinsics_option
@references_option
@colours_option
@params_option
@extrinsics_option
@mirroring_option
@json_option("Print one JSON object.")
@click.option(
    "--overlay",
    type=click.Path(dir_okay=False),
    callback=image_output,
    help="Write the image with stickers, segments and verdict (PNG or JPEG).",
)
@overwrite_option
@handle_errors
def classify_cmd(
    color: str,
    depth: str,
    intrinsics: str | None,
    references_path: str | None,
    colours_path: str | None,
    params_path: str | None,
    extrinsics_path: str | None,
    mirroring: str | None,
    as_json: bool,
    overlay: str | None,
    overwrite: bool,
) -> None:
    """Classify the cloth state in one colour + depth pair.

    Exit 1 when no class can be given: too few stickers seen, or a confidence below
    the documented threshold ("cannot tell", with the reason). With --extrinsics the
    JSON's 3D points (corners, folds, the table's normal "up") are in the robot's base
    frame. With --mirroring yes (or "mirrored": true in the intrinsics) the frame is read
    un-mirrored, and the overlay shows it so.
    """

    from ..analysis.overlay import frame_overlay, verdict_line
    from ..classifier.pipeline import classify_frame
    from ..classifier.references import load_references
    from ..core.extrinsics import read_extrinsics
    from ..core.io import guard_outputs, write_picture
    from ..perception.params import read_params
    from ..sources.colours_file import read_colours
    from ..sources.frames import read_frame

    extrinsics = read_extrinsics(extrinsics_path) if extrinsics_path else None
    if overlay:
        guard_outputs([overlay], overwrite=overwrite)
    frame = read_frame(color, depth, intrinsics)
    refs = load_references(references_path)
    colours = read_colours(colours_path) if colours_path else None
    params = read_params(params_path) if params_path else None
    result = classify_frame(frame, refs, colours=colours, mirroring=mirroring, params=params)
    if overlay:  # signed, not recorded: nothing hidden is left beside the user's file
        write_picture(
            overlay, frame_overlay(result.frame_as_read(frame), result), overwrite=overwrite
        )
    if as_json:
        echo_json(verdict_json(result, color, depth, extrinsics))
    else:
        echo(verdict_line(result))
    if result.prediction is None:  # said once, on stdout: an answer, not an error
        sys.exit(1)
