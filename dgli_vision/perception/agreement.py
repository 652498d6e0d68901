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

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from .detections import RejectionKind, StickerDetections
from .napkin import NapkinMasks

__all__ = [
    "EDGE_ON_MIN_MM",
    "MIN_SLIVERS",
    "SLIVER_RATIO",
    "SLIVER_REACH_MM",
    "BareRaised",
    "bare_raised_problem",
    "bare_table_raised",
    "edge_on_heights",
    "edge_on_problem",
]

#: Least height above the table (mm) of a sticker seen edge-on: a flap turned 60-120
#: degrees holds stickers 50 mm or more from its crease at 43 mm or more; a sliver of a
#: sticker cut by a flap's edge on flat cloth is not edge-on in its depth.
EDGE_ON_MIN_MM = 30.0


#: Area ratios (a blob's area over the disc expected at its depth) of a sticker seen as
#: a sliver: rejected as too small, but more than a speck or a corner of a disc peeping
#: past a fold (below 0.3). A flap within about 10 degrees of vertical shows its stickers
#: so (0.34-0.51 on the simulator's folding sequences).
SLIVER_RATIO = (0.3, 0.55)

#: Least number of slivers, within :data:`SLIVER_REACH_MM` of each other, taken as one
#: flap's stickers seen edge-on; two slivers also happen on cloth lying flat (stickers
#: cut by a crease or under another flap's edge, 4-6 mm above the table).
MIN_SLIVERS = 3

#: Most slivers in a frame for them to be a flap's: two flaps' stickers. More is every
#: sticker seen too small, a wrong focal length or scale (the scale check says so).
MAX_SLIVERS = 8

#: Distance (pixels) from an object above the napkin within which a sliver may be a
#: sticker cut by the object (a gripper's fingers), not one seen edge-on.
SLIVER_OBJECT_PX = 24.0

#: How far apart (mm, at their depth) the stickers of one corner's flap can lie: the
#: four stickers of a corner span at most about 150 mm (SPEC's layout).
SLIVER_REACH_MM = 150.0


def edge_on_heights(
    detections: StickerDetections, masks: NapkinMasks, fx: float | None = None
) -> NDArray[np.float64]:
    """Heights above the table (mm, NaN without a reading) of the stickers seen edge-on
    in colour, at their centres; shape (n,).

    These are the blobs the detector rejected as seen too obliquely
    (:attr:`.RejectionKind.OBLIQUE`) and, given the focal length ``fx`` (pixels), the
    largest group of :data:`MIN_SLIVERS` or more slivers (blobs rejected as too small,
    with an area ratio in :data:`SLIVER_RATIO`) within :data:`SLIVER_REACH_MM` of each
    other, no more than :data:`MAX_SLIVERS` in the frame, when every one of them lies
    below :data:`EDGE_ON_MIN_MM` in depth and none beside an object: a flap's stickers
    seen nearly edge-on whose depth has them flat.
    """
    centres = [r.centroid for r in detections.rejected if r.kind is RejectionKind.OBLIQUE]
    heights = (
        masks.height_at(np.asarray(centres, dtype=np.float64)) if centres else np.zeros(0)
    )
    group = _sliver_group(detections.rejected, fx) if fx is not None else []
    if group:
        uv = np.asarray(group, dtype=np.float64)
        h = masks.height_at(uv)
        # one flap's stickers seen nearly edge-on, every one of them lying flat in depth,
        # none beside an object (a gripper's fingers cut stickers small too)
        beside = masks.near(masks.occluder, uv, SLIVER_OBJECT_PX) if masks.occluder.any() else []
        if np.all(np.nan_to_num(h, nan=np.inf) < EDGE_ON_MIN_MM) and not np.any(beside):
            heights = np.concatenate([heights, h])
    return heights


def _sliver_group(rejected: tuple, fx: float) -> list[tuple[float, float]]:
    """The centres of the largest group of slivers within one flap's reach, if it has
    :data:`MIN_SLIVERS` or more."""
    lo, hi = SLIVER_RATIO
    slivers = [
        r for r in rejected
        if r.kind is RejectionKind.TOO_SMALL and lo <= float(r.values["ratio"]) < hi
        and float(r.values.get("z_mm", 0.0)) > 0.0
    ]
    if not MIN_SLIVERS <= len(slivers) <= MAX_SLIVERS:
        return []
    uv = np.asarray([r.centroid for r in slivers], dtype=np.float64)
    reach_px = SLIVER_REACH_MM * fx / np.asarray([r.values["z_mm"] for r in slivers], float)
    near = np.linalg.norm(uv[:, None] - uv[None], axis=2) <= reach_px[:, None]
    best = int(np.argmax(near.sum(axis=1)))
    if int(near[best].sum()) < MIN_SLIVERS:
        return []
    return [tuple(c) for c in uv[near[best]]]


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


