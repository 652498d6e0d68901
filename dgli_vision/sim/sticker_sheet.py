"""The printable sticker kit: the 32 stickers (16 for each face) and a placement template
for each corner, as a drawing in real millimetres.

The drawing is a list of plain shapes in page millimetres (y down), written out as SVG
(which prints at 1:1) or rasterised with OpenCV for a preview, so that both show the same
thing. Nothing here touches the disk.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import pairwise

import numpy as np
from numpy.typing import NDArray

from ..core.errors import InvalidValueError
from ..core.layout import NapkinLayout

__all__ = [
    "PAPERS",
    "Circle",
    "Line",
    "Sheet",
    "Text",
    "napkin_drawing",
    "sheet_image",
    "sheet_svg",
    "sticker_pages",
    "sticker_sheet",
]

#: A3 portrait, mm: the 32 stickers and four templates fit at 1:1.
PAGE_MM = (297.0, 420.0)
#: The papers the kit prints on (portrait, mm): on A3 one page; on A4 or Letter, where
#: the sticker rows (about 270 mm) do not fit, a page per corner.
PAPERS: dict[str, tuple[float, float]] = {
    "A3": PAGE_MM,
    "A4": (210.0, 297.0),
    "Letter": (215.9, 279.4),
}
#: Side of a corner's placement template, mm (the farthest sticker is 100 mm out).
TEMPLATE_MM = 118.0
#: Diameter of a template's cut-out mark at a sticker centre, mm.
MARK_MM = 3.0

BLACK = (0, 0, 0)
GREY = (150, 150, 150)
WHITE = (255, 255, 255)


@dataclass(frozen=True)
class Circle:
    """A filled and/or outlined circle; ``id`` names it in the SVG."""

    x: float
    y: float
    r: float
    fill: tuple[int, int, int] | None = None
    stroke: tuple[int, int, int] | None = None
    width: float = 0.2
    id: str = ""


@dataclass(frozen=True)
class Line:
    """A straight line (``dash`` > 0: dashed)."""

    x0: float
    y0: float
    x1: float
    y1: float
    colour: tuple[int, int, int] = BLACK
    width: float = 0.3
    dash: float = 0.0


@dataclass(frozen=True)
class Text:
    """A line of text, ``size`` its height in mm, anchored at its start (or middle)."""

    x: float
    y: float
    text: str
    size: float = 3.5
    colour: tuple[int, int, int] = BLACK
    middle: bool = False


@dataclass
class Sheet:
    """A drawing on a page of ``width_mm`` x ``height_mm`` (y down)."""

    width_mm: float
    height_mm: float
    shapes: list[Circle | Line | Text] = field(default_factory=list)

    def rect(self, x: float, y: float, w: float, h: float, **kw) -> None:
        """Add the outline of a rectangle."""
        corners = [(x, y), (x + w, y), (x + w, y + h), (x, y + h), (x, y)]
        for (a, b), (c, d) in pairwise(corners):
            self.shapes.append(Line(a, b, c, d, **kw))


def _sticker(
    sheet: Sheet,
    layout: NapkinLayout,
    k: int,
    x: float,
    y: float,
    tag: str,
    *,
    id_size: float = 3.0,
) -> None:
    """Sticker ``k`` centred at (x, y): disc, dot, and its id below."""
    disc, dot = layout.sticker_disc[k], layout.sticker_dot[k]
    sheet.shapes.append(
        Circle(x, y, layout.disc_diameter_mm / 2, fill=layout.colours_srgb[disc], id=f"{tag}-disc")
    )
    sheet.shapes.append(
        Circle(x, y, layout.dot_diameter_mm / 2, fill=layout.colours_srgb[dot], id=f"{tag}-dot")
    )
    sheet.shapes.append(
        Text(x, y + layout.disc_diameter_mm / 2 + 0.4 + id_size, f"{k}", id_size, middle=True)
    )


def _corner_stickers(layout: NapkinLayout, corner: str) -> list[int]:
    """Ids of the four stickers around a corner (its two segments' ends)."""
    return [k for k in range(layout.n_stickers) if layout.segment_corners[k // 2] == corner]


def _template(sheet: Sheet, layout: NapkinLayout, corner: str, x0: float, y0: float) -> None:
    """The placement template of one corner in the square at (x0, y0): the napkin seen
    front up, its corner at the square's matching corner, a cut-out mark at each sticker
    centre with its distances from the two edges."""
    s = TEMPLATE_MM
    k = layout.corner_names.index(corner)
    cu, cv = layout.corner_uv[k]
    right = cu > layout.width_mm / 2  # the corner is on the napkin's right side
    top = cv > layout.height_mm / 2
    px = x0 + (s if right else 0.0)  # the corner on the page (v up on the napkin)
    py = y0 + (0.0 if top else s)
    sheet.rect(x0, y0, s, s, colour=GREY, width=0.2, dash=2.0)
    # the napkin's two edges through the corner, thick: lay them on the cloth's edges
    sheet.shapes.append(Line(px, py, px + (-s if right else s), py, width=0.8))
    sheet.shapes.append(Line(px, py, px, py + (s if top else -s), width=0.8))
    sheet.shapes.append(Circle(px, py, 0.4, fill=BLACK, id=f"template-{corner}-corner"))
    colour = layout.sticker_disc[_corner_stickers(layout, corner)[0]]
    sheet.shapes.append(Text(x0 + s / 2, y0 + s / 2 - 2, f"corner {corner}", 5.0, middle=True))
    sheet.shapes.append(
        Text(x0 + s / 2, y0 + s / 2 + 4, f"({colour} discs), front up", 3.0, middle=True)
    )
    for sid in _corner_stickers(layout, corner):
        du, dv = layout.sticker_uv[sid] - layout.corner_uv[k]
        mx, my = px + du, py - dv
        sheet.shapes.append(Circle(mx, my, layout.disc_diameter_mm / 2, stroke=GREY, width=0.2))
        sheet.shapes.append(
            Circle(
                mx, my, MARK_MM / 2, stroke=BLACK, width=0.25, id=f"template-{corner}-mark-{sid}"
            )
        )
        sheet.shapes.append(Line(mx - 4, my, mx + 4, my, width=0.15))
        sheet.shapes.append(Line(mx, my - 4, mx, my + 4, width=0.15))
        sheet.shapes.append(
            Text(
                mx + 2.5,
                my - 2.5 if not top else my + 5.0,
                f"{sid}: {abs(du):g}, {abs(dv):g}",
                2.6,
            )
        )


def sticker_sheet(layout: NapkinLayout) -> Sheet:
    """The printable kit for a napkin: every sticker twice (front and back faces) and a
    placement template per corner, with a 100 mm bar to check the print scale.

    Parameters
    ----------
    layout : NapkinLayout
        Its size only changes the caption: the stickers keep their distances from the
        corners at any napkin size.

    Returns
    -------
    Sheet
        On an A3 portrait page (297 x 420 mm). Element ids: ``front-<k>-disc``,
        ``front-<k>-dot`` (and ``back-``) for sticker ``k``; ``template-<C>-corner`` and
        ``template-<C>-mark-<k>`` for corner ``C``'s template.
    """
    sheet = Sheet(*PAGE_MM)
    add = sheet.shapes.append
    add(
        Text(
            10,
            12,
            f"dgli_vision sticker kit: napkin {layout.width_mm:g} x {layout.height_mm:g} mm",
            5.0,
        )
    )
    add(
        Text(
            10,
            18,
            "Print at 100 % (actual size) on A3; the bar on the right must measure "
            "100 mm. Cut out the discs; stick each one on the front and its twin on "
            "the back, exactly behind it.",
            2.6,
        )
    )
    add(
        Text(
            10,
            22.5,
            "Templates: lay the thick lines on the napkin's edges at that corner, front up, and "
            "mark each centre through its small circle (id: mm from the vertical edge, mm "
            "from the horizontal edge).",
            2.6,
        )
    )
    d = layout.disc_diameter_mm
    cell_w, cell_h, label_w, gap = d + 2, d + 5, 12.0, 4.0
    x_start, y_start = 10.0, 30.0
    add(Text(x_start + label_w + 2 * cell_w, y_start - 3, "front", 3.5, middle=True))
    add(Text(x_start + label_w + 6 * cell_w + gap, y_start - 3, "back", 3.5, middle=True))
    for r, corner in enumerate(layout.corner_names):
        y = y_start + r * cell_h + d / 2
        add(Text(x_start, y + 1.5, corner, 6.0))
        for c, sid in enumerate(_corner_stickers(layout, corner)):
            for face, shift in (("front", 0.0), ("back", 4 * cell_w + gap)):
                x = x_start + label_w + shift + c * cell_w + cell_w / 2
                _sticker(sheet, layout, sid, x, y, f"{face}-{sid}")
    y_templates = y_start + 4 * cell_h + 4.0
    positions = {"D": (0, 0), "C": (1, 0), "A": (0, 1), "B": (1, 1)}  # as on the napkin
    for corner in layout.corner_names:
        i, j = positions.get(corner, (0, 0))
        _template(
            sheet, layout, corner, 10 + i * (TEMPLATE_MM + 4), y_templates + j * (TEMPLATE_MM + 4)
        )
    # the scale bar: 100 mm, vertical, right of the templates
    _scale_bar(sheet, 10 + 2 * TEMPLATE_MM + 4 + 14, y_templates + 20)
    return sheet


def _scale_bar(sheet: Sheet, bx: float, by: float) -> None:
    """A vertical 100 mm bar from (bx, by), to check the print scale."""
    add = sheet.shapes.append
    add(Line(bx, by, bx, by + 100, width=0.6))
    for t in (by, by + 100):
        add(Line(bx - 3, t, bx + 3, t, width=0.6))
    add(Text(bx + 4, by + 52, "100 mm", 3.5))


def corner_page(layout: NapkinLayout, corner: str, paper: str) -> Sheet:
    """One corner's page of the kit on a small paper (A4, Letter): its four stickers,
    front and back, its placement template and a 100 mm scale bar.

    Element ids as in :func:`sticker_sheet`, for this corner's stickers and template.
    """
    sheet = Sheet(*PAPERS[paper])
    add = sheet.shapes.append
    n = layout.corner_names.index(corner) + 1
    add(Text(10, 14, f"dgli_vision sticker kit, corner {corner} (page {n} of "
                     f"{len(layout.corner_names)}): napkin {layout.width_mm:g} x "
                     f"{layout.height_mm:g} mm", 4.2))
    for k, line in enumerate((
        f"Print at 100 % (actual size, no 'fit to page') on {paper}; the bar must measure "
        "100 mm.",
        "Cut out the discs along the dashed lines; stick each on the front and its twin on "
        "the back, exactly behind it.",
        "Template: lay the thick lines on the napkin's edges at this corner, front up, and "
        "mark each centre",
        "through its small circle (id: mm from the vertical edge, mm from the horizontal "
        "edge).",
    )):
        add(Text(10, 20 + 4 * k, line, 2.6))
    d = layout.disc_diameter_mm
    cell_w, cell_h, label_w = d + 2, d + 5, 16.0
    y_start = 42.0
    for r, face in enumerate(("front", "back")):
        y = y_start + r * cell_h + d / 2
        add(Text(10, y + 1.5, face, 4.0))
        for c, sid in enumerate(_corner_stickers(layout, corner)):
            x = 10 + label_w + c * cell_w + cell_w / 2
            sheet.rect(x - cell_w / 2, y - d / 2 - 1, cell_w, cell_h, colour=GREY, width=0.15,
                       dash=1.5)
            _sticker(sheet, layout, sid, x, y, f"{face}-{sid}")
    y_template = y_start + 2 * cell_h + 6.0
    _template(sheet, layout, corner, 10, y_template)
    _scale_bar(sheet, 10 + TEMPLATE_MM + 14, y_template + 10)
    return sheet


def sticker_pages(layout: NapkinLayout, paper: str = "A3") -> list[tuple[str, Sheet]]:
    """The kit's pages on ``paper`` (:data:`PAPERS`), each with its name: on A3 the one
    sheet of :func:`sticker_sheet` (name ``""``), otherwise a page per corner (named by
    the corner)."""
    if paper not in PAPERS:
        raise InvalidValueError(f"unknown paper {paper!r}; expected one of {', '.join(PAPERS)}")
    if paper == "A3":
        return [("", sticker_sheet(layout))]
    return [(c, corner_page(layout, c, paper)) for c in layout.corner_names]


def napkin_drawing(layout: NapkinLayout, *, margin_mm: float = 30.0) -> Sheet:
    """The whole napkin front up, to scale, with its stickers, ids, corners and the
    segments they mark (for the documentation)."""
    w, h = layout.width_mm, layout.height_mm
    sheet = Sheet(w + 2 * margin_mm, h + 2 * margin_mm)
    add = sheet.shapes.append

    def page(uv: NDArray) -> tuple[float, float]:
        return float(uv[0] + margin_mm), float(h - uv[1] + margin_mm)

    sheet.rect(margin_mm, margin_mm, w, h, colour=GREY, width=1.0)
    for name, uv in zip(layout.corner_names, layout.corner_uv):
        x, y = page(uv)
        add(Text(x + (-14 if uv[0] < w / 2 else 6), y + (14 if uv[1] < h / 2 else -6), name, 14))
    for i, seg in enumerate(layout.segments_uv):
        (x0, y0), (x1, y1) = page(seg[0]), page(seg[1])
        add(Line(x0, y0, x1, y1, width=2.0, colour=GREY))
        mx, my = (x0 + x1) / 2, (y0 + y1) / 2
        inward = np.array(page(np.array([w / 2, h / 2]))) - (mx, my)
        inward = inward / np.linalg.norm(inward) * 40
        add(
            Text(
                mx + inward[0], my + inward[1] + 4, f"s{i}", 10, colour=(120, 0, 120), middle=True
            )
        )
    for k, uv in enumerate(layout.sticker_uv):
        x, y = page(uv)
        _sticker(sheet, layout, k, x, y, f"napkin-{k}", id_size=11.0)
    return sheet


def _hex(rgb: tuple[int, int, int]) -> str:
    return "#{:02x}{:02x}{:02x}".format(*rgb)


def _escape(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def sheet_svg(sheet: Sheet) -> str:
    """The drawing as an SVG document whose user unit is the millimetre (width and
    height given in mm), so that it prints at 1:1."""
    out = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{sheet.width_mm:g}mm" '
        f'height="{sheet.height_mm:g}mm" viewBox="0 0 {sheet.width_mm:g} {sheet.height_mm:g}">',
        f'<rect width="{sheet.width_mm:g}" height="{sheet.height_mm:g}" fill="#ffffff"/>',
    ]
    for s in sheet.shapes:
        if isinstance(s, Circle):
            attrs = f' id="{s.id}"' if s.id else ""
            fill = _hex(s.fill) if s.fill else "none"
            stroke = f' stroke="{_hex(s.stroke)}" stroke-width="{s.width:g}"' if s.stroke else ""
            out.append(
                f'<circle{attrs} cx="{s.x:.3f}" cy="{s.y:.3f}" r="{s.r:.3f}" '
                f'fill="{fill}"{stroke}/>'
            )
        elif isinstance(s, Line):
            dash = f' stroke-dasharray="{s.dash:g}"' if s.dash else ""
            out.append(
                f'<line x1="{s.x0:.3f}" y1="{s.y0:.3f}" x2="{s.x1:.3f}" y2="{s.y1:.3f}" '
                f'stroke="{_hex(s.colour)}" stroke-width="{s.width:g}"{dash}/>'
            )
        else:
            anchor = ' text-anchor="middle"' if s.middle else ""
            out.append(
                f'<text x="{s.x:.3f}" y="{s.y:.3f}" font-family="sans-serif" '
                f'font-size="{s.size:g}" fill="{_hex(s.colour)}"{anchor}>{_escape(s.text)}</text>'
            )
    out.append("</svg>")
    return "\n".join(out) + "\n"


def _dashes(line: Line) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """The drawn pieces of a line: the whole line, or its dashes (``dash`` mm on, ``dash``
    mm off, as SVG's ``stroke-dasharray``)."""
    a, b = np.array([line.x0, line.y0]), np.array([line.x1, line.y1])
    length = float(np.linalg.norm(b - a))
    if not line.dash or length == 0:
        return [((line.x0, line.y0), (line.x1, line.y1))]
    unit = (b - a) / length
    pieces = []
    for start in np.arange(0.0, length, 2 * line.dash):
        p, q = a + unit * start, a + unit * min(start + line.dash, length)
        pieces.append(((float(p[0]), float(p[1])), (float(q[0]), float(q[1]))))
    return pieces


def sheet_image(sheet: Sheet, *, px_per_mm: float = 3.0) -> NDArray[np.uint8]:
    """The drawing rasterised (BGR uint8) for a preview: the same shapes as the SVG, dashed
    lines dashed."""
    import cv2

    w, h = round(sheet.width_mm * px_per_mm), round(sheet.height_mm * px_per_mm)
    img = np.full((h, w, 3), 255, np.uint8)
    shift = 4  # sub-pixel precision of OpenCV's drawing calls

    def pt(x: float, y: float) -> tuple[int, int]:
        return round(x * px_per_mm * (1 << shift)), round(y * px_per_mm * (1 << shift))

    def bgr(rgb: tuple[int, int, int]) -> tuple[int, int, int]:
        return rgb[2], rgb[1], rgb[0]

    for s in sheet.shapes:
        if isinstance(s, Circle):
            r = round(s.r * px_per_mm * (1 << shift))
            if s.fill:
                cv2.circle(img, pt(s.x, s.y), r, bgr(s.fill), -1, cv2.LINE_AA, shift)
            if s.stroke:
                t = max(1, round(s.width * px_per_mm))
                cv2.circle(img, pt(s.x, s.y), r, bgr(s.stroke), t, cv2.LINE_AA, shift)
        elif isinstance(s, Line):
            t = max(1, round(s.width * px_per_mm))
            for (xa, ya), (xb, yb) in _dashes(s):
                cv2.line(img, pt(xa, ya), pt(xb, yb), bgr(s.colour), t, cv2.LINE_AA, shift)
        else:
            scale = s.size * px_per_mm / 22.0  # Hershey simplex capitals are ~22 px at 1.0
            thick = max(1, round(scale * 1.5))
            (tw, _), _ = cv2.getTextSize(s.text, cv2.FONT_HERSHEY_SIMPLEX, scale, thick)
            x = s.x * px_per_mm - (tw / 2 if s.middle else 0)
            cv2.putText(
                img,
                s.text,
                (round(x), round(s.y * px_per_mm)),
                cv2.FONT_HERSHEY_SIMPLEX,
                scale,
                bgr(s.colour),
                thick,
                cv2.LINE_AA,
            )
    return img
