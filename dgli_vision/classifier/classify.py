"""From cloth coordinates (and which stickers were seen) to a named state.

The distance to a reference is the Spearman distance over the coordinates known in the
observation, plus a visibility term: the mean, over the 16 stickers, of how far the
observation (seen / not seen) is from the reference's rate of being seen. A missing
sticker is evidence: it says what lies on top.

When visibility is given, coordinates of segments with an unseen sticker are ignored even
if a value is supplied (as a simulator can): no camera could have measured them, and a
sticker hidden by a flap lies within a cloth thickness of the flap's own segments, where
the dGLI is near-singular and its sign follows millimetre-level noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.classes import LIFTED_MM
from ..core.distance import soft_centred_unit_ranks
from ..core.errors import DetectionError, InvalidValueError
from .affordances import CornerMap
from .evidence import Evidence
from .references import ReferenceSet

if TYPE_CHECKING:
    from .affordances import SeenFold, SeenFolds

__all__ = [
    "FULL_COORDINATES",
    "FULL_MARGIN",
    "HEIGHT_WEIGHT",
    "LIFTED_MM",
    "LIFTED_WEIGHT",
    "MIN_CONFIDENCE",
    "MIN_COORDINATES",
    "PAST_WEIGHT",
    "TIE_SCALE",
    "VISIBILITY_WEIGHT",
    "DistanceTerms",
    "Evidence",
    "Prediction",
    "RunnerUp",
    "batch_distances",
    "classify_coordinates",
    "confidence_of",
    "coordinate_distances",
    "evidence_terms",
    "reference_distances",
    "reference_terms",
]

#: Fewer known coordinates than this (3 complete segments give 3) cannot be ranked.
MIN_COORDINATES = 3
#: Known coordinates that earn full confidence (4 complete segments give 6): with fewer,
#: the rank correlation is coarse and the confidence is scaled down in proportion.
FULL_COORDINATES = 6
#: Weight of the visibility term against the Spearman distance (both in [0, 2]).
VISIBILITY_WEIGHT = 1.0
#: Weight of the height term: the mean, over the stickers seen, of how far the
#: observation (standing above the table or not) is from the reference's rate. A
#: completed fold lies flat; a flap held up stands 20 mm and more above the table, which
#: tells a fold in progress from a finished one whose stickers fall in similar places.
LIFTED_WEIGHT = 1.0
#: Weight of the height term: the mean, over the stickers seen, of how far each stands
#: outside the reference's range of heights (beyond :data:`HEIGHT_SLACK_MM`), as a
#: fraction of :data:`HEIGHT_SCALE_MM` (capped at 1). It tells a flap held up by how
#: high it stands, so how wide the fold is: a strip and a half fold at the same angle
#: have nearly the same cloth coordinates.
HEIGHT_WEIGHT = 1.0
#: Weight of the lean term: the mean, over the stickers held up whose flap's lean was
#: measured, of how far the observation (turned past 90 degrees or not, see
#: ``ClothObservation.past_vertical``) is from the reference's rate. SPEC's rule
#: changes the class at 90 degrees, where a flap seen edge-on shows no sticker and the
#: lean of the raised cloth is all there is to tell.
PAST_WEIGHT = 1.0
#: Weight of the face term: the mean, over the corners whose stickers tell which face
#: they show (``perception.handedness``), of how far the observation (back face up or
#: not) is from the reference's rate. Three stickers of a corner tell a corner folded
#: over from one lying flat where a gripper or the flap's edge hides the fourth, which
#: the dGLI coordinates of that corner's segments then cannot.
FACE_WEIGHT = 1.0
#: Weight of the spread term: the mean, over the pairs of stickers seen, of how far
#: their 3D distance lies outside the reference's range (beyond
#: :data:`SPREAD_SLACK_MM`), as a fraction of :data:`SPREAD_SCALE_MM` (capped at 1).
#: The dGLI coordinates rank how segments wind round each other; with few of them known
#: (a gripper over half the napkin) a flat napkin and one with corners folded to the
#: centre can rank alike, but their stickers lie 300 mm apart in one and 50 mm in the
#: other.
SPREAD_WEIGHT = 1.0
#: Weight of the tip term: the sum, over the corners whose tip's flat place was looked
#: at (:mod:`~dgli_vision.perception.tips`), of how much more of it shows bare table
#: than the reference leaves bare, beyond :data:`TIP_SLACK`. A gripper over a corner
#: hides its stickers; the table seen where a flat corner would lie says it has moved.
TIP_WEIGHT = 1.0
#: Share of a tip's place seen bare beyond the reference's that costs nothing (the
#: nominal fold sizes stand for ranges; the fit of the napkin is a few mm off).
TIP_SLACK = 0.3
#: Distances within this of a reference's range agree with it (sticker centres to a few
#: mm, wrinkles up to 10 mm, a range drawn from a few states).
SPREAD_SLACK_MM = 20.0
#: A pair this far outside the range (beyond the slack) disagrees in full.
SPREAD_SCALE_MM = 60.0
#: Heights within this of a reference's range agree with it (sensor noise, cloth
#: layers, a range drawn from a few states).
HEIGHT_SLACK_MM = 15.0
#: A sticker this far outside the range (beyond the slack) disagrees in full.
HEIGHT_SCALE_MM = 50.0
#: Margin to the runner-up (distance units, Spearman + visibility) that earns full
#: confidence. On fresh renders of every class under every capture condition
#: (``dgli robustness``) right answers have a median margin near 0.3; the wrong ones
#: that remain come with margins below 0.04.
FULL_MARGIN = 0.2
#: Near ties among a frame's coordinates share their ranks over this fraction of the
#: coordinates' range (:func:`~dgli_vision.core.distance.soft_centred_unit_ranks`): a
#: millimetre of depth noise moves a coordinate by about 0.2% of the range, and two
#: nearly equal coordinates then swap ranks, which with six coordinates known moved the
#: Spearman distance by 0.057 and the confidence by up to 0.3 at once.
TIE_SCALE = 0.005
#: Below this confidence the answer is "cannot tell" (exit 1): a wrong answer is far
#: worse for a robot than none. 0.25 asks for a margin of 0.05 with every sticker's
#: state known (the closest right answers, two crossing flaps against two that do not
#: cross, have about 0.07).
MIN_CONFIDENCE = 0.25


@dataclass(frozen=True)
class RunnerUp:
    """The best reference of another class."""

    class_id: str
    name: str
    variant: str | None
    distance: float


@dataclass(frozen=True)
class StickerIds:
    """The stickers a verdict rests on, by id (0-15).

    Attributes
    ----------
    found : tuple of int
        Seen in the image.
    hidden : tuple of int
        Not seen because cloth lies on them: evidence of a fold.
    unknown : tuple of int
        Not seen, and that tells nothing (out of view, possibly under an object, in a
        highlight); ``reasons`` says why, in the same order.
    reasons : tuple of str
    """

    found: tuple[int, ...] = ()
    hidden: tuple[int, ...] = ()
    unknown: tuple[int, ...] = ()
    reasons: tuple[str, ...] = ()


@dataclass(frozen=True)
class Prediction:
    """A verdict.

    Attributes
    ----------
    class_id, name : str or None
        ``"02"``, ``"corner-over"``. None for a "cannot tell" that
        :func:`~dgli_vision.classifier.api.classify_pair` returns (``reason`` says why,
        ``candidates`` keeps the nearest states), as ``"class": null`` in ``--json``.
    variant : str or None
        SPEC's variant string (None with ``class_id`` None).
    distance : float
        Distance to the winning reference (Spearman + visibility term).
    runner_up : RunnerUp or None
        Best reference of any other class.
    margin : float
        ``runner_up.distance - distance`` (``inf`` without a runner-up).
    confidence : float
        In [0, 1], from the margin and the amount of evidence (:func:`confidence_of`).
    reason : str or None
        Why the command line would say "cannot tell" of this answer (None when it would
        not): :func:`~dgli_vision.classifier.api.classify_pair` fills it.
    why : str or None
        The kind of that reason (``FrameResult.why``).
    stickers : StickerIds or None
        The stickers found, hidden and unknown (``classify_pair`` fills it).
    corners : CornerMap
        Corners ``"A"``-``"D"`` by name, as in the JSON (``p.corners["A"].point``):
        point, pixel, state, graspable
        (:class:`~dgli_vision.classifier.affordances.CornerAffordance`); empty when not
        computed.
    folds : tuple of SeenFold, or SeenFolds
        The folds of the verdict as lines on the table (a classified frame's are a
        :class:`~dgli_vision.classifier.affordances.SeenFolds`, worked out with its
        corners when first read).
    candidates : tuple of (str, str or None, float)
        The nearest state of each of the three nearest classes, as (class, variant,
        distance), nearest first (``classify_pair`` fills it; ``"candidates"`` in
        ``--json``).
    """

    class_id: str | None
    name: str | None
    variant: str | None
    distance: float
    runner_up: RunnerUp | None
    margin: float
    confidence: float = 1.0
    reason: str | None = None
    why: str | None = None
    stickers: StickerIds | None = None
    corners: CornerMap = field(default_factory=CornerMap)
    folds: tuple[SeenFold, ...] | SeenFolds = ()
    candidates: tuple[tuple[str, str | None, float], ...] = ()


def confidence_of(
    margin: float,
    n_unknown_stickers: int = 0,
    n_stickers: int = 16,
    n_coordinates: int | None = None,
) -> float:
    """Confidence in [0, 1] of a verdict.

    The margin to the best reference of another class, as a fraction of
    :data:`FULL_MARGIN` (capped at 1), times the cube of the share of stickers whose
    state is known: seen, or hidden by the cloth (which is evidence too). The cube:
    references that differ only in unknown stickers tie on everything that is known, and
    what separates them then is the spread of fold sizes within each class, not the
    fold; with four stickers unknown a margin of 0.12 is needed. With
    fewer than :data:`FULL_COORDINATES` known coordinates it is scaled down in proportion.

    Parameters
    ----------
    margin : float
        Runner-up distance minus winner distance (``inf`` without a runner-up).
    n_unknown_stickers : int
        Stickers whose state cannot be told (out of view, possibly under an object, in a
        highlight).
    n_stickers : int
        All stickers (16).
    n_coordinates : int, optional
        Cloth coordinates the verdict rests on.
    """
    margin_part = 1.0  # (math and min/max: np.clip's value without its overhead on one)
    if math.isfinite(margin):
        margin_part = min(max(float(margin) / FULL_MARGIN, 0.0), 1.0)
    known = 1.0 - n_unknown_stickers / max(n_stickers, 1)
    coords_part = 1.0 if n_coordinates is None else min(1.0, n_coordinates / FULL_COORDINATES)
    return round(margin_part * max(known, 0.0) ** 3 * coords_part, 4)


def _n_segments(n_coordinates: int) -> int:
    """m such that m (m - 1) / 2 == n_coordinates."""
    m = round((1 + math.sqrt(1 + 8 * n_coordinates)) / 2)
    if m * (m - 1) // 2 != n_coordinates:
        raise ValueError(f"{n_coordinates} is not a number of segment pairs")
    return m


def reference_distances(
    coords: ArrayLike, references: ReferenceSet, evidence: Evidence | None = None
) -> NDArray[np.float64]:
    """Distance of one observation to every reference, shape (k,).

    Parameters
    ----------
    coords : array_like, shape (28,)
        dGLI coordinates, NaN where unknown.
    references : ReferenceSet
    evidence : Evidence, optional
        What else was seen of the frame (:class:`~dgli_vision.classifier.evidence.Evidence`,
        arrays of one frame): each term it gives is weighed (:data:`VISIBILITY_WEIGHT`,
        :data:`LIFTED_WEIGHT`, :data:`HEIGHT_WEIGHT`, :data:`PAST_WEIGHT`,
        :data:`FACE_WEIGHT`, :data:`SPREAD_WEIGHT`, :data:`TIP_WEIGHT`); where it gives
        ``visible``, coordinates of segments with an unseen sticker are not used.

    Raises
    ------
    DetectionError
        With fewer than :data:`MIN_COORDINATES` known coordinates.
    """
    return reference_terms(coords, references, evidence).total()


@dataclass(frozen=True)
class DistanceTerms:
    """The parts of an observation's distance to every reference, shape (k,) each: the
    Spearman distance of the dGLI coordinates, the sum of the weighted evidence terms but
    the corners' faces and tips, the faces' mean disagreement (unweighted; zeros without
    ``back``), and the weighted tip term (None without ``tips``). :meth:`mirrored` gives
    the terms of the same observation seen in a mirror without computing anything
    again."""

    dgli: NDArray[np.float64]
    evidence: NDArray[np.float64]
    face: NDArray[np.float64]
    back: NDArray[np.float64] | None
    back_rates: NDArray[np.float64] | None
    tip: NDArray[np.float64] | None = None
    #: The faces' term of the mirror image, when worked out with ``face`` (None: by
    #: :meth:`mirrored` when asked).
    mirror_face: NDArray[np.float64] | None = field(default=None, repr=False)

    def total(self) -> NDArray[np.float64]:
        """The distance to every reference, shape (k,)."""
        out = self.dgli + self.evidence + FACE_WEIGHT * self.face
        return out if self.tip is None else out + self.tip

    def mirrored(self) -> DistanceTerms:
        """The terms of the mirror image: every dGLI coordinate changes sign, so each
        Spearman correlation does (``d -> 2 - d``), and every corner's stickers turn round
        (``back -> 1 - back``). The tips' places were found front face up, which a
        mirror does not hold to: the mirrored reading goes without them."""
        face, back = self.face, self.back
        if back is not None and self.back_rates is not None:
            back = 1.0 - back
            face = self.mirror_face
            if face is None:
                face = _face_gap(back[None], self.back_rates.T)[0]
        dgli = np.clip(2.0 - self.dgli, 0.0, 2.0)
        return DistanceTerms(dgli, self.evidence, face, back, self.back_rates)


def reference_terms(
    coords: ArrayLike, references: ReferenceSet, evidence: Evidence | None = None
) -> DistanceTerms:
    """:func:`reference_distances` in its parts (same arguments, same errors)."""
    ev = evidence if evidence is not None else Evidence()
    x = np.asarray(coords, dtype=np.float64)
    ref = references.matrix()
    if x.shape != (ref.shape[1],):
        raise InvalidValueError(f"coords must have shape ({ref.shape[1]},), got {x.shape}")
    n_stickers = 2 * _n_segments(len(x))
    if ev.visible is not None and np.shape(ev.visible) != (n_stickers,):
        raise InvalidValueError(
            f"visible must have shape ({n_stickers},), got {np.shape(ev.visible)}"
        )
    known = ev.known_coordinates(x)
    if known.sum() < MIN_COORDINATES:
        raise DetectionError(
            f"only {int(known.sum())} of {len(x)} cloth coordinates are known; "
            f"need at least {MIN_COORDINATES} (3 segments with both stickers seen)"
        )
    dgli = coordinate_distances(x[None], known[None], references)[0]
    back = None if ev.back is None else np.asarray(ev.back, dtype=np.float64)
    rest, face, tip = _evidence_terms(ev.stacked(), references, faces=back is None)
    if back is None:
        return DistanceTerms(dgli, rest[0], face[0], None, None, None if tip is None else tip[0])
    # the faces' term of the mirror image with this one, in one call (mirror_problem
    # asks for it every frame)
    face, mirror_face = _face_gap(np.stack([back, 1.0 - back]), references.by_row("back_rate"))
    rates = references.back_rates()
    return DistanceTerms(
        dgli, rest[0], face, back, rates, None if tip is None else tip[0], mirror_face
    )


def coordinate_distances(
    coords: NDArray[np.float64], known: NDArray[np.bool_], references: ReferenceSet
) -> NDArray[np.float64]:
    """Spearman distance of n frames' coordinates to every reference, over each frame's
    known coordinates (ranked softly, :data:`TIE_SCALE`), shape (n, k); a row of NaN
    where a frame has fewer than :data:`MIN_COORDINATES` known.

    Parameters
    ----------
    coords : ndarray, shape (n, 28)
    known : ndarray of bool, shape (n, 28)
        The coordinates to compare on (:meth:`.Evidence.known_coordinates`).
    references : ReferenceSet
    """
    out = np.full((len(coords), len(references.references)), np.nan)
    ok = known.sum(axis=1) >= MIN_COORDINATES
    if not ok.any():
        return out
    rows = np.flatnonzero(ok)
    if len(rows) == 1:  # one frame (the camera's): no grouping to do
        mask = known[rows[0]]
        ranks = soft_centred_unit_ranks(coords[rows][:, mask], TIE_SCALE)
        out[rows] = np.clip(1.0 - ranks @ references.ranked(mask).T, 0.0, 2.0)
        return out
    masks, group = np.unique(known[ok], axis=0, return_inverse=True)
    for g, mask in enumerate(masks):
        sel = rows[group.ravel() == g]
        ranks = soft_centred_unit_ranks(coords[sel][:, mask], TIE_SCALE)
        out[sel] = np.clip(1.0 - ranks @ references.ranked(mask).T, 0.0, 2.0)
    return out


def evidence_terms(
    evidence: Evidence, references: ReferenceSet
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64] | None]:
    """The evidence terms of n frames (``evidence`` stacked, :meth:`.Evidence.stacked`)
    against every reference: the weighted sum of all but the corners' faces and tips,
    the faces' mean disagreement (unweighted; zeros without ``back``), and the weighted
    tip term (None without ``tips``), each of shape (n, k)."""
    return _evidence_terms(evidence, references)


def _evidence_terms(
    evidence: Evidence, references: ReferenceSet, *, faces: bool = True
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64] | None]:
    """:func:`evidence_terms`; without ``faces``, zeros for the faces' term (the caller
    works it out)."""
    ev = evidence
    k = len(references.references)
    n = next((len(v) for v in vars(ev).values() if v is not None), 1)
    rest = np.zeros((n, k))
    if ev.visible is not None:
        rest += VISIBILITY_WEIGHT * _visibility_gap(
            ev.visible, ev.unknown, references.visible_rates()
        )
    if ev.lifted is not None:
        rest += LIFTED_WEIGHT * _rate_gap(ev.lifted, references.by_row("lifted_rate"))
    if ev.heights_mm is not None:
        rest += HEIGHT_WEIGHT * _height_gap(ev.heights_mm, references.height_bounds())
    if ev.past is not None:
        rest += PAST_WEIGHT * _rate_gap(ev.past, references.by_row("past_rate"))
    if ev.spread_mm is not None:
        rest += SPREAD_WEIGHT * _spread_gap(ev.spread_mm, references.spread_bounds())
    face = np.zeros((n, k))
    if ev.back is not None and faces:
        face = _face_gap(ev.back, references.by_row("back_rate"))
    tip = None
    if ev.tips is not None:
        tip = TIP_WEIGHT * _tip_gap(ev.tips, references.by_row("tip_clear"))
    return rest, face, tip


def batch_distances(
    coords: NDArray[np.float64], evidence: Evidence, references: ReferenceSet
) -> NDArray[np.float64]:
    """:func:`reference_distances` of n frames at once, shape (n, k): the same terms,
    computed by the same functions; a row of NaN where a frame has fewer than
    :data:`MIN_COORDINATES` known coordinates (where the single frame raises).

    Parameters
    ----------
    coords : ndarray, shape (n, 28)
    evidence : Evidence
        Of the n frames, stacked (a leading axis n on each array).
    references : ReferenceSet
    """
    x = np.asarray(coords, dtype=np.float64)
    out = coordinate_distances(x, evidence.known_coordinates(x), references)
    rest, face, tip = evidence_terms(evidence, references)
    out += rest + FACE_WEIGHT * face
    return out if tip is None else out + tip


def _mean_over(told: NDArray[np.bool_], gap: NDArray[np.float64]) -> NDArray[np.float64]:
    """Mean of ``gap`` (n, k, s) over the entries told (n, s); 0 where none is."""
    g = np.where(told[:, None, :], gap, 0.0).sum(axis=2)
    return g / np.maximum(told.sum(axis=1), 1)[:, None]


def _mean_over_rows(told: NDArray[np.bool_], gap: NDArray[np.float64]) -> NDArray[np.float64]:
    """Mean of ``gap`` (n, s, k), one row per sticker or pair, over the rows told (n, s),
    (n, k); 0 where none is. The rows are added in order, one after the other."""
    if told.all():  # a frame's own rows (each term takes those it tells): nothing to mask
        return gap.sum(axis=1) / max(told.shape[1], 1)
    g = np.where(told[:, :, None], gap, 0.0).sum(axis=1)
    return g / np.maximum(told.sum(axis=1), 1)[:, None]


def _zeroed(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """``x`` with 0 where it is not finite (what ``np.nan_to_num`` does with NaN, at a
    fraction of its overhead on short arrays)."""
    return np.where(np.isfinite(x), x, 0.0)


def _told_columns(told: NDArray[np.bool_]) -> NDArray[np.intp]:
    """The columns told in some frame: the terms are computed on them alone (a camera
    frame tells a few of the 120 sticker pairs)."""
    return np.flatnonzero(told.any(axis=0))


def _visibility_gap(
    visible: ArrayLike, unknown: ArrayLike | None, rates: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Mean ``|seen - rate|`` over the stickers that are not unknown, (n, k)."""
    vis = np.asarray(visible, dtype=bool)
    use = np.ones_like(vis) if unknown is None else ~np.asarray(unknown, dtype=bool)
    return _mean_over(use, np.abs(vis[:, None, :] - rates[None]))


