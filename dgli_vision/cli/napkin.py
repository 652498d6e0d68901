"""``dgli stickers`` and ``dgli coords``: the napkin's sticker kit and its flat
coordinates."""

from __future__ import annotations

import click

from .errors import handle_errors
from .options import json_option, overwrite_option, size_option
from .output import command_line, echo, echo_json


@click.command()
@click.argument("out", type=click.Path(dir_okay=False))
@size_option
@overwrite_option
@handle_errors
def stickers(out: str, size_mm: tuple[float, float] | None, overwrite: bool) -> None:
    """Write the printable sticker kit to OUT (SVG in millimetres, prints at 1:1) and a
    PNG preview beside it.

    The kit holds every sticker twice (front and back face) and a placement template for
    each corner, with a 100 mm bar to check the print scale.
    """
    from pathlib import Path

    from ..core.errors import InvalidInputError
    from ..core.io import write_outputs
    from ..core.layout import layout_of_size
    from ..sim.sticker_sheet import sheet_image, sheet_svg, sticker_sheet

    svg = Path(out)
    if svg.suffix.lower() != ".svg":
        raise InvalidInputError(f"'{out}': the sticker kit is written as SVG; name it *.svg")
    preview = svg.with_suffix(".png")
    sheet = sticker_sheet(layout_of_size(size_mm))
    write_outputs(
        {svg: sheet_svg(sheet), preview: sheet_image(sheet)},
        overwrite=overwrite,
        command=command_line(),
    )
    echo(f"wrote {svg} (print at 100 %, A3) and its preview {preview}")


@click.command()
@json_option("Print a JSON object.")
@handle_errors
def coords(as_json: bool) -> None:
    """Show the 28 dGLI cloth coordinates of the flat napkin."""
    from ..core.dgli import pair_indices
    from ..core.layout import default_layout

    layout = default_layout()
    values = layout.flat_coordinates()
    i, j = pair_indices(layout.n_segments)
    if as_json:
        echo_json({"state": "flat", "unit": "1/m", "coordinates": values.tolist()})
        return
    echo("dGLI cloth coordinates of the flat napkin (1/m), segment pairs i-j:")
    for a, b, v in zip(i, j, values):
        echo(f"  {a}-{b}  {v + 0.0:+.6f}")
