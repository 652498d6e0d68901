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
@click.option(
    "--paper",
    type=click.Choice(["A3", "A4", "Letter"], case_sensitive=False),
    default="A3",
    show_default=True,
    help="The paper it prints on: A3 holds the kit on one page; on A4 or Letter it is a "
    "page per corner, OUT's name with -A, -B, -C, -D.",
)
@overwrite_option
@handle_errors
def stickers(out: str, size_mm: tuple[float, float] | None, paper: str,
             overwrite: bool) -> None:
    """Write the printable sticker kit to OUT (SVG in millimetres, prints at 1:1) and a
    PNG preview beside it.

    The kit holds every sticker twice (front and back face) and a placement template for
    each corner, with a 100 mm bar to check the print scale. Print it at 100 % ("actual
    size", not "fit to page") on the paper given; the bar must then measure 100 mm.
    """
    from pathlib import Path

    import numpy as np

    from ..core.errors import InvalidInputError
    from ..core.io import write_outputs
    from ..core.layout import layout_of_size
    from ..sim.sticker_sheet import PAPERS, sheet_image, sheet_svg, sticker_pages

    svg = Path(out)
    if svg.suffix.lower() != ".svg":
        raise InvalidInputError(f"'{out}': the sticker kit is written as SVG; name it *.svg")
    paper = {p.lower(): p for p in PAPERS}[paper.lower()]
    preview = svg.with_suffix(".png")
    pages = sticker_pages(layout_of_size(size_mm), paper)
    files: dict = {}
    for name, sheet in pages:
        files[svg.with_name(f"{svg.stem}-{name}.svg") if name else svg] = sheet_svg(sheet)
    images = [sheet_image(sheet) for _, sheet in pages]
    gap = np.full((images[0].shape[0], 12, 3), 200, np.uint8)  # the pages side by side
    files[preview] = np.hstack([x for im in images for x in (im, gap)][:-1])
    write_outputs(files, overwrite=overwrite, command=command_line())
    written = ", ".join(str(p) for p in files if p != preview)
    echo(f"wrote {written} (print at 100 %, actual size, on {paper}) and the "
         f"preview {preview}")


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