def _rate_gap(observed: ArrayLike, rates: NDArray[np.float64]) -> NDArray[np.float64]:
    """Mean ``|observed - rate|`` over the stickers told (finite), (n, k) for ``rates``
    of shape (16, k) (:meth:`.ReferenceSet.by_row`); 0 where none is told."""
    x = np.asarray(observed, dtype=np.float64)
    told = np.isfinite(x)
    rows = _told_columns(told)
    if len(rows) < len(rates):
        x, told, rates = x[:, rows], told[:, rows], rates[rows]
    return _mean_over_rows(told, np.abs(_zeroed(x)[:, :, None] - rates))


def _tip_gap(tips: ArrayLike, clear: NDArray[np.float64]) -> NDArray[np.float64]:
    """How much more of the corners' tip places shows bare table than each reference
    leaves bare (``clear``, one row per corner, (4, k): :meth:`.ReferenceSet.by_row`),
    beyond :data:`TIP_SLACK`, summed over the corners told, (n, k)."""
    t = np.asarray(tips, dtype=np.float64)
    over = np.clip(_zeroed(t)[:, :, None] - clear[None] - TIP_SLACK, 0.0, None)
    return np.where(np.isfinite(t)[:, :, None], over, 0.0).sum(axis=1)


def _range_gap(
    x: NDArray[np.float64], lo: NDArray[np.float64], hi: NDArray[np.float64],
    slack: float, scale: float,
) -> NDArray[np.float64]:
    """How far each value of ``x`` (n, s) lies outside each reference's range ``lo``
    to ``hi`` (s, k) beyond ``slack``, as a fraction of ``scale`` capped to [0, 1],
    (n, s, k); NaN where ``x`` or the range is."""
    v = x[:, :, None]
    gap = lo - v
    np.maximum(gap, v - hi, out=gap)
    gap -= slack
    gap /= scale
    np.clip(gap, 0.0, 1.0, out=gap)
    return gap


