"""Calibrated sticker colours on disk (written by ``dgli calibrate``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..core.errors import CalibrationError
from ..core.io import guard_outputs, read_json, record_outputs, write_json

__all__ = [
    "COLOURS_FORMAT",
    "read_colours",
    "write_colours",
]

COLOURS_FORMAT = "dgli-colours"


def write_colours(
    path: str | Path,
    colours: dict[str, tuple[int, int, int]],
    provenance: dict[str, Any],
    *,
    overwrite: bool = False,
) -> None:
    """Write calibrated sticker colours (``dgli calibrate``) as JSON (replacing a file
    only if dgli wrote it, or with ``overwrite``)."""
    guard_outputs([path], overwrite=overwrite)
    write_json(
        path,
        {
            "format": COLOURS_FORMAT,
            "version": 1,
            "space": "sRGB 0-255, image balanced to the napkin's white",
            "colours": {k: list(v) for k, v in colours.items()},
            "provenance": provenance,
        },
    )
    record_outputs([path], str(provenance.get("command", "")))


def read_colours(path: str | Path) -> dict[str, tuple[int, int, int]]:
    """Read a colours file written by ``dgli calibrate``.

    Raises
    ------
    UnreadableInputError, CalibrationError
    """
    from ..core.layout import default_layout

    data = read_json(path, what="colours file")
    names = set(default_layout().colours_srgb)
    if not isinstance(data, dict) or data.get("format") != COLOURS_FORMAT:
        raise CalibrationError(
            f'\'{path}\' is not a dgli colours file (no "format": "{COLOURS_FORMAT}")'
        )
    colours = data.get("colours")
    if not isinstance(colours, dict) or set(colours) != names:
        raise CalibrationError(
            f"'{path}' must give exactly the colours {', '.join(sorted(names))}"
        )
    out = {}
    for name, rgb in colours.items():
        if (
            not isinstance(rgb, list)
            or len(rgb) != 3
            or not all(isinstance(v, int) and 0 <= v <= 255 for v in rgb)
        ):
            raise CalibrationError(f"'{path}': colour {name!r} must be three integers 0-255")
        out[name] = (rgb[0], rgb[1], rgb[2])
    return out
