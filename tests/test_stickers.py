"""The printable sticker kit: ``dgli stickers kit.svg`` draws every sticker and the corner
templates at their true size and place (checked by parsing the SVG)."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.cli import main
from dgli_vision.core.layout import default_layout, layout_of_size, parse_size

NS = {"svg": "http://www.w3.org/2000/svg"}
TOL_MM = 0.1


def _kit(tmp_path, *args):
    out = tmp_path / "kit.svg"
    r = CliRunner().invoke(main, ["stickers", str(out), *args])
    assert r.exit_code == 0, r.output
    root = ET.parse(out).getroot()
    circles = {c.get("id"): c for c in root.iterfind(".//svg:circle", NS) if c.get("id")}
    return out, root, circles


def _centre(c) -> np.ndarray:
    return np.array([float(c.get("cx")), float(c.get("cy"))])


def _hex(rgb) -> str:
    return "#{:02x}{:02x}{:02x}".format(*rgb)


def test_the_page_is_in_millimetres_so_it_prints_at_one_to_one(tmp_path):
    _, root, _ = _kit(tmp_path)
    w, h = root.get("width"), root.get("height")
    assert w.endswith("mm") and h.endswith("mm")
    assert root.get("viewBox") == f"0 0 {w[:-2]} {h[:-2]}"  # one user unit = 1 mm


@pytest.mark.parametrize("face", ["front", "back"])
def test_every_sticker_has_its_diameters_and_colours(tmp_path, face):
    layout = default_layout()
    _, _, circles = _kit(tmp_path)
    for k in range(16):
        disc, dot = circles[f"{face}-{k}-disc"], circles[f"{face}-{k}-dot"]
        assert abs(2 * float(disc.get("r")) - layout.disc_diameter_mm) <= TOL_MM
        assert abs(2 * float(dot.get("r")) - layout.dot_diameter_mm) <= TOL_MM
        assert np.abs(_centre(disc) - _centre(dot)).max() <= TOL_MM
        assert disc.get("fill") == _hex(layout.colours_srgb[layout.sticker_disc[k]])
        assert dot.get("fill") == _hex(layout.colours_srgb[layout.sticker_dot[k]])


@pytest.mark.parametrize("size", [None, "300", "500x700"])
def test_template_marks_sit_at_the_sticker_centres_measured_from_each_corner(tmp_path, size):
    layout = layout_of_size(None if size is None else parse_size(size))
    out, root, circles = _kit(tmp_path, *(["--size", size] if size else []))
    marks = 0
    for c, name in enumerate(layout.corner_names):
        corner = _centre(circles[f"template-{name}-corner"])
        for k in range(16):
            mark = circles.get(f"template-{name}-mark-{k}")
            if layout.segment_corners[k // 2] != name:
                assert mark is None
                continue
            du, dv = layout.sticker_uv[k] - layout.corner_uv[c]
            # the napkin is drawn front up: u to the right, v up the page
            np.testing.assert_allclose(_centre(mark) - corner, [du, -dv], atol=TOL_MM)
            marks += 1
    assert marks == 16
    page = np.array([float(root.get("width")[:-2]), float(root.get("height")[:-2])])
    for circle in root.iterfind(".//svg:circle", NS):
        r = float(circle.get("r"))
        assert (_centre(circle) - r >= 0).all() and (_centre(circle) + r <= page).all()
    if size:
        w, h = layout.width_mm, layout.height_mm
        assert f"napkin {w:g} x {h:g} mm" in out.read_text()


def test_the_preview_shows_the_same_drawing(tmp_path):
    layout = default_layout()
    out, root, circles = _kit(tmp_path)
    image = cv2.imread(str(out.with_suffix(".png")))
    page = np.array([float(root.get("width")[:-2]), float(root.get("height")[:-2])])
    scale = image.shape[1] / page[0]
    assert abs(image.shape[0] / scale - page[1]) < 1
    for k in (0, 7, 12):
        x, y = np.round(_centre(circles[f"front-{k}-dot"]) * scale).astype(int)
        rgb = image[y, x, ::-1]
        assert np.abs(rgb.astype(int) - layout.colours_srgb[layout.sticker_dot[k]]).max() <= 2


def test_the_kit_must_be_named_svg(tmp_path):
    r = CliRunner().invoke(main, ["stickers", str(tmp_path / "kit.pdf")])
    assert r.exit_code == 2
    assert len(r.output.strip().splitlines()) == 1 and "SVG" in r.output