def _spread_gap(
    spread_mm: ArrayLike,
    bounds: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]],
) -> NDArray[np.float64]:
    """Mean disagreement in [0, 1] of the observed sticker-pair distances with each
    reference's ranges (``bounds``: :meth:`.ReferenceSet.spread_bounds`, one row per
    pair), (n, k); 0 for a frame where none is known, or where some reference keeps no
    range of a pair told."""
    lo, hi, kept = bounds
    d = np.asarray(spread_mm, dtype=np.float64)
    told = np.isfinite(d)
    usable = told.any(axis=1) & ~(told & ~kept).any(axis=1)
    every = bool(usable.all())
    if not every:
        if not usable.any():
            return np.zeros((len(d), lo.shape[1]))
        d, told = d[usable], told[usable]
    rows = _told_columns(told)
    if len(rows) < len(lo):
        d, told, lo, hi = d[:, rows], told[:, rows], lo[rows], hi[rows]
    # The mean of clip((g - slack) / scale, 0, 1) over the pairs told, g the distance
    # outside the range, taken as (the sum of clip(g, slack, slack + scale) less the
    # slack of each pair) / scale: two passes over the (pairs, references) table fewer
    # than term by term, the same to rounding (1e-16).
    v = d[:, :, None]
    g = lo - v
    np.maximum(g, v - hi, out=g)
    np.clip(g, SPREAD_SLACK_MM, SPREAD_SLACK_MM + SPREAD_SCALE_MM, out=g)
    if told.all():
        total, count = g.sum(axis=1), max(g.shape[1], 1)
    else:  # a pair not told counts as within the slack
        total = np.where(told[:, :, None], g, SPREAD_SLACK_MM).sum(axis=1)
        count = np.maximum(told.sum(axis=1), 1)[:, None]
    total -= g.shape[1] * SPREAD_SLACK_MM
    total /= SPREAD_SCALE_MM
    gap = total / count
    if every:
        return gap
    out = np.zeros((len(usable), lo.shape[1]))
    out[usable] = gap
    return out


