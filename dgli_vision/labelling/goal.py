"""``dgli label --goal STATE[:SIZES]``: did an episode end in its goal, by the simulation
benchmarks' measure and by ours?

- **The benchmarks' measure** (SoftGym's and its forks'): every vertex of the episode's
  last frame against the goal's ideal folded configuration (the flat cloth of the rest
  frame, each flap mirrored across its planned crease,
  :func:`~.fold_mesh.goal_distance`); success when the largest distance is within
  :data:`ONE_FOLD_MM` (45 mm) for a goal of one fold, :data:`CROSS_FOLD_MM` (75 mm) for
  a goal of several ("cross folds").
- **Ours**: the last frame's smoothed state is the goal, and every fold's crease (from
  the mesh, :mod:`.fold_measure`) lies within :data:`TOLERANCE_MM` of the planned one,
  with the corner's tip within it too (``dgli verify``'s rule).

The planned creases are the goal's nominal folds (the middle of its class's sizes),
unless sizes are given: ``02:AB=180,BC=180`` (a corner's legs, which also name the
corner), ``09/CD:inset=130``, ``12/B:offset=10``, ``02/B:tip=200,200``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.classes import VARIANTS
from ..core.errors import InvalidInputError, InvalidValueError
from ..core.fold_graph import StateKey
from ..core.fold_lines import nominal_folds
from ..core.fold_measure import Crease, crease_distance_mm, fold_kind, fold_measures
from ..core.fold_measure import planned_crease as _planned
from ..core.layout import NapkinLayout
from .fold_mesh import goal_distance

__all__ = ["CROSS_FOLD_MM", "ONE_FOLD_MM", "TOLERANCE_MM", "GoalSpec", "evaluate_goal",
           "parse_goal"]

#: The benchmarks' success: every vertex within this of the goal (mm), one fold ...
ONE_FOLD_MM = 45.0
#: ... and for a goal of two or more folds (their cross folds: 70-80 mm).
CROSS_FOLD_MM = 75.0
#: Our success: each crease and tip within this of the planned one (mm).
TOLERANCE_MM = 20.0


@dataclass(frozen=True)
class GoalSpec:
    """A goal: its state (the variant may be None: the one the episode ends in) and the
    planned sizes of its fold, if given."""

    text: str
    class_id: str
    variant: str | None
    legs: dict[str, float] | None = None
    inset_mm: float | None = None
    offset_mm: float | None = None
    tip_mm: tuple[float, float] | None = None


def parse_goal(text: str) -> GoalSpec:
    """``STATE[:SIZES]`` (see the module's description).

    Raises
    ------
    InvalidInputError
        With what is wrong.
    """
    from ..planning.plan import parse_state
    from ..planning.verify import parse_legs

    state, _, sizes = text.strip().partition(":")
    try:
        cls, variant = parse_state(state, need_variant=False)
    except ValueError as exc:
        raise InvalidInputError(f"--goal {text!r}: {exc}") from None
    spec: dict[str, Any] = {}
    sizes = sizes.strip()
    try:
        if not sizes:
            pass
        elif sizes.lower().startswith(("inset=", "offset=", "tip=")):
            key, _, value = sizes.partition("=")
            key = key.lower()
            if key == "tip":
                u, v = (float(x) for x in value.split(","))
                spec["tip_mm"] = (u, v)
            else:
                spec[f"{key}_mm"] = float(value)
            if not all(math.isfinite(float(x)) for x in value.split(",")):
                raise InvalidValueError(f"{value!r} is not a number of mm")
        else:
            spec["legs"] = parse_legs(sizes)
    except ValueError as exc:
        raise InvalidInputError(f"--goal {text!r}: {exc}") from None
    kinds = {fold_kind(w)[0] for w in _words(cls, variant)}
    need = {"legs": "corner", "tip_mm": "corner", "inset_mm": "side", "offset_mm": "diagonal"}
    for key in spec:
        if need[key] not in kinds:
            raise InvalidInputError(
                f"--goal {text!r}: class {cls} has no {need[key]} fold for {key.split('_')[0]}"
            )
    if "legs" in spec:
        first, second = spec["legs"]
        corner = (set(first) & set(second)).pop()
        if variant is None and cls in ("02", "03"):
            variant = corner
        elif variant is not None and corner not in variant:
            raise InvalidInputError(f"--goal {text!r}: the legs' corner {corner} is not "
                                    f"folded in {cls}/{variant}")
    return GoalSpec(text, cls, variant, **spec)


def _words(cls: str, variant: str | None) -> list[str]:
    """The fold words of a class (any variant: the first)."""
    from ..core.fold_graph import folds_of

    v = variant if variant is not None else VARIANTS[cls][0]
    return sorted(folds_of(cls, v))


def _creases(
    goal: GoalSpec, key: StateKey, layout: NapkinLayout
) -> list[tuple[str, Crease, tuple[float, float]]]:
    """The goal's folds in the order they are made: word, planned crease, flap point."""
    out = []
    for f in nominal_folds(key[0], key[1], layout):
        crease = Crease.through(f.p0, f.p1)
        kind, name = fold_kind(f.word)
        sized = None
        if kind == "corner" and goal.legs and name in "".join(goal.legs):
            first, second = goal.legs
            if name in set(first) & set(second):
                sized = _planned(f.word, layout, legs=goal.legs)
        elif kind == "corner" and goal.tip_mm is not None:
            sized = _planned(f.word, layout, tip_mm=goal.tip_mm)
        elif kind == "side" and goal.inset_mm is not None:
            sized = _planned(f.word, layout, inset_mm=goal.inset_mm)
        elif kind == "diagonal" and goal.offset_mm is not None:
            sized = _planned(f.word, layout, offset_mm=goal.offset_mm)
        out.append((f.word, sized or crease, f.flap))
    return out


def _name(key: StateKey) -> str:
    return f"{key[0]}/{key[1]}" if key[1] else key[0]


def evaluate_goal(
    goal: GoalSpec,
    smoothed: StateKey,
    folds: list[Any],
    position: NDArray[np.float64],
    rest: NDArray[np.float64],
    uv: NDArray[np.float64],
    layout: NapkinLayout,
) -> dict[str, Any]:
    """The goal against an episode's last frame.

    Parameters
    ----------
    goal : GoalSpec
    smoothed : StateKey
        The last frame's smoothed state.
    folds : list of FoldGeometry
        The last frame's folds measured on the mesh (of its state).
    position, rest : ndarray, shape (N, 3)
        The last frame and the flat cloth, metres, z up.
    uv : ndarray, shape (N, 2)
        Material coordinates, mm.
    layout : NapkinLayout

    Returns
    -------
    dict
        ``{"goal", "spec", "softgym": {"max_distance_mm", "mean_distance_mm",
        "threshold_mm", "success"}, "dgli": {"state", "success", "folds", "reasons",
        "tolerance_mm"}}``.
    """
    variant = goal.variant
    if variant is None:
        variant = smoothed[1] if smoothed[0] == goal.class_id else VARIANTS[goal.class_id][0]
    key = (goal.class_id, variant)
    planned = _creases(goal, key, layout)
    d = goal_distance(position, rest, uv, [(c, flap) for _, c, flap in planned])
    threshold = ONE_FOLD_MM if len(planned) <= 1 else CROSS_FOLD_MM
    reasons: list[str] = []
    rows = []
    success: bool | None = True
    if smoothed != key:
        success = False
        reasons.append(f"the episode ends in {_name(smoothed)}, not {_name(key)}")
    seen = {g.word: g for g in folds}
    for word, crease, _ in planned:
        g = seen.get(word)
        row: dict[str, Any] = {"fold": word, "planned_crease_mm": crease.ends_in(layout),
                               "crease_mm": None, "tip_mm": None}
        rows.append(row)
        if success is False and g is None:
            continue
        if g is None or g.crease is None:
            if success:
                success = None
            reasons.append(f"{word}: not measured ({g.why if g else 'not in the state'})")
            continue
        row["crease_mm"] = crease_distance_mm(g.crease, crease, layout)
        if fold_kind(word)[0] == "corner":
            a = fold_measures(word, g.crease, layout)["tip_mm"]
            b = fold_measures(word, crease, layout)["tip_mm"]
            row["tip_mm"] = math.dist(a, b)
        for what in ("crease_mm", "tip_mm"):
            if row[what] is not None and row[what] > TOLERANCE_MM:
                success = False
                reasons.append(f"{word}: {what.split('_')[0]} {row[what]:.0f} mm off the "
                               "planned one")

    def r1(v: Any) -> Any:
        if isinstance(v, list):
            return [r1(x) for x in v]
        return None if v is None else round(float(v), 1)

    return {
        "goal": _name(key),
        "spec": goal.text,
        "softgym": {
            "max_distance_mm": r1(d["max_mm"]),
            "mean_distance_mm": r1(d["mean_mm"]),
            "threshold_mm": threshold,
            "success": bool(d["max_mm"] <= threshold),
        },
        "dgli": {
            "state": _name(smoothed),
            "success": success,
            "folds": [{k: r1(v) if k != "fold" else v for k, v in r.items()} for r in rows],
            "reasons": reasons,
            "tolerance_mm": TOLERANCE_MM,
        },
    }
