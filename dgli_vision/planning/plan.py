"""The shortest sequence of folds and unfolds to a goal state, as pick-and-place steps.

The fold graph (:mod:`dgli_vision.core.fold_graph`) says which states are one fold or
one unfold apart; a breadth-first search over it gives a shortest sequence. Each step is
a pick-and-place in the camera frame of the image: grasp the corner (or the middle of
the side) where it lies, carry it over the fold line and put it down where the fold
lays it (its mirror image across the line); an unfold carries it back to its flat place.
The fold lines are the goal class's (the middle of its size ranges, scaled with the
napkin; :mod:`dgli_vision.core.fold_lines`), placed on the napkin by the rigid maps the
affordances are fitted with.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..classifier.affordances import (
    Affordances,
    NapkinMaps,
    bisector_through,
    fold_line_3d,
)
from ..core.classes import CLASS_HINT, CORNERS, VARIANTS, class_id_of, digits_note
from ..core.errors import InvalidValueError, PlanRefused
from ..core.fold_graph import StateKey, fold_edges, folds_of
from ..core.fold_lines import NominalFold, fold_for_word, reflect_uv
from ..core.layout import NapkinLayout
from .motion import DEFAULT_MOTION, Hand, MotionParams, hands_motion

__all__ = [
    "LIFT_CLEARANCE_M",
    "Plan",
    "PlanRefused",
    "PlanStep",
    "parse_state",
    "plan_geometry",
    "plan_steps",
    "shortest_path",
]

#: The lift height before plans carried their hands' paths: the grasped point's distance
#: from the fold line plus this, m. Kept for code that used it; a step's ``lift_height``
#: is now its first hand's path's highest point (:mod:`.motion`).
LIFT_CLEARANCE_M = 0.02


def parse_state(text: str, *, need_variant: bool = True) -> StateKey:
    """A state written as ``08``, ``02/A`` or ``05/AB/B``; the class also as ``8`` or
    ``four-corners-centre`` (:func:`~dgli_vision.core.classes.class_id_of`).

    With ``need_variant`` False a class with variants may be given alone (the variant
    is then None, meaning any).

    Raises
    ------
    InvalidValueError
        An unknown class or variant (the message says which ones there are).
    """
    written, _, variant = text.strip().partition("/")
    cls = class_id_of(written)
    if cls is None:
        raise InvalidValueError(f"unknown class {written!r}{digits_note(written)}; "
                                f"expected {CLASS_HINT}")
    options = VARIANTS[cls]
    if not variant:
        if options == (None,) or not need_variant:
            return cls, None
        raise InvalidValueError(
            f"class {cls} needs a variant: one of {', '.join(f'{cls}/{v}' for v in options)}"
        )
    if options == (None,):
        raise InvalidValueError(
            f"class {cls} has no variant; write it as {cls} (not {cls}/{variant})"
        )
    if variant not in options:
        shown = ", ".join(f"{cls}/{v}" for v in options)
        raise InvalidValueError(f"class {cls} has no variant {variant!r}; it has {shown}")
    return cls, variant


def _moves(key: StateKey) -> list[tuple[str, str, StateKey]]:
    """(action, fold word, next state) from ``key``, in a fixed order: unfolds first,
    so that of two equally short plans the one through fewer folds at once is taken
    (a fourth corner folded onto three smaller flaps leaves more table covered than the
    four-corner state allows)."""
    out = [("unfold", w, a) for a, b, w in fold_edges() if b == key]
    out += [("fold", w, b) for a, b, w in fold_edges() if a == key]
    return out


def _crossable(start: StateKey) -> frozenset[str]:
    """The flaps of ``start`` that a crossing fold can lie over: the first flap of two
    crossing ones (class 05) is folded with the crossing class's longer legs; a corner
    of any other class is too small for a second flap to cross it."""
    if start[0] != "05" or start[1] is None:
        return frozenset()
    side, top = start[1].split("/")
    return frozenset(side.replace(top, ""))


def _tips_would_cross(here: StateKey, corner: str, big: frozenset[str]) -> bool:
    """Folding ``corner`` (not across another flap) next to a folded neighbour lays the
    two tips across each other when either flap has the crossing class's size: the
    state would not be the one of two flaps apart."""
    k = CORNERS.index(corner)
    folded = {w.split(" ")[0] for w in folds_of(*here) if " over" in w}
    for n in (CORNERS[(k + 1) % 4], CORNERS[(k - 1) % 4]):
        if n in folded and (n in big or corner in big):
            return True
    return False


def shortest_path(start: StateKey, goal: StateKey) -> list[tuple[str, str, StateKey]]:
    """A shortest sequence of (action, fold word, state after) from ``start`` to
    ``goal`` (breadth-first over the fold graph; among equals, the first in state
    order). A goal given without its variant (None for a class that has variants) is
    the nearest state of that class.

    A flap crosses another (class 05) only where that other flap has the crossing
    class's size: folded by the plan towards a goal of class 05, or the first flap of a
    05 start; a smaller flap is unfolded and folded again first.

    Raises
    ------
    PlanRefused
        When no sequence of single folds and unfolds reaches the goal.
    """
    any_variant = goal[1] is None and VARIANTS[goal[0]] != (None,)
    big_folds = goal[0] == "05"

    def done(k: StateKey) -> bool:
        return k[0] == goal[0] if any_variant else k == goal

    Node = tuple[StateKey, frozenset[str]]
    first: Node = (start, _crossable(start))
    came: dict[Node, tuple[Node, str, str] | None] = {first: None}
    queue = deque([first])
    while queue:
        node = queue.popleft()
        here, big = node
        if done(here):
            path = []
            while came[node] is not None:
                prev, action, word = came[node]  # type: ignore[misc]
                path.append((action, word, node[0]))
                node = prev
            return path[::-1]
        for action, word, nxt in _moves(here):
            corner = word.split(" ")[0]
            if action == "fold" and " crossing " in word and word.split()[-1] not in big:
                continue
            if action == "fold" and word.endswith(" over") and len(corner) == 1:
                grown = big | {corner} if big_folds else big
                if _tips_would_cross(here, corner, grown):
                    continue
            elif action == "unfold":
                grown = big - {corner}
            else:
                grown = big
            child = (nxt, grown)
            if child not in came:
                came[child] = (node, action, word)
                queue.append(child)
    shown = f"{goal[0]}/{goal[1]}" if goal[1] else goal[0]
    raise PlanRefused(f"no sequence of single folds leads from {_name(start)} to {shown}")


def _name(key: StateKey) -> str:
    return f"{key[0]}/{key[1]}" if key[1] else key[0]


@dataclass(frozen=True)
class PlanStep:
    """One step of a plan.

    Attributes
    ----------
    action : str
        ``"fold"`` or ``"unfold"``.
    fold : str
        The fold word made or undone (``"B over"``, ``"AB half"``...).
    corner, side : str or None
        The corner or the side grasped.
    under : bool
        The flap goes beneath the napkin (or comes out from beneath it).
    expect : tuple of (str, str or None)
        The state after the step.
    grasp_point, place_point : tuple of float or None
        Camera frame, metres (None when planned without an image).
    grasp_pixel : tuple of float or None
    fold_line : tuple of two points or None
        The fold line on the table, camera frame, metres.
    lift_height : float or None
        How high the first hand lifts the grasped point above the table (its path's
        highest point), metres.
    crease_mm : tuple of two (u, v) points or None
        A fold's planned crease on the flat napkin (material mm): what ``dgli verify``
        and ``dgli plan --verify`` check the fold made against.
    hands : tuple of Hand
        The motion per hand (:mod:`.motion`): one for a corner or a diagonal fold, two
        (the side's corners) for a strip or a half fold; ``grasp_point``,
        ``place_point``, ``grasp_pixel`` and ``lift_height`` are the first hand's.
        Empty when planned without an image.
    """

    action: str
    fold: str
    corner: str | None
    side: str | None
    under: bool
    expect: StateKey
    grasp_point: tuple[float, float, float] | None = None
    grasp_pixel: tuple[float, float] | None = None
    place_point: tuple[float, float, float] | None = None
    fold_line: tuple[tuple[float, ...], tuple[float, ...]] | None = None
    lift_height: float | None = None
    crease_mm: tuple[tuple[float, float], tuple[float, float]] | None = None
    hands: tuple[Hand, ...] = ()

    def target(self, layout: NapkinLayout) -> dict[str, Any] | None:
        """A fold's planned sizes (legs and tip, inset and skew, offset and turn:
        :func:`~dgli_vision.core.fold_measure.fold_measures`), None for an unfold."""
        if self.crease_mm is None:
            return None
        from ..core.fold_measure import Crease, fold_measures

        return fold_measures(self.fold, Crease.through(*self.crease_mm), layout)

    def to_json(self) -> dict[str, Any]:
        """The JSON form of a step (see docs/planning.md)."""

        def pt(p: Any, nd: int = 5) -> Any:
            return None if p is None else [round(float(v), nd) for v in p]

        out: dict[str, Any] = {"action": self.action, "fold": self.fold}
        out["corner" if self.corner else "side"] = self.corner or self.side
        out.update(
            {
                "under": self.under,
                "grasp": {"point": pt(self.grasp_point), "pixel": pt(self.grasp_pixel, 1)},
                "place": {"point": pt(self.place_point)},
                "fold_line": None
                if self.fold_line is None
                else [pt(p) for p in self.fold_line],
                "lift_height": None if self.lift_height is None else round(self.lift_height, 4),
                "expect": {"class": self.expect[0], "variant": self.expect[1]},
                "crease_mm": None if self.crease_mm is None
                else [pt(p, 1) for p in self.crease_mm],
                "n_hands": len(self.hands),
                "hands": [h.to_json() for h in self.hands],
            }
        )
        return out


@dataclass(frozen=True)
class Plan:
    """A plan: the state it starts from, the goal, and the steps (empty: already
    there)."""

    start: StateKey
    goal: StateKey
    steps: tuple[PlanStep, ...]

    def to_json(self) -> dict[str, Any]:
        """``{"from": {"class", "variant"}, "goal": {...}, "steps": [...]}``."""
        return {
            "from": {"class": self.start[0], "variant": self.start[1]},
            "goal": {"class": self.goal[0], "variant": self.goal[1]},
            "steps": [s.to_json() for s in self.steps],
        }


def _step_fold(action: str, word: str, before: StateKey, after: StateKey, goal: StateKey,
               layout: NapkinLayout, current: tuple[NominalFold, ...]) -> NominalFold:
    """The fold line of a step: an unfold undoes the fold as it is; a fold takes the
    goal class's sizes when the goal keeps that fold (brought into the range of the
    state after the step, but for two crossing flaps, which need their own), else those
    of the state after."""
    if action == "unfold":
        return next(f for f in current if f.word == word)
    kept = word in folds_of(*goal)
    sized = goal if kept else after
    side = sized[1].split("/")[0] if sized[0] in ("04", "05") and sized[1] else None
    within = after[0] if kept and goal[0] != "05" else None
    return fold_for_word(word, sized[0], layout, side, within)


def plan_steps(
    start: StateKey, goal: StateKey, layout: NapkinLayout
) -> tuple[list[tuple[str, str, StateKey]], list[NominalFold]]:
    """The path and each step's nominal fold line (in the flat napkin's frame)."""
    from ..core.fold_lines import nominal_folds

    path = shortest_path(start, goal)
    current = list(nominal_folds(*start, layout))
    lines = []
    here = start
    final = path[-1][2] if path else start
    for action, word, after in path:
        f = _step_fold(action, word, here, after, final, layout, tuple(current))
        lines.append(f)
        if action == "fold":
            current.append(f)
        else:
            current = [g for g in current if g.word != word]
        here = after
    return path, lines


def plan_geometry(
    start: StateKey,
    goal: StateKey,
    layout: NapkinLayout,
    maps: NapkinMaps | None,
    affordances: Affordances | None,
    intrinsics: Any | None,
    *,
    motion: MotionParams = DEFAULT_MOTION,
) -> Plan:
    """The plan from ``start`` to ``goal``, each step placed in the camera frame when
    ``maps`` (the rigid maps of the napkin seen) are given, with its hands' motion
    (``motion``: :class:`~dgli_vision.planning.motion.MotionParams`).

    Raises
    ------
    PlanRefused
        No sequence of folds leads there, or the first step's corner cannot be placed.
    """
    path, lines = plan_steps(start, goal, layout)
    steps = []
    here = start
    for i, ((action, word, after), f) in enumerate(zip(path, lines)):
        step = PlanStep(action, word, f.corner, f.side, f.under, after,
                        crease_mm=(f.p0, f.p1) if action == "fold" else None)
        if maps is not None:
            placed = _place_step(action, f, maps, affordances, i == 0, intrinsics, layout,
                                 motion)
            if placed is None and i == 0:
                what = f"corner {f.corner}" if f.corner else f"side {f.side}"
                raise PlanRefused(
                    f"cannot place the {what} to {action} ({word}) in {_name(here)}"
                )
            if placed is not None:
                step = replace(step, **placed)
            maps = _after(maps, action, f)
        steps.append(step)
        here = after
    final = path[-1][2] if path else start
    return Plan(start, final if goal[1] is None else goal, tuple(steps))


def _after(maps: NapkinMaps, action: str, f: NominalFold) -> NapkinMaps:
    """The maps once a step is made: a new flap lies where its mirror image is; an
    unfolded flap lies flat again."""
    if action == "fold":
        return replace(maps, folds=(*maps.folds, f), flaps=(*maps.flaps, None), sticker_part=())
    keep = [k for k, g in enumerate(maps.folds) if g.word != f.word]
    return replace(
        maps, folds=tuple(maps.folds[k] for k in keep), flaps=tuple(maps.flaps[k] for k in keep),
        sticker_part=(),
    )


def _corner_now(
    name: str, maps: NapkinMaps, affordances: Affordances | None, first: bool,
    layout: NapkinLayout,
) -> NDArray[np.float64] | None:
    """Where corner ``name`` is now: seen on the first step, else placed by the maps."""
    c = affordances.corners[name] if affordances is not None and first else None
    if c is not None and c.point is not None:
        return np.asarray(c.point, dtype=float)
    p, _ = maps.place(np.asarray(layout.corner_uv[CORNERS.index(name)], dtype=float))
    return p


def _place_step(
    action: str,
    f: NominalFold,
    maps: NapkinMaps,
    affordances: Affordances | None,
    first: bool,
    intrinsics: Any | None,
    layout: NapkinLayout,
    motion: MotionParams = DEFAULT_MOTION,
) -> dict[str, Any] | None:
    """Grasp, place, fold line, lift height and the hands' motion of one step in the
    camera frame. A corner (or diagonal) fold has one hand, on the corner; a strip or a
    half fold two, one on each corner of the side (a side held at its middle alone
    sags at its corners)."""
    names = list(f.moved_corners) if f.side else [f.corner]
    lift = 1.0 if action == "fold" and not f.under else 0.0
    grasps = []
    for name in names:
        grasp = _corner_now(name, maps, affordances, first, layout)
        flat_uv = np.asarray(layout.corner_uv[CORNERS.index(name)], dtype=float)
        target_uv = flat_uv if action == "unfold" else reflect_uv(flat_uv, f)[0]
        place = maps.place_stay(target_uv)
        if grasp is None or place is None:
            return None
        place = maps.on_table(place) + lift * maps.thickness_m * maps.up
        grasps.append((name, grasp, place))
    ends = fold_line_3d(maps, f)
    if ends is None:
        return None
    grasp, place = grasps[0][1], grasps[0][2]
    line = bisector_through(maps.on_table(grasp), maps.on_table(place), ends, maps.up)

    def pixel(p: NDArray) -> tuple[float, float] | None:
        if intrinsics is None or p[2] <= 0:
            return None
        px = intrinsics.project(p[None])[0]
        return float(px[0]), float(px[1])

    what = [f"corner {n}" + (f" of side {f.side}" if f.side else "") for n, _, _ in grasps]
    hands = hands_motion([(w, g, pixel(g), p) for w, (_, g, p) in zip(what, grasps)],
                         line, maps.up, motion)
    first_hand = hands[0]
    return {
        "grasp_point": first_hand.grasp_point,
        "grasp_pixel": first_hand.grasp_pixel,
        "place_point": first_hand.place_point,
        "fold_line": tuple(tuple(float(v) for v in e) for e in line),
        "lift_height": first_hand.lift_height,
        "hands": hands,
    }