def _face_gap(back: ArrayLike, rates: NDArray[np.float64]) -> NDArray[np.float64]:
    """Mean ``|back - rate|`` over the corners told both in the observation and in each
    reference (``rates`` one row per corner, shape (4, k): :meth:`.ReferenceSet.by_row`,
    NaN where not told), (n, k); 0 where none is."""
    x = np.asarray(back, dtype=np.float64)
    both = np.isfinite(x)[:, :, None] & np.isfinite(rates)[None]
    diff = np.abs(_zeroed(x)[:, :, None] - _zeroed(rates)[None])
    return np.where(both, diff, 0.0).sum(axis=1) / np.maximum(both.sum(axis=1), 1)


def _height_gap(
    heights_mm: ArrayLike,
    bounds: tuple[NDArray[np.float64], NDArray[np.float64], bool],
) -> NDArray[np.float64]:
    """Mean disagreement in [0, 1] of the stickers' heights with each reference's ranges
    (``bounds``: :meth:`.ReferenceSet.height_bounds`, one row per sticker), (n, k); 0
    where a reference keeps no range."""
    lo, hi, kept = bounds
    h = np.asarray(heights_mm, dtype=np.float64)
    told = np.isfinite(h)
    rows = _told_columns(told)
    if len(rows) < len(lo):
        h, told, lo, hi = h[:, rows], told[:, rows], lo[rows], hi[rows]
    gap = _range_gap(h, lo, hi, HEIGHT_SLACK_MM, HEIGHT_SCALE_MM)
    if not kept:  # (a reference without a range of a sticker: no disagreement)
        gap = _zeroed(gap)
    return _mean_over_rows(told, gap)


