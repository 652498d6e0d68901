"""The episode formats and length units ``dgli label`` reads: names only, with no heavy
import, so that the command line builds its choices from them (:mod:`.episodes` reads
them)."""

from __future__ import annotations

__all__ = ["FORMATS", "UNITS"]

#: The episode formats: an NPZ of positions, CloSE's MATLAB file, a folder of meshes.
FORMATS = ("npz", "mat", "meshes")

#: Length units of the positions -> metres.
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