#: Least height above the table (mm) of a depth sample taken as cloth held up for
#: :func:`bare_table_raised`: above the folds, wrinkles and sag of cloth lying down (a
#: lying flap's layers stand 2-10 mm) and the depth noise of SPEC's cameras at 1 m.
RAISED_MM = 20.0

#: Largest distance of a sample's colour from the bare table's (per channel, in units of
#: the table's own spread, 1.4826 median absolute deviations) that is still the table.
TABLE_SPREAD = 4.0

#: And in 8-bit levels on top of that spread: sensor noise and JPEG.
TABLE_LEVELS = 10.0

#: Least size (samples of the napkin's grid, in one connected patch) and share of the
#: raised samples at and above which depth's raised cloth over colour's bare table says
#: the two images are of different instants. A synchronised frame shows its raised flap
#: as cloth: on the simulator's folding sequences (270 in-step frames) and 117 pairs
#: under 10 capture conditions, the largest such patch had 3 samples, at a flap's steep
#: sides; a depth image one to three frames behind shows 7-560, and 30-100% of what it
#: holds up.
BARE_MIN_SAMPLES = 6
BARE_SHARE_OF_RAISED = 0.3


@dataclass(frozen=True)
class BareRaised:
    """Cloth held up in the depth image over what the colour image shows as bare table.

    Attributes
    ----------
    raised : int
        Samples of the napkin's grid standing more than :data:`RAISED_MM` above the table.
    bare : int
        Those of them whose colour is the bare table's (not napkin, not an object), in
        the largest connected patch.
    cloth : int
        Samples of napkin-coloured cloth (how much of the napkin is seen).
    """

    raised: int
    bare: int
    cloth: int

    @property
    def apart(self) -> bool:
        """Whether depth shows cloth where colour shows the table, beyond what a
        synchronised frame's flap sides do."""
        return self.bare >= BARE_MIN_SAMPLES and self.bare >= BARE_SHARE_OF_RAISED * self.raised


def bare_table_raised(color: NDArray[np.uint8], masks: NapkinMasks) -> BareRaised | None:
    """Cloth standing up in depth where the colour image shows the bare table.

    A flap moves between two instants; when the depth image is older than the colour
    image, it still holds the flap where the colour image already shows the table it
    has left. The table's colour is learnt from the samples lying at the table plane
    away from the napkin (its median and spread per channel).

    Parameters
    ----------
    color : ndarray of uint8, shape (H, W, 3)
        The colour image.
    masks : NapkinMasks
        The napkin stage's masks and heights on their sampling grid.

    Returns
    -------
    BareRaised or None
        None without heights or a napkin mask, or with too little bare table to learn
        its colour from (fewer than 50 samples). With fewer than
        :data:`BARE_MIN_SAMPLES` raised samples of no napkin colour at all, ``bare`` is
        0 and the table's colour is not read.
    """
    if masks.height_mm is None or masks.cloth is None:
        return None
    height = np.nan_to_num(masks.height_mm, nan=-np.inf)
    cloth = masks.cloth
    raised = height > RAISED_MM
    candidates = raised & ~cloth & ~masks.occluder
    if int(candidates.sum()) < BARE_MIN_SAMPLES:  # (too few to count: the table not read)
        return BareRaised(raised=int(raised.sum()), bare=0, cloth=int(cloth.sum()))
    s = masks.stride
    hh, ww = cloth.shape
    rows = np.minimum(np.arange(hh) * s, color.shape[0] - 1)
    cols = np.minimum(np.arange(ww) * s, color.shape[1] - 1)
    rgb = color[rows[:, None], cols[None, :]].astype(np.float32)
    kernel = np.ones((5, 5), np.uint8)
    near_cloth = cv2.dilate(cloth.astype(np.uint8), kernel).astype(bool)
    table = (np.abs(height) < 4.0) & ~near_cloth & ~masks.occluder & ~masks.highlight
    if int(table.sum()) < 50:
        return None
    centre = np.median(rgb[table], axis=0)
    spread = 1.4826 * np.median(np.abs(rgb[table] - centre), axis=0)
    like = (np.abs(rgb - centre) <= TABLE_SPREAD * spread + TABLE_LEVELS).all(axis=2)
    bare = (candidates & like).astype(np.uint8)
    n, _, stats, _ = cv2.connectedComponentsWithStats(bare, connectivity=8)
    largest = int(stats[1:, cv2.CC_STAT_AREA].max()) if n > 1 else 0
    return BareRaised(raised=int(raised.sum()), bare=largest, cloth=int(cloth.sum()))


def bare_raised_problem(seen: BareRaised | None) -> str | None:
    """Why colour and depth are of different instants, or None: cloth held up in depth
    over bare table in colour (:meth:`BareRaised.apart`)."""
    if seen is None or not seen.apart:
        return None
    return (
        f"colour and depth disagree: the depth image holds cloth up over {seen.bare} "
        f"samples where the colour image shows bare table ({seen.bare}/{seen.raised} of "
        "the cloth held up); were colour and depth taken at the same instant?"
    )