def classify_coordinates(
    coords: ArrayLike,
    references: ReferenceSet,
    evidence: Evidence | None = None,
    *,
    distances: ArrayLike | None = None,
    unsure: ArrayLike | None = None,
    settled: ArrayLike | None = None,
) -> Prediction:
    """Nearest reference of an observation (see :func:`reference_distances`).

    Parameters
    ----------
    coords : array_like, shape (28,)
        dGLI coordinates, NaN where a segment is missing.
    references : ReferenceSet
    evidence : Evidence, optional
        What else was seen (see :func:`reference_distances`). Its ``unknown`` stickers
        lower the confidence; one whose flap's lean was measured (``past`` finite)
        counts as known: it is on that flap, standing.
    distances : array_like, shape (k,), keyword-only, optional
        :func:`reference_distances` of these arguments, when already computed.
    unsure : array_like of bool, shape (16,), keyword-only, optional
        Stickers that count as unknown for the confidence whatever else is told of them
        (held up where an object may cover them: the edge of an object over the napkin
        reads as raised cloth too).
    settled : array_like of bool, shape (16,), keyword-only, optional
        Stickers that count as known for the confidence (an object hides them beside a
        partner lying at its flat place).

    Returns
    -------
    Prediction
    """
    ev = evidence if evidence is not None else Evidence()
    if distances is None:
        dist = reference_distances(coords, references, ev)
    else:
        dist = np.asarray(distances, dtype=np.float64)
    codes = references.class_codes()
    if np.isfinite(dist).all():
        # the first nearest, and the first nearest of another class: what a stable sort
        # puts first (argmin takes the first of equal values), without sorting
        b = int(dist.argmin())
        other = codes != codes[b]
        k = int(np.where(other, dist, np.inf).argmin()) if other.any() else -1
    else:  # (NaN or inf: as the stable sort orders them)
        order = np.argsort(dist, kind="stable")
        b = int(order[0])
        other = codes[order] != codes[b]
        k = int(order[int(np.argmax(other))]) if other.any() else -1
    best = references.references[b]
    runner = None
    if k >= 0:  # the nearest reference of another class
        r = references.references[k]
        runner = RunnerUp(r.class_id, r.name, r.variant, float(dist[k]))
    d = float(dist[b])
    margin = (runner.distance - d) if runner else float("inf")
    n_unknown = 0
    if ev.unknown is not None:
        still = np.asarray(ev.unknown, dtype=bool)
        if ev.past is not None:
            still = still & ~np.isfinite(np.asarray(ev.past, dtype=np.float64))
        if unsure is not None:
            still = still | np.asarray(unsure, dtype=bool)
        if settled is not None:
            still = still & ~np.asarray(settled, dtype=bool)
        n_unknown = int(still.sum())
    x = np.asarray(coords, dtype=np.float64)
    n_known = int(ev.known_coordinates(x).sum())
    confidence = confidence_of(margin, n_unknown, 2 * _n_segments(len(x)), n_known)
    return Prediction(best.class_id, best.name, best.variant, d, runner, margin, confidence)
