"""``dgli calibrate``: the printed sticker colours (and the lens) from one image."""

from __future__ import annotations

import sys
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
    focal: bool,
    intrinsics: str | None,
    overwrite: bool,
) -> None:
    """Measure the printed sticker colours (and the lens) from one image of the flat napkin.

    All 16 stickers must be in view. Use the colours with --colours on classify and
    evaluate when stickers print far from the nominal colours. With --lens-out, the
    radial lens distortion is fitted to the 16 sticker centres as to a chessboard. It is
    determined only if the stickers reach well towards the image border (place the napkin
    off to one side, towards a corner); otherwise nothing is written and the exit code
    is 1.
    """
    from ..core.io import guard_outputs
    from ..sources.frames import read_frame

    if output is None and lens_out is None:
        raise click.UsageError("give -o FILE (the colours) and/or --lens-out FILE (the lens)")
    if focal and lens_out is None:
        raise click.UsageError("--focal needs --lens-out")
    guard_outputs([p for p in (output, lens_out) if p], overwrite=overwrite)
    frame = read_frame(color, depth, intrinsics)
    if output is not None:
        _calibrate_colours(frame, color, output, overwrite)
    if lens_out is None:
        return
    _calibrate_lens(frame, color, lens_out, focal, overwrite)


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


def _calibrate_lens(frame: Any, color: str, lens_out: str, focal: bool, overwrite: bool) -> None:
    """Estimate the lens of ``frame`` (read from ``color``), say what was found, and write
    the intrinsics with it to ``lens_out``; exit 1 without writing when the view does not
    determine it."""
    from pathlib import Path

    from ..core.io import write_outputs
    from ..core.layout import default_layout
    from ..perception.lens import estimate_lens
    from ..sources.intrinsics_files import intrinsics_text

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
    text = intrinsics_text(est.intrinsics, lens_out)
    write_outputs({Path(lens_out): text}, overwrite=overwrite, command=command_line())
    echo(f"wrote {lens_out}")


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
