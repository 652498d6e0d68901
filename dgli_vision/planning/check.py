"""The closed-loop check: render a state, classify it, plan, make the planned
pick-and-place in the simulator, render again and classify.

For every start state (class and variant) and every goal within ``max_steps`` folds,
``per_pair`` times: a state of the start is drawn and rendered (a random camera that sees
the napkin whole even unfolded, random lighting, sensor noise), classified and planned
for; the first step is carried out on the simulated cloth: a fold about the planned fold
line (the perpendicular bisector of grasp -> place, taken from the camera frame to the
table and onto the flat napkin), or the unfold of the planned flap. The cloth is
rendered again from the same camera and classified; the step succeeds when the verdict
is the state the plan expected.

For a fold, the step's crease is also checked against the plan (``crease_mm`` of the
step, on the flat napkin): the crease **made** (the fold the simulator carried out, as
the planned fold line lands on the cloth) and the crease **seen** (the after frame's
fold geometry, as ``dgli verify`` measures it) are each compared with the planned one:
the crease's distance (the largest of either's ends on the napkin from the other) and,
for a corner, the distance of its tip from the planned tip. A fold step succeeds at a
tolerance when the state is the expected one and both errors are within it
(:data:`TOLERANCES_MM`).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from ..classifier.pipeline import classify_frame
from ..classifier.references import ReferenceSet
from ..core.camera import DEFAULT_INTRINSICS, Intrinsics
from ..core.classes import CORNERS
from ..core.fold_graph import StateKey, state_keys
from ..core.fold_measure import Crease, crease_distance_mm, fold_kind, fold_measures
from ..core.frame import RGBDFrame
from ..core.layout import NapkinLayout, default_layout
from ..sim.cloth.states import FoldStep, draw_fold_steps, make_state
from ..sim.dataset import random_camera
from ..sim.render import Lighting, SensorModel, render
from .api import plan_frame
from .plan import PlanRefused, PlanStep, shortest_path

__all__ = [
    "OUTCOMES",
    "TOLERANCES_MM",
    "CheckRow",
    "check_count",
    "check_pairs",
    "check_table",
    "fold_errors",
    "geometry_table",
    "goals_within",
    "run_pair",
]

#: What can happen to one (start, goal) pair.
OUTCOMES = ("right", "cannot tell", "refused", "wrong")
#: The tolerances (mm) at which the fold steps' success rates are given: 45 mm is the
#: simulation benchmarks' per-point success, 20 mm ``dgli verify``'s default.
TOLERANCES_MM = (10.0, 20.0, 45.0)


def goals_within(start: StateKey, max_steps: int) -> list[tuple[StateKey, int]]:
    """Every state 1 to ``max_steps`` folds or unfolds from ``start``, with its
    distance, in state order."""
    out = []
    for key in state_keys():
        if key == start:
            continue
        try:
            n = len(shortest_path(start, key))
        except PlanRefused:
            continue
        if n <= max_steps:
            out.append((key, n))
    return out


@dataclass(frozen=True)
class CheckRow:
    """One trial: the start, the goal, what the start was read as, the step planned,
    the state that came out and the outcome (one of :data:`OUTCOMES`), with the reason
    for a "cannot tell" or a refusal; for a fold step carried out, ``geometry`` (see
    :func:`fold_errors`)."""

    start: StateKey
    goal: StateKey
    steps: int
    seen: StateKey | None
    expect: StateKey | None
    after: StateKey | None
    outcome: str
    note: str = ""
    geometry: dict[str, object] | None = None


def _placement(rng: np.random.Generator) -> tuple[float, float, tuple[float, float]]:
    """Wrinkle amplitude (mm), yaw (rad) and centre (m) as :func:`sample_state` draws."""
    wrinkle = float(rng.uniform(0, 8))
    yaw = float(rng.uniform(0, 2 * np.pi))
    offset = tuple(float(v) for v in rng.uniform(-0.05, 0.05, size=2))
    return wrinkle, yaw, offset  # type: ignore[return-value]


def _to_material(points_world: np.ndarray, yaw: float, offset: tuple, layout: NapkinLayout):
    """World xy (k, 3) -> material mm (k, 2) of the napkin that stays (the inverse of
    :func:`~dgli_vision.sim.cloth.states.make_state`'s placement)."""
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.array([[c, -s], [s, c]])
    centre = np.array([layout.width_mm, layout.height_mm]) * 0.5e-3
    return ((points_world[:, :2] - np.asarray(offset)) @ rot + centre) * 1e3


def _executed_steps(
    step: PlanStep,
    steps: list[FoldStep],
    words: list[str],
    pose,
    yaw: float,
    offset: tuple,
    layout: NapkinLayout,
) -> list[FoldStep] | None:
    """The cloth's folds once the planned step is made; None when the step undoes a
    fold the cloth does not have (the start was misread)."""
    if step.action == "unfold":
        if step.fold not in words:
            return None
        k = words.index(step.fold)
        return steps[:k] + steps[k + 1 :]
    ends = pose.camera_to_world(np.asarray(step.fold_line, dtype=float))
    a, b = _to_material(ends, yaw, offset, layout)
    mid, along = 0.5 * (a + b), (b - a) / np.linalg.norm(b - a)
    if step.corner:
        flap = layout.corner_uv[CORNERS.index(step.corner)]
    else:
        x, y = (layout.corner_uv[CORNERS.index(c)] for c in step.side or "")
        flap = 0.5 * (x + y)
    new = FoldStep(
        tuple(mid - 40.0 * along), tuple(mid + 40.0 * along), tuple(float(v) for v in flap),
        step.under,
    )
    return [*steps, new]


def _crease_errors(
    word: str, planned: Crease, crease: Crease, layout: NapkinLayout
) -> dict[str, float | None]:
    """``{"crease_mm", "tip_mm"}`` of a crease against the planned one (the tip: a
    corner fold's, else None)."""
    out: dict[str, float | None] = {
        "crease_mm": crease_distance_mm(crease, planned, layout), "tip_mm": None,
    }
    if fold_kind(word)[0] == "corner":
        a = fold_measures(word, crease, layout)["tip_mm"]
        b = fold_measures(word, planned, layout)["tip_mm"]
        out["tip_mm"] = float(np.hypot(a[0] - b[0], a[1] - b[1]))
    return out


def fold_errors(
    word: str,
    planned: Crease,
    made: Crease,
    seen: object | None,
    layout: NapkinLayout,
    why: str | None = None,
) -> dict[str, object]:
    """A fold step's crease against the plan.

    Parameters
    ----------
    word : str
        The fold word.
    planned : Crease
        The step's planned crease (material mm).
    made : Crease
        The crease the fold was made along.
    seen : FoldGeometry or None
        The fold's geometry measured on the frame after it (None: not measured, see
        ``why``; a geometry whose ``why`` is set is not measured either).
    layout : NapkinLayout
    why : str, optional
        Why ``seen`` is None.

    Returns
    -------
    dict
        ``{"fold", "made": {"crease_mm", "tip_mm"}, "seen": {...} or None, "why",
        "measure_mm"}``: the errors (mm) of the crease made and of the crease seen
        against the plan, why the crease was not seen, and how far the crease seen lies
        from the one made (the measurement's own error).
    """
    out: dict[str, object] = {
        "fold": word, "made": _crease_errors(word, planned, made, layout), "seen": None,
        "why": why, "measure_mm": None,
    }
    crease = getattr(seen, "crease", None)
    if seen is not None and getattr(seen, "why", None) is None and crease is not None:
        out["seen"] = _crease_errors(word, planned, crease, layout)
        out["measure_mm"] = crease_distance_mm(crease, made, layout)
    elif seen is not None:
        out["why"] = getattr(seen, "why", None) or "not measured"
    return out


def _frame(r) -> RGBDFrame:
    return RGBDFrame(r.color, r.depth_mm, r.intrinsics, "<render>", "<render>", "given")


def _verdict(result) -> StateKey | None:
    p = result.prediction
    return None if p is None else (p.class_id, p.variant)


def run_pair(
    start: StateKey,
    goal: StateKey,
    seed: tuple[int, ...],
    references: ReferenceSet,
    *,
    intrinsics: Intrinsics = DEFAULT_INTRINSICS,
    layout: NapkinLayout | None = None,
) -> CheckRow:
    """One trial of the closed loop (see the module's description)."""
    layout = layout or default_layout()
    rng = np.random.default_rng(list(seed))
    steps, params = draw_fold_steps(start[0], start[1], layout, rng)
    words = list(params["folds"])
    wrinkle, yaw, offset = _placement(rng)
    wrinkle_seed = int(rng.integers(2**31))
    n = len(shortest_path(start, goal))

    def state(key: StateKey, folds: list[FoldStep]):
        return make_state(
            key[0], key[1], folds, layout=layout, wrinkle_mm=wrinkle, yaw=yaw, offset_m=offset,
            rng=wrinkle_seed, params=dict(params),
        )

    flat = state(("01", None), [])
    pose, _ = random_camera(flat, rng, intrinsics=intrinsics)
    lighting = Lighting.random(rng)
    before = render(state(start, steps), pose, intrinsics=intrinsics, lighting=lighting,
                    sensor=SensorModel(), rng=rng, layout=layout)
    frame = _frame(before)
    result = classify_frame(frame, references, layout=layout)
    seen = _verdict(result)
    if seen is None:
        return CheckRow(start, goal, n, None, None, None, "cannot tell", result.reason or "")
    try:
        plan = plan_frame(result, frame, goal, layout)
    except PlanRefused as exc:
        return CheckRow(start, goal, n, seen, None, None, "refused", str(exc))
    step = plan.steps[0]
    folds = _executed_steps(step, steps, words, pose, yaw, offset, layout)
    if folds is None:
        return CheckRow(start, goal, n, seen, step.expect, None, "wrong", "unfolded a fold "
                        "the cloth does not have")
    after = render(state(step.expect, folds), pose, intrinsics=intrinsics, lighting=lighting,
                   sensor=SensorModel(), rng=rng, layout=layout)
    verdict = classify_frame(_frame(after), references, layout=layout)
    got = _verdict(verdict)
    geometry = None
    if step.action == "fold" and step.crease_mm is not None:
        made = Crease.through(folds[-1].p0, folds[-1].p1)
        p = verdict.prediction
        mine = None if p is None else next((f for f in p.folds if f.fold == step.fold), None)
        why = None
        if got is None:
            why = "the state after the fold cannot be told"
        elif got != step.expect:
            why = f"the state after the fold was read as {_txt(got)}"
        elif mine is None or mine.geometry is None:
            why = "not measured"
        geometry = fold_errors(step.fold, Crease.through(*step.crease_mm), made,
                               mine.geometry if why is None and mine else None, layout, why)
    if got is None:
        return CheckRow(start, goal, n, seen, step.expect, None, "cannot tell",
                        verdict.reason or "", geometry)
    outcome = "right" if got == step.expect and seen == start else "wrong"
    return CheckRow(start, goal, n, seen, step.expect, got, outcome, geometry=geometry)


def check_count(
    *,
    per_pair: int = 1,
    max_steps: int = 3,
    starts: list[StateKey] | None = None,
    limit: int | None = None,
) -> int:
    """How many trials :func:`check_pairs` runs with the same arguments (for a progress
    bar)."""
    count = kept = 0
    for start in starts or list(state_keys()):
        for _goal, _ in goals_within(start, max_steps):
            count += 1
            kept += limit is None or count % limit == 0
    return kept * per_pair


def check_pairs(
    references: ReferenceSet,
    *,
    per_pair: int = 1,
    seed: int = 0,
    max_steps: int = 3,
    starts: list[StateKey] | None = None,
    intrinsics: Intrinsics = DEFAULT_INTRINSICS,
    limit: int | None = None,
    on_row: Callable[[CheckRow], None] | None = None,
) -> Iterator[CheckRow]:
    """Every (start, goal within ``max_steps``) pair, ``per_pair`` times, each trial
    drawn from ``(seed, start, goal, k)``; ``limit`` keeps every ``limit``-th pair only
    (a small version of the check, spread over all starts)."""
    keys = state_keys()
    count = 0
    for start in starts or list(keys):
        for goal, _ in goals_within(start, max_steps):
            count += 1
            if limit is not None and count % limit:
                continue
            for k in range(per_pair):
                row = run_pair(
                    start, goal, (seed, keys.index(start), keys.index(goal), k, 41),
                    references, intrinsics=intrinsics,
                )
                if on_row is not None:
                    on_row(row)
                yield row


def _spread(values: list[float]) -> dict[str, float | None]:
    """Median, 90th percentile and largest of ``values`` (mm, one decimal)."""
    if not values:
        return {"median": None, "p90": None, "max": None}
    v = np.asarray(values, dtype=float)
    return {k: round(float(np.quantile(v, q)), 1)
            for k, q in (("median", 0.5), ("p90", 0.9), ("max", 1.0))}


def _within(e: dict[str, float | None] | None, tol: float) -> bool:
    """Both errors (crease, tip) known where they apply and within ``tol``."""
    if e is None or e["crease_mm"] is None:
        return False
    return e["crease_mm"] <= tol and (e["tip_mm"] is None or e["tip_mm"] <= tol)


def geometry_table(rows: list[CheckRow]) -> dict[str, object]:
    """The fold steps' geometry against the plan: the crease and tip errors of the
    creases made and seen (median, p90, max, mm), the share of fold steps that succeed
    at each of :data:`TOLERANCES_MM` (crease and tip within it; for the crease seen,
    also the expected state read and the fold measured), the folds not measured (and
    why) and the measurement's own error (the crease seen against the crease made)."""
    g = [r for r in rows if r.geometry is not None]
    n = len(g)
    out: dict[str, object] = {"fold_steps": n}
    for which in ("made", "seen"):
        errs = [r.geometry[which] for r in g if r.geometry[which] is not None]
        out[which] = {
            "measured": len(errs),
            "crease_mm": _spread([e["crease_mm"] for e in errs if e["crease_mm"] is not None]),
            "tip_mm": _spread([e["tip_mm"] for e in errs if e["tip_mm"] is not None]),
            "success": {
                f"{tol:g}": round(sum(_within(r.geometry[which], tol) for r in g) / n, 4)
                if n else None
                for tol in TOLERANCES_MM
            },
        }
    out["not_seen"] = dict(Counter(str(r.geometry["why"]) for r in g
                                   if r.geometry["seen"] is None))
    out["measure_mm"] = _spread([r.geometry["measure_mm"] for r in g
                                 if r.geometry["measure_mm"] is not None])
    return out


def check_table(rows: list[CheckRow]) -> dict[str, object]:
    """The success table: outcomes by number of steps to the goal and in all, the
    trials that were not right, and the fold steps' geometry (:func:`geometry_table`)."""
    by_steps: dict[int, Counter] = {}
    for r in rows:
        by_steps.setdefault(r.steps, Counter())[r.outcome] += 1
    total = Counter(r.outcome for r in rows)
    return {
        "pairs": len(rows),
        "outcomes": {o: total.get(o, 0) for o in OUTCOMES},
        "success": round(total.get("right", 0) / len(rows), 4) if rows else None,
        "by_steps": {
            str(n): {o: c.get(o, 0) for o in OUTCOMES} for n, c in sorted(by_steps.items())
        },
        "not_right": [
            {
                "start": _txt(r.start), "goal": _txt(r.goal), "seen": _txt(r.seen),
                "expect": _txt(r.expect), "after": _txt(r.after), "outcome": r.outcome,
                "note": r.note,
            }
            for r in rows
            if r.outcome != "right"
        ],
        "geometry": geometry_table(rows),
    }


def _txt(key: StateKey | None) -> str | None:
    if key is None:
        return None
    return f"{key[0]}/{key[1]}" if key[1] else key[0]
