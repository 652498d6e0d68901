"""Does the nearest state explain the stickers seen? The check after the verdict.

The nearest reference by Spearman distance is the nearest of the twelve states, whatever
the napkin's state: a napkin folded in quarters, gate-folded or with a corner folded
twice is near some state too. What tells it apart is geometry. A state's folds, fitted
to the stickers seen (each flap a rigid turn of the flat napkin about its crease, the
fit of :mod:`.fold_geometry`), predict where every sticker lying on the table lies,
which stickers no camera can see and which may stand in the air. The state fits when

* every sticker seen lying flat lies within :data:`PLACE_TOLERANCE_MM` of where the
  fitted state puts it (one sticker alone may be off by up to :data:`LONE_TOLERANCE_MM`:
  a sticker half covered at a crease shows the centroid of its uncovered part; farther,
  it lowers the confidence, by :data:`LONE_FLOOR` at most, but never alone rules the
  state out: a misread sticker is no fold);
* each fitted fold is the state's: its legs, inset or place on the diagonal within
  :data:`SIZE_SLACK_MM` of SPEC's ranges, a strip's crease within
  :data:`SKEW_SLACK_DEG` of parallel to its side;
* no sticker is seen that the state hides: under a flap folded under, or more than
  :data:`COVERED_MARGIN_MM` inside the place a flap lying on top covers;
* the stickers standing in the air (above ``LIFTED_MM``, or held up out of sight) are
  on one flap, and one that the state can be folding: one of its own folds settling,
  or a fold to a state one fold further rising (:func:`moving_flaps`).

Each criterion gives a factor on the verdict's confidence that falls continuously
from 1 to 0 over the last part of its tolerance (:data:`RAMP`), so that a tiny change
of the input never moves the confidence from 1 to 0; where it reaches 0 the state does
not fit, and the answer is "cannot tell: no known state fits".

The fit is made for both handednesses of the napkin as a whole (front face up, and
mirrored: back face up or a mirroring camera), the better kept: whether the whole image
may be mirrored is the mirror check's say (:mod:`.consistency`); this one asks whether
the state's folds, with the face each part shows, explain the stickers.

The tolerances come from the residuals of the twelve states' own renders under every
capture condition and in folding sequences (docs/outside.md has the figures).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ..core.classes import CLASS_NAMES, CORNERS
from ..core.fold_graph import fold_edges
from ..core.fold_lines import (
    CORNER_LEG_RANGES,
    SIDE_INSET_RANGES,
    NominalFold,
    along_scale,
    nominal_folds,
)
from ..core.fold_measure import Crease, fold_kind, fold_measures
from ..core.layout import NapkinLayout
from .fold_geometry import initial_flaps, plane_basis, rigid_fit_2d, rotation_2d, solve_flaps

__all__ = [
    "COVERED_MARGIN_MM",
    "LONE_TOLERANCE_MM",
    "PLACE_TOLERANCE_MM",
    "RAMP",
    "SIZE_SLACK_MM",
    "SKEW_SLACK_DEG",
    "StateFit",
    "fit_state",
    "moving_flaps",
    "unexplained_in_the_air",
]

#: A sticker seen lying flat farther than this (mm, in the table plane) from where the
#: fitted state puts it is not explained by the state (with a second one beyond
#: :data:`RAMP` times it). The twelve states' renders leave every sticker within 9 mm
#: under every capture condition (wrinkles up to 10 mm, a flap settling at 170
#: degrees, 2-4 mm of depth noise); a fold the state does not have moves stickers by
#: 30 mm and more.
PLACE_TOLERANCE_MM = 15.0
#: One sticker alone is still explained up to this far (a sticker half covered at a
#: crease shows its uncovered part, whose centroid lies up to a radius off).
LONE_TOLERANCE_MM = 25.0
#: The factor one sticker alone off its place leaves at most: a sticker misread (a
#: coloured object taken for it, a disc cut by a crease) is no fold, but a doubt.
LONE_FLOOR = 0.5
#: How far (mm on the 400 mm napkin, scaled with it) a fitted fold's size may lie outside
#: its class's range (SPEC section 3) and still be that fold: a robot's fold is seldom
#: exactly in range, and the fit is good to a few mm.
SIZE_SLACK_MM = 40.0
#: How far (degrees) a strip's or half fold's crease may turn from its side (SPEC's
#: are parallel to it; the fit is good to 2-3 degrees).
SKEW_SLACK_DEG = 10.0
#: How far (mm, scaled) a diagonal fold's crease may lie from the diagonal at its middle
#: (SPEC: within 10 mm along its whole length), and how far it may turn (degrees).
DIAGONAL_SLACK_MM = 30.0
DIAGONAL_TURN_DEG = 6.0
#: A corner fold's legs, whatever the class (mm on the 400 mm napkin): the union of
#: SPEC's ranges, since a state is the fold it has (folding sequence II folds the corners
#: of 04 and 07 with 08's legs).
_CORNER_LEGS = (
    min(r[0] for pair in CORNER_LEG_RANGES.values() for r in pair),
    max(r[1] for pair in CORNER_LEG_RANGES.values() for r in pair),
)
#: A sticker seen this far (mm, on the flat napkin) inside the place a flap lying on top
#: covers contradicts the state: its disc's radius is 15 mm, so one 15 mm inside is
#: wholly covered; a few mm more for the fitted crease's own error.
COVERED_MARGIN_MM = 20.0
#: Each criterion's factor falls from 1 at ``RAMP`` times its tolerance to 0 at the
#: tolerance (linearly).
RAMP = 0.7
#: A part (the napkin that stays, or a flap) is fitted on its own, without a placed
#: napkin under it, from this many stickers lying flat: three fix its handedness.
MIN_PART_STICKERS = 3


def _ramp(x: float, tolerance: float) -> float:
    """1 up to ``RAMP * tolerance``, 0 from ``tolerance`` on, linear between."""
    lo = RAMP * tolerance
    return min(max((tolerance - x) / (tolerance - lo), 0.0), 1.0)


@dataclass(frozen=True)
class StateFit:
    """How well a state's folds explain the stickers seen.

    Attributes
    ----------
    class_id, variant : str, str or None
        The state fitted.
    factor : float
        In [0, 1], on the verdict's confidence: 1 where every criterion is well within
        its tolerance, 0 where one is beyond it (the state does not fit).
    residual_mm : ndarray, shape (16,)
        Each sticker's distance (mm, in the table plane) from where the fitted state
        puts it; NaN for a sticker not seen lying flat or on no fitted part.
    misplaced : tuple of int
        Stickers the state does not explain by their place.
    hidden_seen : tuple of int
        Stickers seen that the state hides.
    wrong_folds : tuple of str
        Folds whose fitted crease is not the state's (``"CD strip over: its crease runs
        22 degrees off its side"``).
    in_the_air : tuple of int
        Stickers standing in the air on no flap the state can be folding.
    mirrored : bool
        Whether the fit kept is the mirrored one.
    """

    class_id: str
    variant: str | None
    factor: float
    residual_mm: NDArray[np.float64]
    misplaced: tuple[int, ...] = ()
    hidden_seen: tuple[int, ...] = ()
    wrong_folds: tuple[str, ...] = ()
    in_the_air: tuple[int, ...] = ()
    mirrored: bool = False

    @property
    def fits(self) -> bool:
        """Whether the state explains what was seen (``factor`` above 0)."""
        return self.factor > 0.0

    def describe(self) -> str:
        """What the state leaves unexplained, for a "cannot tell": ``"sticker 3 lies
        48 mm from where 09 strip-over (AB) puts it; ..."`` (empty when it fits)."""
        state = f"{self.class_id} {CLASS_NAMES[self.class_id]}" + (
            f" ({self.variant})" if self.variant else ""
        )
        parts = []
        if self.misplaced:
            worst = sorted(self.misplaced, key=lambda i: -self.residual_mm[i])
            listed = ", ".join(f"{i} {self.residual_mm[i]:.0f} mm" for i in worst[:4])
            more = f" and {len(worst) - 4} more" if len(worst) > 4 else ""
            them = "it" if len(worst) == 1 else "them"
            parts.append(f"{_stickers(worst)} {listed}{more} from where {state} puts {them}")
        if self.hidden_seen:
            ids = ", ".join(str(i) for i in self.hidden_seen)
            parts.append(f"{_stickers(self.hidden_seen)} {ids} seen, which {state} hides")
        parts.extend(f"{state}'s fold {w}" for w in self.wrong_folds)
        if self.in_the_air:
            ids = ", ".join(str(i) for i in self.in_the_air)
            parts.append(
                f"{_stickers(self.in_the_air)} {ids} in the air, on no flap {state} "
                "can be folding"
            )
        return "; ".join(parts)


