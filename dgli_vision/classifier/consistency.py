"""Is this the napkin as SPEC defines it, the right size and the right way round?

Two faults a lab makes every week turn into confident wrong states unless checked:

* **Depth in the wrong units** (or wrong intrinsics) scales every 3D distance. The
  stickers around a corner keep their distances in every state (folding never
  stretches cloth), so :class:`~dgli_vision.perception.scale.NapkinRuler` measures the
  napkin; off by more than :data:`SCALE_TOLERANCE`, no verdict is given.
* **A mirrored layout.** A napkin lying back face up, or a camera that mirrors its image,
  shows the corners running clockwise seen from above. The dGLI is a pseudo-scalar
  (the Gauss linking integral changes sign in a mirror), so a mirrored observation has
  the negated cloth coordinates of the real state. Both readings are ranked against the
  references; where the mirrored one fits as well or better, the answer is "cannot
  tell". A few states are mirror images of each other by their stickers alone (a strip
  folded under and a half fold over show the same stickers the same way), so the
  napkin's footprint on the table decides between such readings.

What a front-up state means when the napkin is back face up: SPEC defines the states
with the front face up, and "over" (towards the camera) would be "under" in the
napkin's own frame. The tool does not guess which of the two faults it sees (a flat
napkin looks the same under both): it says what it saw and how to fix it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..core.camera import Intrinsics
from ..core.layout import NapkinLayout
from ..perception.detect import StickerDetections
from ..perception.footprint import Footprint
from ..perception.scale import NapkinRuler
from .classify import MIN_CONFIDENCE, DistanceTerms, Evidence, reference_terms
from .references import ReferenceSet

__all__ = [
    "CLEAR_MARGIN",
    "FOOTPRINT_EXCESS",
    "FOOTPRINT_SCALE",
    "FOOTPRINT_SHIFT",
    "FOOTPRINT_SLACK",
    "GOOD_FIT",
    "MIRROR_MARGIN",
    "MIRROR_TWINS",
    "MIRROR_TWIN_CONFIDENCE",
    "RIGIDITY_TOLERANCE",
    "SCALE_TOLERANCE",
    "UNITS_TOLERANCE",
    "Doubt",
    "depth_range_hint",
    "depth_scale_hint",
    "doubt_factor",
    "footprint_penalty",
    "footprint_problem",
    "mirror_problem",
    "rigidity_problem",
    "scale_causes",
    "scale_problem",
]

#: Largest relative error of the napkin's measured size that still gives a verdict.
#: Sensor noise and sticker placement give under 1%; an uncorrected lens a few per cent
#: near the border; a wrong depth-units setting 20% and more.
SCALE_TOLERANCE = 0.08
#: Largest relative difference between one corner's sticker distances and the napkin's
#: overall scale that still gives a verdict. Renders give under 2% (wrinkles, a sticker
#: on the crease of a diagonal fold); an uncorrected lens stretches a corner near the
#: image border by 5% and more.
RIGIDITY_TOLERANCE = 0.05
#: Largest distance of a front-up reading that the footprint may pick over a mirrored
#: reading the stickers prefer (a half fold's own references fit it 0.06-0.12 away).
GOOD_FIT = 0.2
#: How much better (distance units) one reading must fit once the footprint is counted.
MIRROR_MARGIN = 0.05
#: How much better (distance units) one reading must fit for the stickers alone to
#: decide: a half fold seen front up fits a strip folded under seen mirrored 0.06 better
#: than its own references (and the other way round); the footprint tells those apart.
CLEAR_MARGIN = 0.1
#: Footprint (fraction of the napkin's area) outside a reference's range that is still
#: agreement: the measurement's error (2% on clean images, 5% in shadow or dim light).
FOOTPRINT_SLACK = 0.05
#: Footprint (fraction of the napkin's area) beyond a verdict's largest that rules it out.
FOOTPRINT_EXCESS = 0.1
#: Footprint disagreement beyond the slack that counts in full (one distance unit).
FOOTPRINT_SCALE = 0.1
#: How far (distance units) the footprint moves the mirror check's margin when it fits
#: one reading's best reference and rules out the other's: twice :data:`CLEAR_MARGIN`,
#: so a footprint that clearly speaks for a reading decides a doubt the stickers leave.
FOOTPRINT_SHIFT = 0.2

#: The states that a napkin lying back face up, seen by a camera that mirrors its image,
#: shows exactly: two mirrors cancel in the corners' order, and a fold over turned over
#: lies under. A corner folded over (02) so shows what a corner folded under (03) does,
#: a strip over (09) what a strip under (10) does, and the other way round; two corners
#: of one edge folded over and crossing (05) turned over read as a strip under too. The
#: stickers are the same on both faces, so nothing in one frame tells these apart.
MIRROR_TWINS: dict[str, tuple[str, ...]] = {
    "02": ("03",), "03": ("02",), "09": ("10",), "10": ("09", "05"),
}
#: The highest confidence a state of :data:`MIRROR_TWINS` is given: answered, but never
#: confidently (0.5 and more), since a napkin back face up under a mirroring camera in
#: its twin state looks the same.
MIRROR_TWIN_CONFIDENCE = 0.45


@dataclass(frozen=True)
class Doubt:
    """A check's say on a verdict.

    Attributes
    ----------
    factor : float
        In [0, 1], on the verdict's confidence: continuous in what the check measures
        (:func:`doubt_factor`), so a tiny change of the input never moves the
        confidence from 1 to 0.
    reason : str or None
        Why the check rules the verdict out ("cannot tell"), or None. Where it is given,
        ``factor`` is at most :data:`~dgli_vision.classifier.classify.MIN_CONFIDENCE`.
    """

    factor: float = 1.0
    reason: str | None = None


def doubt_factor(x: float, ruled_out_below: float, clear_above: float, zero_below: float) -> float:
    """A confidence factor that is continuous in a check's measure ``x`` (larger is
    better): 1 from ``clear_above`` up, falling linearly to
    :data:`~dgli_vision.classifier.classify.MIN_CONFIDENCE` at ``ruled_out_below`` (where
    the check starts to rule the verdict out), and on to 0 at ``zero_below``.

    Parameters
    ----------
    x : float
    ruled_out_below, clear_above, zero_below : float
        ``zero_below < ruled_out_below < clear_above``.
    """
    if not np.isfinite(x):
        return 1.0
    if x >= ruled_out_below:
        t = (x - ruled_out_below) / (clear_above - ruled_out_below)
        return float(MIN_CONFIDENCE + (1.0 - MIN_CONFIDENCE) * min(t, 1.0))
    t = (x - zero_below) / (ruled_out_below - zero_below)
    return float(MIN_CONFIDENCE * max(t, 0.0))


def scale_problem(
    ruler: NapkinRuler | None, layout: NapkinLayout, intrinsics: Intrinsics | None = None,
    *, nominal: bool = False,
) -> str | None:
    """The reason the napkin's measured size rules out a verdict, or None, with what
    would explain it: depth units (a power of ten), the focal length (the value that
    would give the printed size) or another napkin size.

    Parameters
    ----------
    ruler : NapkinRuler or None
        The napkin's measured scale (None: too few stickers to tell, no objection).
    layout : NapkinLayout
        The napkin's true size.
    intrinsics : Intrinsics, optional
        The frame's intrinsics (their focal length is named in the hint).
    nominal : bool, keyword-only
        Whether those are the nominal camera's, not given for this one.
    """
    if ruler is None or abs(ruler.scale - 1.0) <= SCALE_TOLERANCE:
        return None
    w, h = layout.width_mm, layout.height_mm
    if w == h:
        measured, expected = f"{ruler.scale * w:.0f} mm", f"{w:.0f}"
        size = f"{ruler.scale * w:.0f}"
    else:
        measured = f"{ruler.scale * w:.0f} x {ruler.scale * h:.0f} mm"
        expected = f"{w:.0f} x {h:.0f}"
        size = f"{ruler.scale * w:.0f}x{ruler.scale * h:.0f}"
    causes = scale_causes(ruler.scale, intrinsics, nominal=nominal)
    return (
        f"the napkin measures {measured}, expected {expected} (its stickers are "
        f"{ruler.scale:.2f} times as far apart as printed): {causes}; or another napkin "
        f"size (--size {size})?"
    )


#: How near (relative) a scale must be to a power of ten to be read as depth units.
UNITS_TOLERANCE = 0.15

_UNITS = {10.0: "0.1 mm", 100.0: "0.01 mm", 1000.0: "micrometres", 0.1: "cm", 0.01: "dm",
          0.001: "m"}


def scale_causes(
    scale: float, intrinsics: Intrinsics | None = None, *, nominal: bool = False
) -> str:
    """What makes 3D distances ``scale`` times their true size, most likely first:
    depth in other units (near a power of ten: "depth in cm?"), else a focal length that
    is not this camera's (the one that would fit: "about 605 px, not 910"), then the
    depth.

    Parameters
    ----------
    scale : float
        Measured over true size (the depth read over the true depth, or the true focal
        length over the one given).
    intrinsics : Intrinsics, optional
        The intrinsics used (their focal length is named).
    nominal : bool, keyword-only
        Whether the intrinsics are the nominal camera's rather than given.
    """
    tens = 10.0 ** round(float(np.log10(scale)))
    if tens != 1.0 and abs(scale / tens - 1.0) <= UNITS_TOLERANCE:
        unit = _UNITS.get(tens, "other units")
        fix = f"x{1 / tens:g}" if tens < 1 else f"/{tens:g}"
        return (
            f"the depth reads about {tens:g} times the true distance (depth in {unit} "
            f"instead of mm? {fix} gives mm; depth units? a depth scale setting?)"
        )
    depth = (
        f"the depth reads {scale:.2g} times the true distance (depth units? a depth "
        "scale setting?)"
    )
    if intrinsics is None:
        return f"{depth}, or intrinsics that are not this camera's"
    fits = f"the focal length would be about {scale * intrinsics.fx:.0f} px"
    focal = (
        f"{fits}, not the nominal camera's {intrinsics.fx:.0f} (give this camera's "
        "intrinsics: an intrinsics.json beside the images, or --intrinsics)"
        if nominal
        else f"{fits}, not {intrinsics.fx:.0f} as the intrinsics give (another camera's, "
        "or another resolution's?)"
    )
    return f"{focal}, or {depth}"


def depth_range_hint(depth_mm: NDArray[np.uint16]) -> str:
    """What the depth image's own readings say of its units, or ``""``: a camera that
    sees the napkin's stickers is more than 150 mm away, so readings (mm) all below 1000
    with a median below 150 are most likely cm, dm or m, and whole metres keep no detail.

    Parameters
    ----------
    depth_mm : ndarray of uint16, shape (H, W)
    """
    read = depth_mm[::4, ::4]
    read = read[read > 0]
    if read.size == 0:
        return "the depth image has no readings (all 0)"
    median = float(np.median(read))
    lo, hi = int(read.min()), int(read.max())
    if median >= 150 or hi >= 1000:
        return ""
    if hi <= 3:
        return (
            f"the depth image reads only {lo}-{hi}: depth in metres stored as whole "
            "numbers? (that keeps no detail: write it in mm, metres x 1000 as 16-bit)"
        )
    factor = next((f for f in (10, 100, 1000) if 250 <= median * f <= 5000), 10)
    unit = {10: "cm", 100: "dm", 1000: "m"}[factor]
    return (
        f"the depth image reads {lo}-{hi} (median {median:.0f}), a camera "
        f"{median:.0f} mm from the napkin: depth in {unit}? (x{factor} gives "
        f"{median * factor:.0f} mm; depth must be in mm)"
    )


def depth_scale_hint(
    detections: StickerDetections,
    depth_mm: NDArray[np.uint16],
    intrinsics: Intrinsics | None = None,
    *,
    nominal: bool = False,
) -> str:
    """What the depth image (or the intrinsics) may have wrong when too few stickers were
    located: readings no camera that sees the napkin gives (:func:`depth_range_hint`), a
    depth image stuck at its largest value, or blobs of the stickers' colours whose size
    disagrees with their depth by one common factor (depth in other units, or a focal
    length that is not this camera's: :func:`scale_causes`). ``""`` when none is seen.

    Parameters
    ----------
    detections : StickerDetections
        The detector's result, with its rejected blobs.
    depth_mm : ndarray of uint16, shape (H, W)
    intrinsics : Intrinsics, optional
        The frame's intrinsics (their focal length is named).
    nominal : bool, keyword-only
        Whether the intrinsics are the nominal camera's rather than given.
    """
    ranged = depth_range_hint(depth_mm)
    if ranged:
        return ranged
    hints = []
    n_valid = np.count_nonzero(depth_mm > 0)
    if n_valid:
        # the share of the valid readings stuck at the largest value (counted, not copied)
        stuck = float(np.count_nonzero(depth_mm == np.iinfo(np.uint16).max) / n_valid)
        if stuck > 0.5:
            hints.append(
                f"the depth image reads 65535 at {100 * stuck:.0f}% of its pixels (depth "
                "units? a depth scale setting?)"
            )
    # (each rejected blob's area against a disc's, as data: rounded as its message shows it)
    ratios = [round(r.size_ratio, 2) for r in detections.rejected if r.size_ratio is not None]
    if len(ratios) >= 4:
        factor = float(np.median(ratios))
        size = f"{factor:.0f} times" if factor >= 1 else f"1/{1 / max(factor, 1e-6):.0f} of"
        # a blob's side over a sticker's there: the depth read over the true one, or the
        # true focal length over the one given
        causes = scale_causes(float(np.sqrt(max(factor, 1e-12))), intrinsics, nominal=nominal)
        hints.append(
            f"{len(ratios)} blobs of the stickers' colours are {size} the area of a sticker "
            f"at the depth read there: {causes}"
        )
    return "; ".join(hints)


def rigidity_problem(ruler: NapkinRuler | None, *, lens_known: bool) -> str | None:
    """The reason the stickers of some corner do not keep their printed distances (a
    corner stretched or shrunk beyond :data:`RIGIDITY_TOLERANCE` against the napkin's
    overall scale), or None.

    Cloth does not stretch, so a corner whose stickers lie farther apart or closer
    together than printed is seen through something that bends the image: most often an
    uncorrected lens near the image border. Missing and displaced stickers there would
    otherwise turn into folds.

    Parameters
    ----------
    ruler : NapkinRuler or None
    lens_known : bool, keyword-only
        Whether the intrinsics carry the lens's distortion (then the hint differs).
    """
    if ruler is None or ruler.worst_against_scale <= RIGIDITY_TOLERANCE:
        return None
    hint = (
        "are the intrinsics and their distortion coefficients those of this camera?"
        if lens_known
        else "is the lens distortion corrected? give it with --intrinsics"
    )
    return (
        f"the stickers do not fit the napkin's geometry (a corner's stickers lie "
        f"{100 * ruler.worst_against_scale:.0f}% off their printed distances): {hint}"
    )


def footprint_problem(
    footprint: Footprint | None,
    references: ReferenceSet,
    front: NDArray[np.float64],
    napkin_area_mm2: float,
) -> Doubt:
    """Whether the cloth covers too much table for the verdict.

    A shadow or an object can hide cloth from the footprint, but nothing adds cloth to
    it: a napkin that covers more of the table than every reference nearly as near as
    the best allows (by more than :data:`FOOTPRINT_EXCESS`) is not in that state. (A
    napkin lying back face up with two corners tucked under shows the stickers of a
    half fold, on three quarters of its area.) The factor falls from 1 at an excess of
    ``FOOTPRINT_EXCESS - FOOTPRINT_SLACK`` to ``MIN_CONFIDENCE`` at ``FOOTPRINT_EXCESS``
    and to 0 a slack beyond it.

    Parameters
    ----------
    footprint : Footprint or None
    references : ReferenceSet
    front : ndarray, shape (k,)
        Distances of the observation to the references.
    napkin_area_mm2 : float
    """
    if footprint is None:
        return Doubt()
    ranges = references.footprint_ranges()
    near = np.flatnonzero(front <= front.min() + MIRROR_MARGIN)
    lo = footprint.fraction(napkin_area_mm2)[0]
    excess = lo - ranges[near, 1]
    if not np.isfinite(excess).all():
        return Doubt()
    worst = float(excess.min())
    factor = doubt_factor(
        -worst, -FOOTPRINT_EXCESS, -(FOOTPRINT_EXCESS - FOOTPRINT_SLACK),
        -(FOOTPRINT_EXCESS + FOOTPRINT_SLACK),
    )
    if worst <= FOOTPRINT_EXCESS:
        return Doubt(factor)
    k = int(near[np.argmin(front[near])])
    return Doubt(factor, (
        f"the napkin covers {100 * lo:.0f}% of its area, more than "
        f"{_describe(references, k)} can ({100 * ranges[k, 1]:.0f}% at most)"
    ))


def footprint_penalty(
    footprint: Footprint | None, references: ReferenceSet, napkin_area_mm2: float
) -> NDArray[np.float64]:
    """Disagreement in [0, 1] of the measured footprint with each reference's range,
    shape (k,): 0 within :data:`FOOTPRINT_SLACK`, 1 beyond it by
    :data:`FOOTPRINT_SCALE`; 0 where either is unknown."""
    ranges = references.footprint_ranges()
    if footprint is None:
        return np.zeros(len(ranges))
    lo, hi = footprint.fraction(napkin_area_mm2)
    gap = np.maximum(ranges[:, 0] - hi, lo - ranges[:, 1])
    pen = np.clip((gap - FOOTPRINT_SLACK) / FOOTPRINT_SCALE, 0.0, 1.0)
    return np.where(np.isfinite(pen), pen, 0.0)


def _describe(references: ReferenceSet, k: int) -> str:
    r = references.references[k]
    return f"{r.class_id} {r.name}" + (f" ({r.variant})" if r.variant else "")


def mirror_problem(
    coords: NDArray[np.float64],
    references: ReferenceSet,
    evidence: Evidence,
    footprint: Footprint | None,
    napkin_area_mm2: float,
    *,
    front: NDArray[np.float64] | None = None,
    terms: DistanceTerms | None = None,
    mirroring: str = "unknown",
) -> Doubt:
    """Whether the observation may be a mirrored napkin.

    The measure is how much better the front-up reading fits than the mirrored one
    (``better``, distance units), moved by the footprint by up to
    :data:`FOOTPRINT_SHIFT` towards the reading whose best reference it fits while it
    rules out the other's (and, towards the front-up reading, only where that fits well,
    within :data:`GOOD_FIT`). At or above :data:`CLEAR_MARGIN` there is no doubt; below
    :data:`MIRROR_MARGIN` the answer is "cannot tell"; the factor on the confidence is
    continuous in between and below (:func:`doubt_factor`, 0 at ``-MIRROR_MARGIN``).

    Parameters
    ----------
    coords : ndarray, shape (28,)
        Cloth coordinates as measured (NaN where unknown).
    references : ReferenceSet
    evidence : Evidence
        What else was seen (:class:`~dgli_vision.classifier.evidence.Evidence`): a mirror
        changes none of it but ``back``, which it turns round.
    footprint : Footprint or None
        The cloth's measured footprint.
    napkin_area_mm2 : float
    front : ndarray, shape (k,), keyword-only, optional
        The front-up reading's distances to the references, when already computed.
    terms : DistanceTerms, keyword-only, optional
        The front-up reading's :func:`~dgli_vision.classifier.classify.reference_terms`,
        when already computed: the mirrored reading is derived from them.
    mirroring : {"no", "yes", "unknown"}, keyword-only
        The camera's handedness the frame was read with (``"yes"``: already
        un-mirrored): the reason's fix names what may be wrong with it.

    Returns
    -------
    Doubt
        Its reason starts with what was seen; the caller prefixes ``"cannot tell: "``.
    """
    if terms is None:
        terms = reference_terms(coords, references, evidence)
    if front is None:
        front = terms.total()
    mirrored = terms.mirrored().total()  # a mirror turns every corner's stickers round too
    pen = footprint_penalty(footprint, references, napkin_area_mm2)
    i, j = int(np.argmin(front)), int(np.argmin(mirrored))
    # judged on the references nearly as near as the best: a tie picks either
    pen_front = float(pen[front <= front[i] + MIRROR_MARGIN].min())
    pen_mirror = float(pen[mirrored <= mirrored[j] + MIRROR_MARGIN].min())
    # The footprint speaks for a reading when it fits that reading's best reference and
    # clearly not the other's; it only ever moves the doubt towards the front-up reading
    # when that fits well (measured wrong, a shadow's footprint must not).
    fits_well = _unit_clip(float(1.0 + (GOOD_FIT - front[i]) / MIRROR_MARGIN))
    for_front = _fits(pen_front) * _rules_out(pen_mirror) * fits_well
    for_mirror = _fits(pen_mirror) * _rules_out(pen_front)
    better = float(mirrored[j] - front[i])  # > 0: the front-up reading fits better
    measure = better + FOOTPRINT_SHIFT * (for_front - for_mirror)
    factor = doubt_factor(measure, MIRROR_MARGIN, CLEAR_MARGIN, -MIRROR_MARGIN)
    if measure >= MIRROR_MARGIN:
        return Doubt(factor)
    fix = _MIRROR_FIX.get(mirroring, _MIRROR_FIX["unknown"])
    if better >= CLEAR_MARGIN:  # the footprint, not the stickers, speaks for the mirror
        lo = footprint.fraction(napkin_area_mm2)[0] if footprint else np.nan
        return Doubt(factor, (
            f"the stickers fit {_describe(references, i)} front up, but the napkin covers "
            f"{100 * lo:.0f}% of its area, as {_describe(references, j)} seen mirrored "
            f"does: the napkin may lie back face up, or the image be mirrored; {fix}"
        ))
    if measure <= -MIRROR_MARGIN:
        return Doubt(factor, (
            f"the stickers run clockwise seen from above: the napkin lies back face up "
            f"or the image is mirrored (mirrored, it reads as {_describe(references, j)} "
            f"at {mirrored[j]:.3f}); {fix}"
        ))
    return Doubt(factor, (
        f"the stickers fit the napkin front face up ({_describe(references, i)}, "
        f"{front[i]:.3f}) and mirrored ({_describe(references, j)}, {mirrored[j]:.3f}) "
        f"nearly alike: the napkin may lie back face up, or the image be mirrored; {fix}"
    ))


#: The fix a mirrored layout's reason names, by the camera's handedness it was read with.
_MIRROR_FIX = {
    "unknown": "turn the napkin front face up, or switch off the camera's mirroring",
    "no": "turn the napkin front face up, or switch off the camera's mirroring (or "
    "declare it: --mirroring yes)",
    "yes": "turn the napkin front face up, or check that the camera mirrors its image "
    "(it is declared mirrored: --mirroring, or \"mirrored\" in the intrinsics)",
}


def _fits(penalty: float) -> float:
    """1 where the footprint agrees with a reference (penalty 0), 0 from a penalty of
    0.1 up, linear between."""
    return _unit_clip(1.0 - penalty / 0.1)


def _rules_out(penalty: float) -> float:
    """1 where the footprint rules a reference out (penalty 0.5 and more), linear to 0
    at penalty 0."""
    return _unit_clip(2.0 * penalty)


def _unit_clip(x: float) -> float:
    """``x`` clipped to [0, 1] as ``np.clip`` does it (NaN stays NaN), without its
    overhead on one number."""
    return min(max(x, 0.0), 1.0)
