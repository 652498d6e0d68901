"""``dgli stickers --paper A4|Letter|A3``: the kit on the paper a home printer has, a page
per corner where A3's rows do not fit, every shape inside the page's printable area, and
dashed cut lines dashed in the preview too."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.cli import main
from dgli_vision.core.layout import default_layout
from dgli_vision.sim.sticker_sheet import (
    PAPERS,
    Circle,
    Line,
    Text,
    sheet_image,
    sheet_svg,
    sticker_pages,
)

MARGIN_MM = 5.0  # what a printer cannot print at the paper's edge


def _extent(shape) -> tuple[float, float, float, float]:
    if isinstance(shape, Circle):
        return shape.x - shape.r, shape.y - shape.r, shape.x + shape.r, shape.y + shape.r
    if isinstance(shape, Line):
        return (min(shape.x0, shape.x1), min(shape.y0, shape.y1), max(shape.x0, shape.x1),
                max(shape.y0, shape.y1))
    width = 0.5 * shape.size * len(shape.text)  # generous for a sans-serif font
    return shape.x, shape.y - shape.size, shape.x + width, shape.y


@pytest.mark.parametrize("paper", ["A4", "Letter"])
def test_every_page_fits_its_paper_and_all_stickers_are_there(paper):
    layout = default_layout()
    pages = sticker_pages(layout, paper)
    assert [name for name, _ in pages] == list(layout.corner_names)
    ids = set()
    for _, sheet in pages:
        assert (sheet.width_mm, sheet.height_mm) == PAPERS[paper]
        for shape in sheet.shapes:
            x0, y0, x1, y1 = _extent(shape)
            assert MARGIN_MM <= x0 and x1 <= sheet.width_mm - MARGIN_MM, shape
            assert MARGIN_MM <= y0 and y1 <= sheet.height_mm - MARGIN_MM, shape
        svg = sheet_svg(sheet)
        assert f'width="{sheet.width_mm:g}mm"' in svg and f"on {paper}" in svg
        ids |= {s.id for s in sheet.shapes if isinstance(s, Circle) and s.id}
    for k in range(layout.n_stickers):
        assert {f"front-{k}-disc", f"back-{k}-disc"} <= ids
    assert {f"template-{c}-corner" for c in layout.corner_names} <= ids


def test_the_cli_writes_a_page_per_corner_and_says_how_to_print(tmp_path):
    res = CliRunner().invoke(main, ["stickers", str(tmp_path / "kit.svg"), "--paper", "letter"])
    assert res.exit_code == 0, res.output
    for corner in "ABCD":
        assert (tmp_path / f"kit-{corner}.svg").is_file()
    assert (tmp_path / "kit.png").is_file() and not (tmp_path / "kit.svg").exists()
    assert "print at 100 %, actual size, on Letter" in res.output


def test_dashed_lines_are_dashed_in_the_preview():
    _, sheet = sticker_pages(default_layout(), "A4")[0]
    dashed = next(s for s in sheet.shapes if isinstance(s, Line) and s.dash and s.y0 == s.y1)
    img = sheet_image(sheet)
    row = img[round(dashed.y0 * 3.0), round(dashed.x0 * 3.0) + 2: round(dashed.x1 * 3.0) - 2]
    ink = row.min(axis=1) < 230
    assert 0.3 < ink.mean() < 0.8  # on and off, not one solid line
    assert np.any(np.diff(ink.astype(int)) != 0)


def test_a3_is_still_one_page():
    (name, sheet), = sticker_pages(default_layout(), "A3")
    assert name == "" and (sheet.width_mm, sheet.height_mm) == PAPERS["A3"]
    assert not any(isinstance(s, Text) and "page 1 of" in s.text for s in sheet.shapes)