def _stickers(ids: tuple[int, ...] | list[int]) -> str:
    return "sticker" if len(ids) == 1 else "stickers"


def _sticker_parts(folds: tuple[NominalFold, ...], uv: NDArray[np.float64]) -> NDArray[np.intp]:
    """The part each sticker lies on: -1 the napkin that stays, else the index of the
    last fold whose flap holds it (as the affordances' plan)."""
    from .affordances import ON_LINE_MM

    part = np.full(len(uv), -1)
    for j, f in enumerate(folds):
        part[f.on_flap(uv, ON_LINE_MM)] = j
    return part


@lru_cache(maxsize=128)
def _parts_of_state(class_id: str, variant: str | None, layout: NapkinLayout) -> NDArray[np.intp]:
    """:func:`_sticker_parts` of a state's nominal folds, worked out once (read-only)."""
    part = _sticker_parts(nominal_folds(class_id, variant, layout), layout.sticker_uv)
    part.setflags(write=False)
    return part


@lru_cache(maxsize=128)
def moving_flaps(
    class_id: str, variant: str | None, layout: NapkinLayout
) -> tuple[tuple[frozenset[int], frozenset[int]], ...]:
    """The flaps that may stand in the air while the napkin is in this state, by SPEC's
    90-degree rule: each of its own folds (settling, past 90 degrees) and each fold that
    leads to a state one fold further (rising, not yet at 90). Each as (the stickers on
    the flap, the stickers under the place it lands: out of sight beneath it while it
    stands in the air)."""
    uv = np.asarray(layout.sticker_uv, dtype=float)
    flaps: list[NominalFold] = list(nominal_folds(class_id, variant, layout))
    for before, after, word in fold_edges():
        if before == (class_id, variant):
            flaps += [f for f in nominal_folds(*after, layout) if f.word == word]
    out = []
    for f in flaps:
        on = f.on_flap(uv, 0.0)
        lands = _covered_depth(
            uv, np.full(len(uv), -1), (f,), {}, layout, np.zeros(1, dtype=bool)
        ) > 0.0
        out.append((frozenset(np.flatnonzero(on).tolist()),
                    frozenset(np.flatnonzero(lands & ~on).tolist())))
    return tuple(out)


