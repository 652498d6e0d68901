"""``dgli calibrate``: the printed sticker colours, the camera's handedness (and the
lens) from one image of the flat napkin."""

from __future__ import annotations

import sys
from dataclasses import replace
from typing import Any

import click

from .errors import handle_errors
from .options import intrinsics_option, overwrite_option
from .output import command_line, echo, package_version


@click.command()
@click.argument("color", type=click.Path())
@click.argument("depth", type=click.Path())
@click.option(
    "-o",
    "--output",
    type=click.Path(),
    help="Colours file to write (JSON). Required unless --lens-out is given.",
)
@click.option(
    "--lens-out",
    type=click.Path(),
    help="Also estimate the lens distortion (k1, k2) and write the intrinsics with it: "
    'Open3D JSON with "distortion", or an OpenCV file for .yaml/.yml/.xml.',
)
@click.option(
    "--intrinsics-out",
    type=click.Path(),
    help="Write the intrinsics (as given, or as found beside COLOR) with the camera's "
    'handedness, "mirrored": true or false (Open3D JSON, or an OpenCV file for '
    ".yaml/.yml/.xml). --lens-out writes it too.",
)
@click.option(
    "--focal",
    is_flag=True,
    help="With --lens-out, estimate the focal length too (from the stickers' depths).",
)
@intrinsics_option
@overwrite_option
@handle_errors
def calibrate(
    color: str,
    depth: str,
    output: str | None,
    lens_out: str | None,
    intrinsics_out: str | None,
    focal: bool,
    intrinsics: str | None,
    overwrite: bool,
) -> None:
    """Measure the printed sticker colours, the camera's handedness (and the lens) from
    one image of the flat napkin, lying unfolded and front face up.

    All 16 stickers must be in view. Use the colours with --colours on classify and
    evaluate when stickers print far from the nominal colours. The handedness (does the
    camera mirror its image?) is said, and written as "mirrored" into the intrinsics of
    --intrinsics-out and --lens-out: put that file beside the images as intrinsics.json,
    or give it with --intrinsics (a camera not declared mirrored is taken as not
    mirrored). With --lens-out, the
    radial lens distortion is fitted to the 16 sticker centres as to a chessboard. It is
    determined only if the stickers reach well towards the image border (place the napkin
    off to one side, towards a corner); otherwise nothing is written and the exit code
    is 1.
    """
    from ..core.io import guard_outputs
    from ..sources.frames import read_frame

    if output is None and lens_out is None and intrinsics_out is None:
        raise click.UsageError(
            "give -o FILE (the colours), --intrinsics-out FILE (the camera's handedness) "
            "and/or --lens-out FILE (the lens)"
        )
    if focal and lens_out is None:
        raise click.UsageError("--focal needs --lens-out")
    guard_outputs([p for p in (output, lens_out, intrinsics_out) if p], overwrite=overwrite)
    frame = read_frame(color, depth, intrinsics)
    if output is not None:
        _calibrate_colours(frame, color, output, overwrite)
    mirrored = _calibrate_handedness(frame, color)
    if intrinsics_out is not None:
        _write_intrinsics(replace(frame.intrinsics, mirrored=mirrored), intrinsics_out,
                          overwrite)
    if lens_out is None:
        return
    _calibrate_lens(frame, color, lens_out, focal, overwrite, mirrored)


def _calibrate_handedness(frame: Any, color: str) -> bool:
    """Whether the camera of ``frame`` mirrors its image, said in one line."""
    from ..core.layout import default_layout
    from ..perception.calibrate import calibrate_handedness

    mirrored = calibrate_handedness(
        frame.color, frame.depth_mm, frame.intrinsics, default_layout(), source=color
    )
    echo(
        "handedness: the camera mirrors its image (the stickers run the other way round "
        "than printed; or is the napkin back face up?)" if mirrored
        else "handedness: the camera does not mirror its image (the stickers run as printed)"
    )
    return mirrored


def _write_intrinsics(intr: Any, path: str, overwrite: bool) -> None:
    """Write intrinsics ``intr`` to ``path`` (by its extension) and say so."""
    from pathlib import Path

    from ..core.io import write_outputs
    from ..sources.intrinsics_files import intrinsics_text

    write_outputs({Path(path): intrinsics_text(intr, path)}, overwrite=overwrite,
                  command=command_line())
    echo(f"wrote {path}")


def _calibrate_colours(frame: Any, color: str, output: str, overwrite: bool) -> None:
    """Measure the sticker colours of ``frame`` (read from ``color``), write them to
    ``output`` and list them."""
    from ..core.layout import default_layout
    from ..perception.calibrate import calibrate_colours
    from ..sources.colours_file import write_colours

    colours = calibrate_colours(
        frame.color, frame.depth_mm, frame.intrinsics, default_layout(), source=color
    )
    write_colours(
        output,
        colours,
        {"command": command_line(), "package_version": package_version()},
        overwrite=overwrite,
    )
    for name, rgb in colours.items():
        echo(f"{name:<7} {rgb}")
    echo(f"wrote {output}")


def _calibrate_lens(
    frame: Any, color: str, lens_out: str, focal: bool, overwrite: bool, mirrored: bool
) -> None:
    """Estimate the lens of ``frame`` (read from ``color``), say what was found, and write
    the intrinsics with it (and the camera's handedness ``mirrored``) to ``lens_out``;
    exit 1 without writing when the view does not determine it."""
    from ..core.layout import default_layout
    from ..perception.lens import estimate_lens

    est = estimate_lens(
        frame.color,
        frame.depth_mm,
        frame.intrinsics,
        default_layout(),
        fit_focal=focal,
        source=color,
    )
    for line in _lens_lines(est):
        echo(line)
    if est.problem is not None:
        click.echo(
            f"error: '{color}': lens poorly constrained, {lens_out} not written: {est.problem}",
            err=True,
        )
        sys.exit(1)
    _write_intrinsics(replace(est.intrinsics, mirrored=mirrored), lens_out, overwrite)


def _lens_lines(est: Any) -> list[str]:
    """What ``dgli calibrate --lens-out`` says about a :class:`LensEstimate`."""
    import math

    import numpy as np

    def term(name: str, value: float, sd: float, unit: str = "") -> str:
        if math.isnan(sd):
            return f"{name} {value:.4g}{unit} (held fixed: not determined by this view)"
        return f"{name} {value:.4f}{unit} +/- {sd:.4f}{unit}"

    intr = est.intrinsics
    focal = (
        f"focal length {est.focal:.1f} +/- {est.focal_sd:.1f} px"
        if not math.isnan(est.focal_sd)
        else f"focal length {intr.fx:.1f} px (as given)"
    )
    quality = "poorly constrained" if est.problem else "determined"
    return [
        f"lens ({quality}): {term('k1', est.k1, est.k1_sd)}; {term('k2', est.k2, est.k2_sd)}",
        f"{focal}; principal point ({intr.cx:.1f}, {intr.cy:.1f}) (as given)",
        f"the stickers reach {est.reach:.0%} of the way to the image corner; fit residual "
        f"{est.rms_px:.2f} px rms",
        f"sticker shift by the lens: max {est.shift_px.max():.1f} px, "
        f"median {float(np.median(est.shift_px)):.1f} px",
    ]
