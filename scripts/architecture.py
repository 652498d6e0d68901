"""Draw the package's folders and the imports between them as docs/architecture.svg.

Usage: python scripts/architecture.py [OUT.svg]

Each box is a folder of ``dgli_vision`` (or a top-level module), with its modules and
lines; each arrow says "imports from", drawn from the importer down to what it uses.
Boxes stand on floors: a folder stands one floor above the highest folder it imports
from, so the arrows all point down when the layering holds. Reads the source with
``ast`` (nothing is imported), so it runs without the package's dependencies.
"""

from __future__ import annotations

import ast
import sys
from collections import defaultdict
from pathlib import Path
from xml.sax.saxutils import escape

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / "dgli_vision"
BOX_W, BOX_H, GAP_X, GAP_Y, MARGIN = 250, 92, 40, 70, 30


def room_of(path: Path) -> str:
    """The folder (or top-level module) a source file belongs to."""
    rel = path.relative_to(PKG)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def imported_rooms(path: Path) -> set[str]:
    """Rooms of ``dgli_vision`` that a file imports from."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = path.relative_to(ROOT).with_suffix("").parts[:-1]
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = list(package[: len(package) - node.level + 1])
                parts = base + (node.module.split(".") if node.module else [])
                if len(parts) == 1:  # "from .. import x": the names are the modules
                    parts = [*parts, node.names[0].name]
            else:
                parts = (node.module or "").split(".")
        elif isinstance(node, ast.Import):
            parts = node.names[0].name.split(".")
        else:
            continue
        if len(parts) >= 2 and parts[0] == "dgli_vision":
            out.add(parts[1])
    return out


def read_package() -> tuple[dict[str, list[Path]], dict[str, set[str]]]:
    """Files per room and the rooms each room imports from (itself excluded)."""
    files: dict[str, list[Path]] = defaultdict(list)
    deps: dict[str, set[str]] = defaultdict(set)
    for path in sorted(PKG.rglob("*.py")):
        room = room_of(path)
        if room in {"__init__", "__main__"}:
            continue
        files[room].append(path)
        deps[room] |= {r for r in imported_rooms(path) if r != room}
    for room in deps:
        deps[room] &= set(files)
    return dict(files), dict(deps)


def floors(deps: dict[str, set[str]], rooms: list[str]) -> dict[str, int]:
    """Floor of each room: one above the highest room it imports from (0 for none)."""
    floor: dict[str, int] = {}

    def visit(room: str, path: tuple[str, ...]) -> int:
        if room in floor:
            return floor[room]
        if room in path:  # an import circle: drawn, not resolved
            return 0
        below = [visit(d, (*path, room)) for d in deps.get(room, ())]
        floor[room] = 1 + max(below) if below else 0
        return floor[room]

    for room in rooms:
        visit(room, ())
    return floor


def draw(files: dict[str, list[Path]], deps: dict[str, set[str]]) -> str:
    """The SVG text of the drawing."""
    rooms = sorted(files)
    floor = floors(deps, rooms)
    by_floor: dict[int, list[str]] = defaultdict(list)
    for room in rooms:
        by_floor[floor[room]].append(room)
    top = max(by_floor)
    widest = max(len(v) for v in by_floor.values())
    width = 2 * MARGIN + widest * BOX_W + (widest - 1) * GAP_X
    height = 2 * MARGIN + (top + 1) * BOX_H + top * GAP_Y + 30
    pos = {}
    for f, row in by_floor.items():
        row_w = len(row) * BOX_W + (len(row) - 1) * GAP_X
        x0 = (width - row_w) / 2
        y = MARGIN + 30 + (top - f) * (BOX_H + GAP_Y)
        for i, room in enumerate(row):
            pos[room] = (x0 + i * (BOX_W + GAP_X), y)
    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
        f'font-family="sans-serif" font-size="12">',
        '<defs><marker id="a" viewBox="0 0 10 10" refX="10" refY="5" markerWidth="7" '
        'markerHeight="7" orient="auto"><path d="M0,0 L10,5 L0,10 z" fill="#555"/>'
        "</marker></defs>",
        f'<rect width="{width}" height="{height}" fill="white"/>',
        f'<text x="{MARGIN}" y="{MARGIN}" font-size="15" font-weight="bold">dgli_vision: '
        "folders and what they import (arrows point to what is used)</text>",
    ]
    for room in rooms:
        x, y = pos[room]
        for dep in sorted(deps.get(room, ())):
            dx, dy = pos[dep]
            up = dy < y  # an arrow that climbs: drawn red
            colour = "#c0392b" if up else "#555"
            out.append(
                f'<line x1="{x + BOX_W / 2:.0f}" y1="{y + BOX_H:.0f}" '
                f'x2="{dx + BOX_W / 2:.0f}" y2="{dy:.0f}" stroke="{colour}" '
                f'stroke-opacity="0.55" marker-end="url(#a)"/>'
            )
    for room in rooms:
        x, y = pos[room]
        paths = files[room]
        lines = sum(len(p.read_text(encoding="utf-8").splitlines()) for p in paths)
        is_dir = (PKG / room).is_dir()
        names = [p.stem for p in paths if p.stem != "__init__"]
        label = f"{room}/" if is_dir else f"{room}.py"
        detail = f"{len(names)} modules, {lines} lines" if is_dir else f"{lines} lines"
        fill = "#eaf2fb" if is_dir else "#f4f4f4"
        out.append(
            f'<rect x="{x:.0f}" y="{y:.0f}" width="{BOX_W}" height="{BOX_H}" rx="8" '
            f'fill="{fill}" stroke="#34495e"/>'
        )
        out.append(
            f'<text x="{x + 10:.0f}" y="{y + 20:.0f}" font-size="14" font-weight="bold">'
            f"{escape(label)}</text>"
        )
        out.append(f'<text x="{x + 10:.0f}" y="{y + 38:.0f}" fill="#555">{detail}</text>')
        text, row = "", 0
        for name in names:
            piece = (", " if text else "") + name
            if len(text) + len(piece) > 38:
                out.append(
                    f'<text x="{x + 10:.0f}" y="{y + 56 + 14 * row:.0f}" font-size="10" '
                    f'fill="#333">{escape(text)},</text>'
                )
                text, row = name, row + 1
                if row >= 3:
                    text = "..."
                    break
            else:
                text += piece
        if text:
            out.append(
                f'<text x="{x + 10:.0f}" y="{y + 56 + 14 * row:.0f}" font-size="10" '
                f'fill="#333">{escape(text)}</text>'
            )
    out.append("</svg>")
    return "\n".join(out) + "\n"


def main(argv: list[str]) -> int:
    out = Path(argv[1]) if len(argv) > 1 else ROOT / "docs" / "architecture.svg"
    files, deps = read_package()
    out.write_text(draw(files, deps), encoding="utf-8")
    print(f"wrote {out}: {len(files)} folders and modules")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