def fit_state(
    obs: object, class_id: str, variant: str | None, layout: NapkinLayout
) -> StateFit:
    """Fit a state's folds to the stickers of ``obs`` and say what they leave unexplained
    (see the module's description).

    Parameters
    ----------
    obs : ClothObservation
        The stickers in 3D (``points_m``), which were seen (``visible``), their heights
        above the table (``heights_mm``), which stand or are held up (``lifted``) and
        the table normal (``up``).
    class_id, variant : str, str or None
        The state, as SPEC names it.
    layout : NapkinLayout

    Returns
    -------
    StateFit
    """
    uv = np.asarray(layout.sticker_uv, dtype=float)
    n = len(uv)
    pts = getattr(obs, "points_m", None)
    if pts is None:
        return StateFit(class_id, variant, 1.0, np.full(n, np.nan))
    seen = np.asarray(obs.visible, dtype=bool) & np.isfinite(pts).all(axis=1)
    up_mask = obs.lifted
    raised = np.zeros(n, dtype=bool) if up_mask is None else np.nan_to_num(up_mask) > 0.5
    lying = seen & ~raised
    held = raised & ~seen  # out of sight, on cloth held up (the evidence's say)
    folds = nominal_folds(class_id, variant, layout)
    part = _parts_of_state(class_id, variant, layout)
    under = np.array([f.under for f in folds] + [False], dtype=bool)  # [-1]: stays
    hidden_under = seen & under[part]
    airborne = np.array([bool(np.any(raised & (part == j))) for j in range(len(folds))])
    flaps = moving_flaps(class_id, variant, layout)
    air, air_factor = unexplained_in_the_air(raised & seen, held, flaps)
    p2 = (np.nan_to_num(pts) @ plane_basis(obs.up).T) * 1e3
    best: tuple | None = None
    for mirrored in (False, True):
        q = p2 * np.array([1.0, -1.0]) if mirrored else p2
        res, creases = _fit_parts(uv, q, part, lying & ~hidden_under, folds)
        place, misplaced = _place_factor(res)
        depth = _covered_depth(uv, part, folds, creases, layout, airborne)
        depth = np.where(seen & ~hidden_under, depth, -np.inf)
        covered = tuple(int(i) for i in np.flatnonzero(depth > COVERED_MARGIN_MM))
        cover = _ramp(float(np.max(depth)), COVERED_MARGIN_MM)  # (the ramp falls with depth)
        # a crease is measured where the napkin under it is placed by two stickers of
        # its own (or three flaps), and two stickers of the flap fix it
        stay = np.count_nonzero(lying & ~hidden_under & (part < 0))
        sized = {
            j: c for j, c in creases.items()
            if np.count_nonzero(lying & (part == j)) >= 2 and (stay >= 2 or len(creases) >= 3)
        }
        size, wrong = _size_factor(class_id, variant, folds, sized, layout)
        factor = min(place, cover, size, air_factor, 0.0 if hidden_under.any() else 1.0)
        score = (-factor, float(np.nansum(np.minimum(res, 50.0))))
        if best is None or score < best[0]:
            best = (score, factor, res, misplaced, covered, wrong, mirrored)
        if factor == 1.0:  # explained as seen: the mirrored fit can do no better
            break
    _, factor, res, misplaced, covered, wrong, mirrored = best
    hidden = tuple(sorted(set(np.flatnonzero(hidden_under).tolist()) | set(covered)))
    if factor > 0.0:  # what is listed is what rules the state out
        misplaced, hidden, wrong, air = (), (), (), ()
    return StateFit(
        class_id, variant, round(factor, 6), res, misplaced, hidden, wrong, air, mirrored
    )


