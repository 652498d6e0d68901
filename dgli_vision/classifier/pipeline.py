"""The classification pipeline: an RGB-D frame -> stickers -> 3D -> dGLI -> a state.

The perception's stages run in :func:`dgli_vision.perception.observe.observe` (each
once, in its order); this module judges what they saw (the coordinates, the nearest
reference, the fault checks, the state's folds) and keeps every intermediate result,
which is what a person debugging a real image needs.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.classes import CLASS_NAMES, LANDING_PAIRS
from ..core.dgli import cloth_coordinates
from ..core.errors import DetectionError
from ..core.handedness import camera_mirroring, unmirrored
from ..core.json_ready import json_ready
from ..core.layout import NapkinLayout, layout_of_size
from ..core.order_stats import median
from ..core.why import WhyKind
from ..perception.agreement import bare_raised_problem, edge_on_problem
from ..perception.detect import (
    DetectorParams,
    StickerDetections,
)
from ..perception.lift import Markers3D
from ..perception.observe import Observation, StageClock
from ..perception.observe import observe as observe_frame
from ..perception.params import PipelineParams
from ..perception.tips import settled_stickers
from ..sources.frames import RGBDFrame
from .affordances import Affordances, affordances_of, deferred_affordances
from .capture_limits import border_factor, sticker_px, sticker_size_problem
from .classify import (
    MIN_CONFIDENCE,
    Evidence,
    Prediction,
    classify_coordinates,
    reference_terms,
)
from .consistency import (
    MIRROR_TWIN_CONFIDENCE,
    MIRROR_TWINS,
    Doubt,
    depth_scale_hint,
    doubt_factor,
    footprint_problem,
    mirror_problem,
    rigidity_problem,
    scale_problem,
)
from .known_states import (
    crumpled_problem,
    diagonal_crease_stretch,
    folded_apart_problem,
    footprint_problem_below,
)
from .references import ReferenceSet
from .state_fit import StateFit, fit_state

__all__ = ["ClothObservation", "FrameResult", "StageClock", "classify_frame", "observe"]


@dataclass(frozen=True, eq=False, kw_only=True)
class ClothObservation(Observation):
    """The cloth as seen (:class:`~dgli_vision.perception.observe.Observation`: every
    perception stage's result), with what the classifier weighs beside the coordinates
    (:meth:`classifier_evidence`)."""

    def classifier_evidence(self) -> Evidence:
        """What the classifier weighs beside the coordinates
        (:class:`~dgli_vision.classifier.evidence.Evidence`)."""
        return Evidence(
            visible=self.visible, unknown=self.unknown, lifted=self.lifted,
            heights_mm=self.matched_heights_mm, past=self.past_vertical,
            back=self.back, spread_mm=self.spread_mm, tips=self.tips,
        )


@dataclass(frozen=True, eq=False, kw_only=True)
class FrameResult:
    """Everything the pipeline computed for one frame.

    ``prediction`` is None when too little was seen or the best match is not clear
    enough; ``reason`` then says why, and ``best_guess`` keeps what the nearest reference
    was (for reports), if any. ``why`` names the kind of reason (:data:`WHY_KINDS`) and
    ``candidates`` the nearest states of the three nearest classes, as (class, variant,
    distance), nearest first (empty when too few stickers were seen to rank any).
    ``affordances`` gives each corner's point, state and whether it can be grasped, and
    the folds seen (:mod:`~dgli_vision.classifier.affordances`). ``distances`` keeps the
    frame's distance to every reference (what
    :func:`~dgli_vision.classifier.classify.reference_distances` gives for its
    evidence) whenever they were ranked: ``best_guess`` is then set. ``doubts`` gives each
    factor that the checks put on the best guess's confidence, as (what it says, factor),
    1.0 where the check is clear (empty when no state was ranked). ``mirroring`` is the
    camera's handedness it was classified with (``"no"``, ``"yes"``, ``"unknown"``:
    :func:`~dgli_vision.core.handedness.camera_mirroring`); ``unmirrored`` is True when the
    frame was flipped left to right first (a camera declared mirrored), so that every
    pixel position in the result is one of the flipped image
    (:func:`~dgli_vision.core.handedness.unmirrored`) and every 3D point the scene's own.
    """

    detections: StickerDetections
    markers: Markers3D
    observation: ClothObservation
    coordinates: NDArray[np.float64]
    prediction: Prediction | None
    reason: str | None = None
    best_guess: Prediction | None = None
    timings_ms: dict[str, float] = field(default_factory=dict)
    why: str | None = None
    candidates: tuple[tuple[str, str | None, float], ...] = ()
    affordances: Affordances | None = None
    distances: NDArray[np.float64] | None = None
    fit: StateFit | None = None
    doubts: tuple[tuple[str, float], ...] = ()
    mirroring: str = "no"
    unmirrored: bool = False

    def frame_as_read(self, frame: RGBDFrame) -> RGBDFrame:
        """``frame`` (the one classified) as the pipeline read it: flipped left to right
        when it was un-mirrored (``unmirrored``), so that the result's pixels are its own
        (for overlays and for placing a plan in the camera)."""
        return unmirrored(frame) if self.unmirrored else frame

    def to_json(self, color: str, depth: str) -> dict[str, Any]:
        """The JSON object of ``dgli classify --json``, naming the pair as ``color`` and
        ``depth`` (docs/json.md)."""
        found = self.observation.visible
        p = self.prediction
        out: dict[str, Any] = {"color": color, "depth": depth}
        if p is None:
            guess = self.best_guess
            out.update(
                {
                    "class": None,
                    "name": None,
                    "variant": None,
                    "distance": None,
                    "runner_up": None,
                    "confidence": None if guess is None else guess.confidence,
                    "reason": self.reason,
                }
            )
        else:
            ru = p.runner_up
            out.update(
                {
                    "class": p.class_id,
                    "name": p.name,
                    "variant": p.variant,
                    "distance": round(p.distance, 6),
                    "confidence": p.confidence,
                    "runner_up": None
                    if ru is None
                    else {
                        "class": ru.class_id,
                        "name": ru.name,
                        "variant": ru.variant,
                        "distance": round(ru.distance, 6),
                    },
                }
            )
        unknown = self.observation.unknown
        evidence = self.observation.evidence
        out["stickers"] = {
            "found": int(found.sum()),
            "missing": np.flatnonzero(~found).tolist(),
            "unknown": {str(i): evidence.reasons[i] for i in np.flatnonzero(unknown)}
            if evidence is not None
            else {},
        }
        out["candidates"] = [
            {"class": c, "variant": v, "distance": d} for c, v, d in self.candidates
        ]
        if p is None:
            out["why"] = {
                "kind": None if self.why is None else str(self.why),
                "classes": [c for c, _, _ in self.candidates[:2]],
                "stickers": out["stickers"],
            }
            if self.why == WhyKind.NO_STATE_FITS and self.fit is not None:
                out["why"]["unexplained"] = _unexplained_json(self.fit)
        if self.affordances is not None:
            out.update(self.affordances.to_json())
        out["coordinates"] = [
            None if not np.isfinite(v) else round(float(v), 8) for v in self.coordinates
        ]
        return json_ready(out)


#: The kinds of "cannot tell" (``FrameResult.why``), as strings in
#: :class:`~dgli_vision.core.why.WhyKind`'s order (kept for programs that import it;
#: compare ``why`` with :class:`~dgli_vision.core.why.WhyKind`'s members).
WHY_KINDS = tuple(k.value for k in WhyKind if k is not WhyKind.DEFERRED)


def _candidates(
    distances: NDArray[np.float64], references: ReferenceSet, k: int = 3
) -> tuple[tuple[str, str | None, float], ...]:
    """The nearest reference of each of the ``k`` nearest classes, nearest first."""
    codes = references.class_codes()
    out: list[tuple[str, str | None, float]] = []
    classes: set[int] = set()
    for i in np.argsort(distances, kind="stable").tolist():  # stops at the k-th class
        if codes[i] in classes:
            continue
        classes.add(codes[i])
        r = references.references[i]
        out.append((r.class_id, r.variant, round(float(distances[i]), 6)))
        if len(out) == k:
            break
    return tuple(out)


def observe(
    frame: RGBDFrame,
    layout: NapkinLayout | None = None,
    params: PipelineParams | DetectorParams | None = None,
    *,
    colours: dict[str, tuple[int, int, int]] | None = None,
    clock: StageClock | None = None,
) -> tuple[StickerDetections, Markers3D, ClothObservation]:
    """:func:`~dgli_vision.perception.observe.observe` (every perception stage once, in
    its order), its observation a :class:`ClothObservation`."""
    return observe_frame(
        frame, layout, params, colours=colours, clock=clock, into=ClothObservation
    )


def classify_frame(
    frame: RGBDFrame,
    references: ReferenceSet,
    *,
    layout: NapkinLayout | None = None,
    params: PipelineParams | DetectorParams | None = None,
    min_confidence: float = MIN_CONFIDENCE,
    colours: dict[str, tuple[int, int, int]] | None = None,
    mirroring: str | None = None,
) -> FrameResult:
    """Classify one RGB-D frame.

    Parameters
    ----------
    frame : RGBDFrame
    references : ReferenceSet
    layout : NapkinLayout, keyword-only, optional
        Default: the packaged layout at the napkin size the references were built for.
    params : PipelineParams or DetectorParams, keyword-only, optional
        Every perception stage's parameters
        (:class:`~dgli_vision.perception.params.PipelineParams`, e.g. from
        :func:`~dgli_vision.perception.params.read_params`); a ``DetectorParams``: the
        defaults with those of the sticker detector. Default: the defaults.
    min_confidence : float, keyword-only
        Below this confidence the answer is "cannot tell" (default
        :data:`~dgli_vision.classifier.classify.MIN_CONFIDENCE`).
    colours : dict, keyword-only, optional
        Calibrated sticker colours (``dgli calibrate``); default: the nominal ones.
    mirroring : {"no", "yes", "unknown"}, keyword-only, optional
        Whether the camera mirrors its image (default: as the frame's intrinsics declare,
        ``"mirrored"``, else ``"no"``: :func:`~dgli_vision.core.handedness.camera_mirroring`).
        ``"yes"`` flips the frame left to right before reading it
        (:func:`~dgli_vision.core.handedness.unmirrored`); ``"unknown"`` never gives 02,
        03, 09 or 10 a confidence above 0.45 (docs/robustness.md).

    Returns
    -------
    FrameResult
        With ``prediction`` None and a ``reason`` when too few stickers were seen or
        the confidence is below ``min_confidence``.
    """
    mode = camera_mirroring(mirroring, frame.intrinsics)
    if mode == "yes":
        frame = unmirrored(frame)
    layout = layout or layout_of_size(references.napkin_mm)
    clock = StageClock()
    detections, markers, obs = observe(frame, layout, params, colours=colours, clock=clock)
    result = _judge(
        frame, references, layout, (detections, markers, obs), min_confidence, clock, mode
    )
    result = _with_affordances(result, layout, frame)
    clock.lap("affordances")
    return replace(
        result, timings_ms=dict(clock.ms), mirroring=mode, unmirrored=mode == "yes"
    )


def _with_affordances(result: FrameResult, layout: NapkinLayout, frame: RGBDFrame) -> FrameResult:
    """The result with its corners and folds, in the verdict and in the prediction:
    worked out when first read (:func:`~.affordances.deferred_affordances`)."""
    p = result.prediction
    obs, intrinsics = result.observation, frame.intrinsics
    class_id, variant = (p.class_id, p.variant) if p is not None else (None, None)
    aff = deferred_affordances(
        lambda: affordances_of(obs, class_id, variant, layout, intrinsics, frame=frame)
    )
    if p is None:
        guess = result.best_guess
        if guess is not None:
            guess = replace(guess, corners=aff.corners)
        return replace(result, best_guess=guess, affordances=aff)
    p = replace(p, corners=aff.corners, folds=aff.folds)
    guess = p if result.best_guess is result.prediction else result.best_guess
    return replace(result, prediction=p, best_guess=guess, affordances=aff)


#: What the border factor (:func:`~.capture_limits.border_factor`) says in ``doubts``.
BORDER_DOUBT_NAME = "stickers near the image border, lens distortion unknown"
#: What the cap of a state with a mirror twin says in ``doubts`` (the camera's handedness
#: unknown: :data:`~.consistency.MIRROR_TWIN_CONFIDENCE`).
TWIN_DOUBT_NAME = "its twin, back face up under a mirroring camera, looks the same"


#: The landing check's measure (:func:`_landing`): how much farther the landing partner
#: of the nearest class lies than that class, as a share of how much farther the nearest
#: class of a third kind lies. Below 1 the partner is the runner-up ("cannot tell"); from
#: :data:`LANDING_CLEAR` up it is far enough behind to leave the confidence alone.
LANDING_CLEAR = 1.5


def _landing(
    obs: ClothObservation, distances: NDArray[np.float64], references: ReferenceSet
) -> Doubt:
    """Whether the nearest two classes cannot be told apart yet: a flap is held up and
    they differ only in where it will land (:data:`LANDING_PAIRS`). The factor on the
    confidence is continuous in how far behind the landing partner lies (see
    :data:`LANDING_CLEAR`); the reason is given where the partner is the runner-up."""
    if obs.flap_deg is None or not np.isfinite(obs.flap_deg).any():
        return Doubt()
    near = _candidates(distances, references, k=4)
    if len(near) < 3:
        return Doubt()
    a, va, da = near[0]
    partner = [c for c in near[1:] if frozenset({a, c[0]}) in LANDING_PAIRS]
    if not partner:
        return Doubt()
    b, vb, db = partner[0]
    third = next(c[2] for c in near[1:] if c[0] != b)
    ratio = (db - da) / max(third - da, 1e-9)
    factor = doubt_factor(ratio, 1.0, LANDING_CLEAR, 0.0)
    if ratio >= 1.0:
        return Doubt(factor)
    lean = float(np.nanmedian(obs.flap_deg))
    return Doubt(factor, (
        f"a flap held up at about {lean:.0f} degrees: {_named(a, va, da)} "
        f"and {_named(b, vb, db)} differ only in where it lands"
    ))


#: The vertical check's band (:func:`_near_vertical`), degrees from vertical of a flap
#: held up: within :data:`VERTICAL_RULED_OUT_DEG` the answer is "cannot tell" (the state
#: changes as the flap passes 90 degrees, and a flap's measured lean is good to a few
#: degrees, colour and depth taken a frame apart move it by more); from
#: :data:`VERTICAL_CLEAR_DEG` on the confidence is left alone, and between the two it
#: rises continuously (confident, 0.5 or more, from about 10 degrees off vertical).
VERTICAL_RULED_OUT_DEG = 5.0
VERTICAL_CLEAR_DEG = 20.0


def _near_vertical(
    obs: ClothObservation, near: tuple[tuple[str, str | None, float], ...]
) -> Doubt:
    """Whether a flap held up stands too near vertical to say which side of 90 degrees
    it is on: the states before and after its fold are then both within the noise of
    its lean. The factor on the confidence is continuous in the lean's distance from
    vertical (see :data:`VERTICAL_RULED_OUT_DEG`); the reason names the two nearest
    classes where it rules the verdict out."""
    if obs.flap_deg is None or not np.isfinite(obs.flap_deg).any():
        return Doubt()
    lean = float(np.nanmedian(obs.flap_deg))
    off = abs(lean - 90.0)
    factor = doubt_factor(off, VERTICAL_RULED_OUT_DEG, VERTICAL_CLEAR_DEG, 0.0)
    if off >= VERTICAL_RULED_OUT_DEG or len(near) < 2:
        return Doubt(factor)
    (a, va, da), (b, vb, db) = near[0], near[1]
    return Doubt(factor, (
        f"a flap held up at about {lean:.0f} degrees, within {VERTICAL_RULED_OUT_DEG:.0f} "
        f"of vertical: {_named(a, va, da)} before or after it passes "
        f"90 degrees, or {_named(b, vb, db)}"
    ))


def _named(class_id: str, variant: str | None, distance: float) -> str:
    """``"04 two-adjacent-corners (AB, 0.016)"``; ``"01 flat (0.040)"`` for a state
    without a variant."""
    told = f"{variant}, {distance:.3f}" if variant else f"{distance:.3f}"
    return f"{class_id} {CLASS_NAMES[class_id]} ({told})"


def _too_small(
    detections: StickerDetections, frame: RGBDFrame, napkin_mm: float, layout: NapkinLayout
) -> str | None:
    """Why the stickers are too small to be read, or None. With three stickers located
    their size is measured in the image (whatever the depth's units), otherwise it
    follows from the depth, unless the depth itself looks wrong (then the depth is
    blamed, in the detection's message)."""
    found = detections.found
    if found.sum() >= 3:
        fore = detections.foreshortening
        fore = fore[found] if fore is not None else 1.0
        across = median(2 * np.sqrt(detections.areas[found] / (np.pi * fore)))
        depth_mm = layout.disc_diameter_mm * frame.intrinsics.fx / max(across, 1e-6)
        return sticker_size_problem(depth_mm, frame.intrinsics, layout.disc_diameter_mm)
    if depth_scale_hint(detections, frame.depth_mm, frame.intrinsics):
        return None
    return sticker_size_problem(napkin_mm, frame.intrinsics, layout.disc_diameter_mm)


def _napkin_depth(detections: StickerDetections, depth_mm: NDArray[np.uint16]) -> float:
    """The napkin's distance from the camera, mm: the median depth of the stickers
    located (at least three), else of the frame's readings (NaN with none)."""
    z = detections.depth_mm[np.isfinite(detections.depth_mm)]
    if len(z) >= 3:
        return median(z)
    read = depth_mm[::8, ::8]
    read = read[read > 0]
    return float(np.median(read)) if read.size else float("nan")


def _unknown_summary(obs: ClothObservation) -> str:
    """What the stickers neither seen nor evidence of a fold are (for a "cannot tell":
    only worked out when one is said)."""
    return obs.evidence.summary() if obs.evidence is not None else ""


def _judge(
    frame: RGBDFrame,
    references: ReferenceSet,
    layout: NapkinLayout,
    seen: tuple[StickerDetections, Markers3D, ClothObservation],
    min_confidence: float,
    clock: StageClock,
    mirroring: str = "unknown",
) -> FrameResult:
    """The verdict on an observed frame: the fault checks, the nearest reference and
    its confidence, whether its state's folds explain what was seen, or "cannot tell"
    and why. With the camera's handedness ``"unknown"``, a state of
    :data:`~.consistency.MIRROR_TWINS` is never confident (its twin, back face up under
    a mirroring camera, looks the same); a camera known not to mirror (``"no"``, or one
    un-mirrored first) leaves it its confidence."""
    detections, markers, obs = seen
    coords = cloth_coordinates(obs.segments, obs.up)
    seen_as = {
        "detections": detections, "markers": markers, "observation": obs, "coordinates": coords,
    }
    napkin_mm = _napkin_depth(detections, frame.depth_mm)
    border = border_factor(
        detections.centroids,
        frame.intrinsics,
        sticker_px(napkin_mm, frame.intrinsics, layout.disc_diameter_mm),
        stretch=None if obs.ruler is None else obs.ruler.worst_against_scale,
    )
    kind, problem = _image_problem(frame, detections, obs, napkin_mm, layout, border)
    stretched = problem if kind == WhyKind.DEFERRED else None
    if problem is not None and stretched is None:
        return FrameResult(
            **seen_as, prediction=None, reason=f"cannot tell: {problem}", why=kind
        )
    evidence = obs.classifier_evidence()
    try:
        terms = reference_terms(coords, references, evidence)
    except DetectionError as exc:
        return _too_few(frame, references, layout, seen_as, exc)
    front = terms.total()
    guess = _guess(coords, references, evidence, front, obs, layout, min_confidence)
    if border < 1.0:  # an uncorrected lens may have moved the stickers near the border
        guess = replace(guess, confidence=round(guess.confidence * border, 4))
    clock.lap("classify")
    checks = _checks(obs, coords, references, evidence, terms, guess, layout, mirroring)
    clock.lap("checks")
    # each check lowers the confidence continuously; where one rules the verdict out the
    # nearest reference stays for reports, with the confidence left to it
    unchecked = guess.confidence
    if checks.factor < 1.0:
        guess = replace(guess, confidence=round(guess.confidence * checks.factor, 4))
    doubts = (*checks.lowering(), (BORDER_DOUBT_NAME, border))
    if (
        mirroring == "unknown" and guess.class_id in MIRROR_TWINS
        and guess.confidence > MIRROR_TWIN_CONFIDENCE
    ):
        twin = (TWIN_DOUBT_NAME, round(MIRROR_TWIN_CONFIDENCE / guess.confidence, 4))
        doubts = (*doubts, twin)
        guess = replace(guess, confidence=MIRROR_TWIN_CONFIDENCE)
    told = {
        "best_guess": guess, "candidates": checks.near, "distances": front, "fit": checks.fit,
        "doubts": doubts,
    }
    why, reason = _ruled_out(obs, references, layout, terms, checks, guess, stretched)
    if reason is None and checks.told is not None and unchecked >= min_confidence:
        why, reason = WhyKind.TOO_CLOSE, f"cannot tell: {checks.told}"
    if reason is None and guess.confidence < min_confidence:
        why = WhyKind.TOO_CLOSE
        reason = _low_confidence_reason(guess, obs, min_confidence, border, checks.lowering())
    if reason is not None:
        return FrameResult(**seen_as, **told, prediction=None, reason=reason, why=why)
    return FrameResult(**seen_as, **told, prediction=guess)


def _too_few(
    frame: RGBDFrame,
    references: ReferenceSet,
    layout: NapkinLayout,
    seen_as: dict[str, Any],
    exc: DetectionError,
) -> FrameResult:
    """The "cannot tell" of a frame with too few stickers to rank the states: too little
    cloth for any state (no state fits), or what was seen and what may be wrong."""
    detections, obs = seen_as["detections"], seen_as["observation"]
    reason = f"{int(obs.visible.sum())} of {len(obs.visible)} stickers located; {exc}"
    below = footprint_problem_below(obs.footprint, references, layout.width_mm * layout.height_mm)
    if below is not None:
        return FrameResult(
            **seen_as, prediction=None, why=WhyKind.NO_STATE_FITS,
            reason=f"cannot tell: no known state fits: {below}; {reason}",
        )
    unknown = _unknown_summary(obs)
    if unknown:
        reason += f" ({unknown})"
    depth_hint = depth_scale_hint(
        detections, frame.depth_mm, frame.intrinsics,
        nominal=frame.intrinsics_source == "default",
    )
    if depth_hint:
        reason += f"; {depth_hint}"
    return FrameResult(**seen_as, prediction=None, reason=reason, why=WhyKind.TOO_FEW)


@dataclass(frozen=True)
class _Checks:
    """What the checks of a verdict say: each a factor on its confidence, and a reason
    where one rules it out (see :func:`_checks`)."""

    near: tuple[tuple[str, str | None, float], ...]
    mirror: Doubt
    foot: Doubt
    landing: Doubt
    vertical: Doubt
    fit: StateFit

    @property
    def factor(self) -> float:
        """The checks' factors together."""
        return (
            self.mirror.factor * self.foot.factor * self.landing.factor
            * self.vertical.factor * self.fit.factor
        )

    @property
    def told(self) -> str | None:
        """Why a flap held up leaves the state not yet told, if it does."""
        return self.landing.reason or self.vertical.reason

    def lowering(self) -> tuple[tuple[str, float], ...]:
        """Each check's factor with what it says, for a low confidence's reason."""
        return (("the mirrored reading nearly as close", self.mirror.factor),
                ("the footprint larger than the state allows", self.foot.factor),
                ("a flap held up, where it lands not yet seen", self.landing.factor),
                ("a flap held up near vertical", self.vertical.factor),
                ("the state's folds explain the stickers only in part", self.fit.factor))


def _checks(
    obs: ClothObservation,
    coords: NDArray[np.float64],
    references: ReferenceSet,
    evidence: Evidence,
    terms: Any,
    guess: Prediction,
    layout: NapkinLayout,
    mirroring: str = "unknown",
) -> _Checks:
    """The checks of the verdict ``guess``: the mirrored reading, the footprint, a flap
    held up (where it lands, near vertical) and the state's own folds."""
    front = terms.total()
    area = layout.width_mm * layout.height_mm
    near = _candidates(front, references)
    mirror = mirror_problem(
        coords, references, evidence, obs.footprint, area, front=front, terms=terms,
        mirroring=mirroring,
    )
    fit = fit_state(obs, guess.class_id, guess.variant, layout)
    # a flap in the air, one the state can be folding, stands over the table the camera
    # sees past it: the footprint measured then says nothing of the state's
    foot = (
        Doubt() if _flap_in_the_air(obs) and fit.factor == 1.0
        else footprint_problem(obs.footprint, references, front, area)
    )
    return _Checks(
        near, mirror, foot, _landing(obs, front, references), _near_vertical(obs, near), fit
    )


def _ruled_out(
    obs: ClothObservation,
    references: ReferenceSet,
    layout: NapkinLayout,
    terms: Any,
    checks: _Checks,
    guess: Prediction,
    stretched: str | None,
) -> tuple[WhyKind | None, str | None]:
    """The kind and reason of a check that rules the verdict out, in their order: the
    state's folds (unless the mirrored reading's state explains what the mirror check
    doubts), a corner stretched as only a diagonal fold's crease stretches one, the
    mirror or footprint; ``(None, None)`` when none does."""
    doubt = checks.mirror.reason or checks.foot.reason
    fit = checks.fit
    if not fit.fits and not (doubt and _mirrored_state_fits(obs, terms, references, layout)):
        return WhyKind.NO_STATE_FITS, f"cannot tell: no known state fits: {fit.describe()}"
    if stretched is not None and guess.class_id != "12":
        # a corner's stickers cut as a diagonal fold's crease cuts them, but the state
        # nearest is no diagonal fold: a lens may bend the napkin
        return WhyKind.GEOMETRY, f"cannot tell: {stretched}"
    if doubt is not None:
        return WhyKind.MIRROR, f"cannot tell: {doubt}"
    return None, None


def _flap_in_the_air(obs: ClothObservation) -> bool:
    """Whether cloth stands in the air: stickers seen above ``LIFTED_MM``, or held up
    out of sight (a fold in progress, when the state fit finds it one flap)."""
    lifted = obs.lifted
    return lifted is not None and bool(np.any(np.nan_to_num(lifted) > 0.5))


def _mirrored_state_fits(
    obs: ClothObservation, terms: Any, references: ReferenceSet, layout: NapkinLayout
) -> bool:
    """Whether the nearest state of the mirrored reading (a napkin back face up, or a
    mirroring camera) explains the stickers: then the mirror check, not "no known state
    fits", says what is wrong."""
    j = int(np.argmin(terms.mirrored().total()))
    r = references.references[j]
    return fit_state(obs, r.class_id, r.variant, layout).fits


def _unexplained_json(fit: StateFit) -> dict[str, Any]:
    """``why.unexplained`` of a "no state fits": the state fitted, each sticker off its
    place (mm), the stickers seen that it hides, its folds that are not its own and
    the stickers in the air on no flap it can be folding."""
    return {
        "class": fit.class_id,
        "variant": fit.variant,
        "stickers_mm": {str(i): round(float(fit.residual_mm[i]), 1) for i in fit.misplaced},
        "hidden_seen": list(fit.hidden_seen),
        "folds": list(fit.wrong_folds),
        "in_the_air": list(fit.in_the_air),
    }


def _image_problem(
    frame: RGBDFrame,
    detections: StickerDetections,
    obs: ClothObservation,
    napkin_mm: float,
    layout: NapkinLayout,
    border: float,
) -> tuple[WhyKind, str | None]:
    """Why the images themselves give no verdict, and its kind: stickers too small,
    colour and depth of different instants, a wrong scale (geometry); cloth in a heap
    (crumpled); a corner's stickers folded apart (no state fits); a lens bending the
    napkin (geometry). ``(GEOMETRY, None)`` when none."""
    problem = (
        _too_small(detections, frame, napkin_mm, layout)
        or (edge_on_problem(obs.edge_on_mm) if obs.edge_on_mm is not None else None)
        or bare_raised_problem(obs.bare_raised)
        or scale_problem(
            obs.ruler, layout, frame.intrinsics, nominal=frame.intrinsics_source == "default"
        )
    )
    if problem is not None:
        return WhyKind.GEOMETRY, problem
    crumpled = crumpled_problem(obs, layout)
    if crumpled is not None:
        return WhyKind.CRUMPLED, crumpled
    apart = folded_apart_problem(obs, layout, lens_possible=border < 1.0)
    if apart is not None:
        return WhyKind.NO_STATE_FITS, f"no known state fits: {apart}"
    rigid = rigidity_problem(obs.ruler, lens_known=frame.intrinsics.distorted)
    if rigid is not None and diagonal_crease_stretch(obs, layout):
        return WhyKind.DEFERRED, rigid  # the state fit says (a diagonal fold's crease)
    return WhyKind.GEOMETRY, rigid


def _guess(
    coords: NDArray[np.float64],
    references: ReferenceSet,
    evidence: Evidence,
    front: NDArray[np.float64],
    obs: ClothObservation,
    layout: NapkinLayout,
    min_confidence: float,
) -> Prediction:
    """The nearest reference and its confidence; below ``min_confidence``, again with the
    stickers an object hides beside one lying at its flat place taken as known."""
    unsure = obs.evidence.near_object & obs.unknown if obs.evidence is not None else None
    guess = classify_coordinates(coords, references, evidence, distances=front, unsure=unsure)
    placed = obs.points_m is not None and obs.heights_mm is not None
    if guess.confidence < min_confidence and placed:
        settled = settled_stickers(
            obs.points_m, obs.heights_mm, obs.turns, layout, obs.up, pose=obs.pose
        )
        if settled.any():
            guess = classify_coordinates(
                coords, references, evidence, distances=front, unsure=unsure,
                settled=settled,
            )
    return guess


def _low_confidence_reason(
    guess: Prediction,
    obs: ClothObservation,
    min_confidence: float,
    border: float,
    checks: tuple[tuple[str, float], ...] = (),
) -> str:
    """``"cannot tell: confidence 0.12 < 0.25; ..."`` with what lowered it."""
    n = int(obs.visible.sum())
    ru = guess.runner_up
    why = [f"confidence {guess.confidence:.2f} < {min_confidence:.2f}"]
    if ru is not None:
        why.append(
            f"{guess.class_id} {guess.name} and {ru.class_id} {ru.name} are nearly as close "
            f"({guess.distance:.3f} vs {ru.distance:.3f})"
        )
    raised = obs.flap_deg is not None and bool(np.isfinite(obs.flap_deg).any())
    occluded = obs.evidence is not None and obs.evidence.occluded
    if occluded and not raised:  # (a flap raised is itself cloth above the napkin)
        why.append("the napkin is partly covered by an object above it")
    why.extend(f"{what} (confidence x{f:.2f})" for what, f in checks if f < 1.0)
    if border < 1.0:
        why.append(
            "stickers near the image border, lens distortion unknown (confidence "
            f"x{border:.2f}: give the lens with --intrinsics)"
        )
    unknown = _unknown_summary(obs)
    if unknown:
        why.append(unknown)
    if raised:
        why.append(
            f"a flap is raised, at about {np.nanmedian(obs.flap_deg):.0f} degrees"
            + (" (it, or an object holding it, stands above the napkin)" if occluded else "")
        )
    why.append(f"{n} of {len(obs.visible)} stickers located")
    return "cannot tell: " + "; ".join(why)
