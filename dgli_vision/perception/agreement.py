"""Do the colour and depth images show the same instant?

A camera whose colour and depth streams are not synchronised (or a recording whose
frames were paired one or two apart) shows a flap being folded at one angle in colour
and at another in depth; every state on either side of a fold's 90 degrees is then a
confident wrong answer. The two images must agree where the colour image leaves no
doubt: a sticker seen edge-on (its disc foreshortened to a sliver, so the detector
rejects it as seen too obliquely) lies on cloth held up steeply, and a flap of SPEC's
states holds its stickers 50 mm or more from its crease, so the depth there must stand
well above the table.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .detections import RejectionKind, StickerDetections
from .napkin import NapkinMasks

__all__ = ["EDGE_ON_MIN_MM", "edge_on_heights", "edge_on_problem"]

#: Least height above the table (mm) of a sticker seen edge-on: a flap turned 60-120
#: degrees holds stickers 50 mm or more from its crease at 43 mm or more; a sliver of a
#: sticker cut by a flap's edge on flat cloth is not edge-on in its depth.
EDGE_ON_MIN_MM = 30.0


def edge_on_heights(detections: StickerDetections, masks: NapkinMasks) -> NDArray[np.float64]:
    """Heights above the table (mm, NaN without a reading) of the blobs the detector
    rejected as seen edge-on (:attr:`.RejectionKind.OBLIQUE`), at their centres; shape
    (n,)."""
    centres = [r.centroid for r in detections.rejected if r.kind is RejectionKind.OBLIQUE]
    if not centres:
        return np.zeros(0)
    return masks.height_at(np.asarray(centres, dtype=np.float64))


def edge_on_problem(heights_mm: NDArray[np.float64]) -> str | None:
    """Why colour and depth disagree, or None: two or more stickers seen edge-on in
    colour whose depth puts them (median) lower than :data:`EDGE_ON_MIN_MM` above the
    table."""
    h = np.asarray(heights_mm, dtype=np.float64)
    h = h[np.isfinite(h)]
    if len(h) < 2 or float(np.median(h)) >= EDGE_ON_MIN_MM:
        return None
    return (
        f"colour and depth disagree: {len(h)} stickers seen edge-on on a flap held up lie "
        f"{float(np.median(h)):.0f} mm above the table in the depth image (a flap holds "
        f"them {EDGE_ON_MIN_MM:.0f} mm up or more); were colour and depth taken at the "
        "same instant?"
    )