def unexplained_in_the_air(
    raised: NDArray[np.bool_],
    held: NDArray[np.bool_],
    flaps: tuple[tuple[frozenset[int], frozenset[int]], ...],
) -> tuple[tuple[int, ...], float]:
    """The stickers in the air that no one flap the state can be folding explains, and
    the factor (0 or 1: a sticker is seen in the air or not; how high is the flap
    checks' say). A flap explains the stickers seen raised that lie on it, and those
    held up out of sight that lie on it or under where it lands."""
    up, out_of_sight = (frozenset(np.flatnonzero(m).tolist()) for m in (raised, held))
    if not up and not out_of_sight:
        return (), 1.0
    if any(up <= on and out_of_sight <= on | under for on, under in flaps):
        return (), 1.0
    return tuple(sorted(up | out_of_sight)), 0.0


def _place_factor(res: NDArray[np.float64]) -> tuple[float, tuple[int, ...]]:
    """The factor of the stickers' places (the largest residual against
    :data:`LONE_TOLERANCE_MM`, the second against :data:`PLACE_TOLERANCE_MM`) and the
    stickers beyond :data:`PLACE_TOLERANCE_MM` where it is 0."""
    d = np.sort(np.nan_to_num(res[np.isfinite(res)]))[::-1]
    if not len(d):
        return 1.0, ()
    # one sticker alone never rules the state out (a sticker misread, or half covered):
    # it halves the confidence at most
    factor = max(_ramp(float(d[0]), LONE_TOLERANCE_MM), LONE_FLOOR)
    if len(d) > 1:
        factor = min(factor, _ramp(float(d[1]), PLACE_TOLERANCE_MM))
    far = np.flatnonzero(np.nan_to_num(res) > PLACE_TOLERANCE_MM)
    return factor, tuple(int(i) for i in far) if factor == 0.0 else ()


def _size_factor(
    class_id: str,
    variant: str | None,
    folds: tuple[NominalFold, ...],
    creases: dict[int, tuple[float, float]],
    layout: NapkinLayout,
) -> tuple[float, tuple[str, ...]]:
    """The factor of the fitted folds' sizes (``creases``: fold index -> (normal angle,
    offset)) against the class's (see the module's description), and the folds beyond
    the slacks."""
    factor, out = 1.0, []
    scale = min(layout.fold_scale)  # (a diagonal's)
    for j, (a, c) in creases.items():
        word = folds[j].word
        sizes = fold_measures(word, Crease.from_normal(a, c), layout)
        kind, name = fold_kind(word)
        if kind == "corner":
            for edge, leg in sizes["legs_mm"].items():
                lo, hi = _CORNER_LEGS
                along = along_scale(layout, edge[0], edge[1])  # a leg scales with its edge
                mid, half = 0.5 * (lo + hi) * along, (0.5 * (hi - lo) + SIZE_SLACK_MM) * along
                off = math.inf if leg is None else abs(leg - mid)
                f = _ramp(off, half)
                factor = min(factor, f)
                if f == 0.0:
                    told = "misses it" if leg is None or leg < 0 else f"is {leg:.0f} mm"
                    out.append(
                        f"{word}: its leg along {edge} {told}, not {mid - half:.0f}-"
                        f"{mid + half:.0f} mm"
                    )
        elif kind == "side":
            inset, skew = sizes["inset_mm"], abs(sizes["skew_deg"])
            lo, hi = SIDE_INSET_RANGES["11" if class_id == "11" else "09"]
            k = CORNERS.index(name[1])
            across = along_scale(layout, name[1], CORNERS[(k + 1) % 4])  # an inset, across it
            mid, half = 0.5 * (lo + hi) * across, (0.5 * (hi - lo) + SIZE_SLACK_MM) * across
            f_skew = _ramp(skew, SKEW_SLACK_DEG)
            f_in = _ramp(math.inf if inset is None else abs(inset - mid), half)
            factor = min(factor, f_skew, f_in)
            if f_skew == 0.0:
                out.append(f"{word}: its crease runs {skew:.0f} degrees off its side")
            elif f_in == 0.0:
                out.append(
                    f"{word}: its crease lies {inset:.0f} mm in, not {mid - half:.0f}-"
                    f"{mid + half:.0f} mm"
                )
        else:
            off, turn = sizes["offset_mm"], abs(sizes["turn_deg"])
            f = min(
                _ramp(math.inf if off is None else abs(off), DIAGONAL_SLACK_MM * scale),
                _ramp(turn, DIAGONAL_TURN_DEG),
            )
            factor = min(factor, f)
            if f == 0.0:
                out.append(
                    f"{word}: its crease lies {abs(off or 0):.0f} mm and {turn:.0f} "
                    "degrees off the diagonal"
                )
    return factor, tuple(out)


def _predict(m: NDArray, g: NDArray, x: NDArray) -> NDArray:
    """Where the fit ``x`` (theta, tau, alpha_j, c_j...) puts material points ``m`` of
    parts ``g`` (-1 the napkin that stays), in the table plane (mm)."""
    rot, _ = rotation_2d(float(x[0]))
    if len(x) == 3:
        return m @ rot.T + x[1:3]
    on = g >= 0
    gi = np.where(on, g, 0)
    alpha, c = x[3::2], x[4::2]
    nrm = np.stack([np.cos(alpha[gi]), np.sin(alpha[gi])], axis=1) * on[:, None]
    s = np.sum(m * nrm, axis=1) - c[gi] * on
    return (m - 2.0 * s[:, None] * nrm) @ rot.T + x[1:3]


def _fit_parts(
    uv: NDArray, q: NDArray, part: NDArray, lying: NDArray[np.bool_],
    folds: tuple[NominalFold, ...],
) -> tuple[NDArray[np.float64], dict[int, tuple[float, float]]]:
    """Each sticker's residual (mm; NaN where not judged) under the state's fit, and the
    fitted creases (fold index -> (normal angle, offset)). With the napkin that stays
    placed (two stickers of it, or one and a flap of two, or three flaps) one joint
    fit, leaving out the worst sticker while it lies beyond :data:`PLACE_TOLERANCE_MM`
    and the rest still place every part; otherwise each part of three stickers or more
    on its own (a rigid map, mirrored for a flap)."""
    n = len(uv)
    res = np.full(n, np.nan)
    k = len(folds)
    counts = np.bincount(part[lying] + 1, minlength=k + 1)  # [0]: the napkin that stays
    active = [j for j in range(k) if counts[j + 1] > 0 and not folds[j].under]
    n_stay, big = int(counts[0]), sum(counts[j + 1] >= 2 for j in active)
    placed = n_stay >= 2 or (n_stay == 1 and big >= 1) or big >= 3
    if not placed:
        _fit_each_part(uv, q, part, lying, k, res)
        return res, {}
    lut = np.full(k + 1, -1)
    lut[active] = np.arange(len(active))
    fitted = np.zeros(k + 1, dtype=bool)
    fitted[active] = fitted[-1] = True
    judged = lying & fitted[part]
    use = judged.copy()
    x = None
    for _ in range(max(int(use.sum()) // 2, 1)):
        ids = np.flatnonzero(use)
        g = lut[part[ids]]
        if active:
            x0 = initial_flaps(uv[ids], q[ids], g, [folds[j] for j in active])
            x, _, _ = solve_flaps(uv[ids], q[ids], g, x0, len(active))
        else:  # no flap seen lying: the napkin that stays alone
            th, tau = rigid_fit_2d(uv[ids], q[ids])
            x = np.array([th, float(tau[0]), float(tau[1])])
        all_ids = np.flatnonzero(judged)
        d = np.linalg.norm(_predict(uv[all_ids], lut[part[all_ids]], x) - q[all_ids], axis=1)
        res[all_ids] = d
        inside = res[ids]
        worst = int(ids[np.argmax(inside)])
        if float(inside.max()) <= PLACE_TOLERANCE_MM:
            break
        # leave it out only where its part keeps what places it
        left = np.count_nonzero(use & (part == part[worst]))
        if left <= (2 if part[worst] < 0 else 1):
            break
        use[worst] = False
    creases = (
        {} if x is None
        else {j: (float(x[3 + 2 * i]), float(x[4 + 2 * i])) for i, j in enumerate(active)}
    )
    return res, creases


def _fit_each_part(
    uv: NDArray, q: NDArray, part: NDArray, lying: NDArray[np.bool_], k: int, res: NDArray
) -> None:
    """Each part's stickers (three or more) fitted by a rigid map of their own, mirrored
    for a flap (which shows its back face): residuals into ``res``."""
    for j in range(-1, k):
        ids = np.flatnonzero(lying & (part == j))
        if len(ids) < MIN_PART_STICKERS:
            continue
        m = uv[ids] * (np.array([1.0, -1.0]) if j >= 0 else 1.0)
        th, tau = rigid_fit_2d(m, q[ids])
        rot, _ = rotation_2d(th)
        res[ids] = np.linalg.norm(m @ rot.T + tau - q[ids], axis=1)


def _covered_depth(
    uv: NDArray,
    part: NDArray,
    folds: tuple[NominalFold, ...],
    creases: dict[int, tuple[float, float]],
    layout: NapkinLayout,
    airborne: NDArray[np.bool_],
) -> NDArray[np.float64]:
    """How far (mm, on the flat napkin) each sticker lies inside the place that a flap
    folded over later, and lying down (not ``airborne``), covers; -inf where none
    covers it. Where the sticker lies on the flat napkin (its own flap's fold undone),
    mirrored across a later fold's crease, is the flap's cloth that lands there."""
    out = np.full(len(uv), -np.inf)
    w, hgt = layout.width_mm, layout.height_mm
    lines = [creases.get(j) or _normal_form(f) for j, f in enumerate(folds)]
    q = uv.copy()  # each sticker's place on the flat napkin, its own fold undone
    for j in range(len(folds)):
        mine = part == j
        q[mine] = _reflect(uv[mine], lines[j])
    for j, f in enumerate(folds):
        later = part < j  # a flap folded later lies on the napkin and earlier flaps
        if f.under or airborne[j] or not later.any():
            continue
        back = _reflect(q[later], lines[j])  # the flap's cloth that lands there, if any
        a, c = lines[j]
        beyond = back[:, 0] * math.cos(a) + back[:, 1] * math.sin(a) - c
        depth = beyond if _flap_positive(f, lines[j]) else -beyond
        inside = np.minimum.reduce(
            [depth, back[:, 0], w - back[:, 0], back[:, 1], hgt - back[:, 1]]
        )
        out[later] = np.maximum(out[later], inside)
    return out


def _normal_form(f: NominalFold) -> tuple[float, float]:
    """A nominal fold's crease as (normal angle, offset)."""
    (x0, y0), (x1, y1) = f.p0, f.p1
    alpha = math.atan2(x1 - x0, -(y1 - y0))
    return alpha, math.cos(alpha) * x0 + math.sin(alpha) * y0


def _flap_positive(f: NominalFold, line: tuple[float, float]) -> bool:
    """Whether the flap lies on the positive side of ``line`` (n . x > c)."""
    a, c = line
    return f.flap[0] * math.cos(a) + f.flap[1] * math.sin(a) - c > 0


def _reflect(q: NDArray, line: tuple[float, float]) -> NDArray:
    """Points (k, 2) mirrored across the line (normal angle, offset)."""
    a, c = line
    nrm = np.array([math.cos(a), math.sin(a)])
    return q - 2.0 * (q @ nrm - c)[:, None] * nrm
