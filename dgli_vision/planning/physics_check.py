"""The closed loop on physics cloth: ``dgli plan --check --physics``.

For each trial (a start state and a goal one step away): the start is folded in
MuJoCo's sim frame by the isometric simulator (layers ``2 radius`` apart) and settled as
physics cloth (:mod:`dgli_vision.sim.physics`); rendered from a random camera that sees
the whole napkin under random light with sensor noise, classified and planned for; the
plan's first step is carried out by simulated grippers following each hand's path (taken
from the camera frame to the table's and on to the sim frame), the cloth settles, is
rendered again from the same camera, classified and checked with ``verify`` against the
step's expected state and planned crease.

Besides the verdicts, the cloth itself is measured (``made``): the napkin that stays is
fitted by a rigid map from its own vertices (how far it was dragged, ``base_drag_mm``),
each grasped corner's landing is read in that napkin's material frame, and the crease
the fold made (the perpendicular bisector of a corner's flat place and its landing, the
line through the two bisectors' midpoints for a side) is compared with the planned one
(``crease_mm``) with the corner's distance from its planned landing (``tip_mm``).

A state that the last step left imperfect is made by carrying out a first step with the
place point ``short_mm`` short of the plan (``short`` trials), then planning again from
the image of that.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..classifier.pipeline import classify_frame
from ..classifier.references import ReferenceSet
from ..core.camera import DEFAULT_INTRINSICS, CameraPose, Intrinsics
from ..core.classes import CORNERS
from ..core.fold_graph import StateKey
from ..core.fold_lines import reflect_uv
from ..core.fold_measure import Crease, crease_distance_mm
from ..core.frame import RGBDFrame
from ..core.layout import NapkinLayout, default_layout
from ..sim.cloth.states import draw_fold_steps, make_state
from ..sim.dataset import random_camera
from ..sim.render import Lighting, SensorModel, render
from .api import plan_frame
from .motion import DEFAULT_MOTION, MotionParams
from .plan import PlanRefused, PlanStep, plan_steps

__all__ = [
    "PHYSICS_TRIALS",
    "PhysicsRow",
    "PhysicsSetup",
    "physics_table",
    "run_physics_trial",
]

#: The trials of ``dgli plan --check --physics``: (start, goal, kind); ``kind`` is
#: ``"one step"`` (a one-step plan from 01 or 02: every corner, strip, half and
#: diagonal fold from flat and the folds from 02 towards 04 and 06), ``"unfold"`` or
#: ``"short"`` (the plan from a corner fold left 20 mm short).
PHYSICS_TRIALS: tuple[tuple[StateKey, StateKey, str], ...] = (
    *((("01", None), ("02", c), "one step") for c in CORNERS),
    *((("01", None), ("09", s), "one step") for s in ("AB", "BC", "CD", "DA")),
    *((("01", None), ("11", s), "one step") for s in ("AB", "BC", "CD", "DA")),
    *((("01", None), ("12", c), "one step") for c in CORNERS),
    (("02", "A"), ("04", "AB"), "one step"),
    (("02", "A"), ("04", "DA"), "one step"),
    (("02", "A"), ("06", "AC"), "one step"),
    (("02", "C"), ("04", "BC"), "one step"),
    (("02", "C"), ("04", "CD"), "one step"),
    (("02", "C"), ("06", "AC"), "one step"),
    (("02", "A"), ("01", None), "unfold"),
    (("04", "AB"), ("02", "A"), "unfold"),
    (("11", "AB"), ("01", None), "unfold"),
    (("01", None), ("04", "AB"), "short"),
)


@dataclass(frozen=True)
class PhysicsSetup:
    """How the physics trials are run.

    Attributes
    ----------
    material : ClothMaterial or None
        The napkin's physics (None: :class:`~dgli_vision.sim.physics.model.ClothMaterial`'s
        defaults).
    motion : MotionParams
        How the hands move.
    settle_s : float
        At most this long for the cloth to come to rest, before and after the step, s.
    intrinsics : Intrinsics
        The camera.
    short_mm : float
        How far short of the plan a ``short`` trial's first fold is laid, mm.
    tolerance_mm : float
        ``verify``'s tolerance on the planned crease.
    keep_images : bool
        Keep the colour images before and after the step in each row (for figures).
    """

    material: Any = None
    motion: MotionParams = DEFAULT_MOTION
    settle_s: float = 1.0
    intrinsics: Intrinsics = DEFAULT_INTRINSICS
    short_mm: float = 20.0
    tolerance_mm: float = 20.0
    keep_images: bool = False


@dataclass(frozen=True)
class PhysicsRow:
    """One physics trial.

    Attributes
    ----------
    start, goal : StateKey
    kind : str
        As in :data:`PHYSICS_TRIALS`.
    seen, expect, after : StateKey or None
        The start as read, the state the step should make, the state read after it.
    outcome : str
        ``right`` (start read right and the state after the expected one), ``cannot
        tell``, ``refused`` or ``wrong``.
    verified : bool or None
        ``verify``'s verdict on the after frame (state and planned crease).
    made : dict
        The cloth's own measures: ``base_drag_mm``, ``crease_mm``, ``tip_mm`` (a
        fold's), ``landing_mm`` (each grasped corner's distance from where the path
        should lay it), ``hands``, ``sim_s`` (simulated time), ``settled``.
    note : str
    images : tuple of ndarray
        The colour images before and after the step (``keep_images``), else empty.
    """

    start: StateKey
    goal: StateKey
    kind: str
    seen: StateKey | None
    expect: StateKey | None
    after: StateKey | None
    outcome: str
    verified: bool | None = None
    made: dict[str, Any] = field(default_factory=dict)
    note: str = ""
    images: tuple = ()


def _frame(r: Any) -> RGBDFrame:
    return RGBDFrame(r.color, r.depth_mm, r.intrinsics, "<render>", "<render>", "given")


def _verdict(result: Any) -> StateKey | None:
    p = result.prediction
    return None if p is None else (p.class_id, p.variant)


def _sim_layout(layout: NapkinLayout, material: Any) -> NapkinLayout:
    """The layout with the layers ``2 radius`` (plus 0.5 mm) apart, for a start state
    the physics cloth can lie in."""
    return replace(layout, thickness_mm=2e3 * material.radius_m + 0.5)


def settled_start(
    start: StateKey, rng: np.random.Generator, layout: NapkinLayout, setup: PhysicsSetup
) -> tuple[NDArray[np.float64], Any]:
    """A state of ``start`` as physics cloth at rest: the grid's vertices (sim frame)
    and the model's shape."""
    from ..sim.physics.grippers import execute
    from ..sim.physics.model import ClothMaterial, build_model

    material = setup.material or ClothMaterial()
    steps, params = draw_fold_steps(start[0], start[1], layout, rng)
    spacing = layout.width_mm / (material.grid - 1)
    state = make_state(start[0], start[1], steps, layout=_sim_layout(layout, material),
                       spacing_mm=spacing, params=params)
    xyz = state.mesh.xyz.copy()  # make_state puts the napkin's centre at the origin
    xyz[:, :2] += np.array([layout.width_mm, layout.height_mm]) * 0.5e-3
    cm = build_model(layout, xyz, material=material)
    ex = execute(cm, [], settle_s=setup.settle_s)
    return ex.xyz, cm


def _hand_paths(step: PlanStep, pose: CameraPose, layout: NapkinLayout, yaw: float,
                offset: tuple[float, float], radius: float) -> list[Any]:
    """Each hand's path in the sim frame: the cloth's midsurface lies ``radius`` up and
    its layers ``2 radius`` apart (the real napkin's ``thickness``), so a height of one
    thickness above the table (a corner put down on the napkin) becomes ``3 radius``."""
    from ..sim.physics.export import world_to_sim
    from ..sim.physics.grippers import HandPath

    out = []
    for hand in step.hands:
        cam = np.asarray([w.point for w in hand.path], dtype=float)
        sim = world_to_sim(pose.camera_to_world(cam), layout, yaw, offset)
        h = np.maximum(sim[:, 2], 0.0)
        t = layout.thickness_mm * 1e-3
        sim[:, 2] = radius + h + (2 * radius - t) * np.minimum(h / t, 1.0)
        out.append(HandPath(np.asarray([w.t for w in hand.path]), sim,
                            np.asarray([w.gripper == "closed" for w in hand.path])))
    return out


def execute_step(
    xyz: NDArray[np.float64], step: PlanStep, pose: CameraPose, layout: NapkinLayout,
    yaw: float, offset: tuple[float, float], setup: PhysicsSetup,
) -> tuple[Any, Any]:
    """Carry out ``step`` on the cloth at ``xyz`` (sim frame): each hand grasps the
    vertex nearest to its grasp point. Returns the model and the execution."""
    from ..sim.physics.grippers import execute
    from ..sim.physics.model import ClothMaterial, build_model

    material = setup.material or ClothMaterial()
    paths = _hand_paths(step, pose, layout, yaw, offset, material.radius_m)
    # the vertex under the gripper's jaws: nearest to the point where it closes
    grip = [int(np.argmax(p.closed)) for p in paths]
    vertices = tuple(int(np.argmin(np.linalg.norm(xyz - p.points[k], axis=1)))
                     for p, k in zip(paths, grip))
    cm = build_model(layout, xyz, material=material, hand_vertices=vertices)
    return cm, execute(cm, paths, settle_s=setup.settle_s)


def _rigid_2d(src: NDArray, dst: NDArray) -> tuple[NDArray, NDArray]:
    """Rotation (2, 2) and translation (2,) taking points ``src`` (k, 2) to ``dst``."""
    ms, md = src.mean(axis=0), dst.mean(axis=0)
    u, _, vt = np.linalg.svd((src - ms).T @ (dst - md))
    d = np.sign(np.linalg.det(u @ vt))
    rot = (u @ np.diag([1.0, d]) @ vt).T
    return rot, md - rot @ ms


def cloth_measures(
    before: NDArray, after: NDArray, uv: NDArray, step: PlanStep, layout: NapkinLayout,
    fold_line: Any,
) -> dict[str, Any]:
    """The cloth's own measures of a step (see the module's description): the napkin
    that stays (its vertices more than 30 mm inside the fold line, lying on the table),
    fitted from ``before`` to ``after`` (sim frame, m; ``uv`` their material mm)."""
    stay = ~fold_line.on_flap(uv, -30.0)
    low = after[:, 2] < after[stay, 2].min() + 2.5e-3
    keep = stay & low
    rot, shift = _rigid_2d(after[keep, :2] * 1e3, uv[keep])  # after (mm) -> material
    drag = float(np.median(np.linalg.norm(after[keep, :2] * 1e3 - before[keep, :2] * 1e3,
                                          axis=1)))
    names = list(fold_line.moved_corners)
    landings, mids, out = [], [], {"base_drag_mm": round(drag, 1)}
    for name in names:
        flat = np.asarray(layout.corner_uv[CORNERS.index(name)], dtype=float)
        k = int(np.argmin(np.linalg.norm(uv - flat, axis=1)))
        land = rot @ (after[k, :2] * 1e3) + shift
        want = flat if step.action == "unfold" else reflect_uv(flat[None], fold_line)[0]
        landings.append(float(np.linalg.norm(land - want)))
        mids.append((0.5 * (flat + land), land - flat))
    out["landing_mm"] = [round(v, 1) for v in landings]
    if step.action == "fold" and step.crease_mm is not None:
        planned = Crease.through(*step.crease_mm)
        if len(mids) == 2:  # a side: the line through the two corners' midpoints
            made = Crease.through(mids[0][0], mids[1][0])
        else:  # a corner: the perpendicular bisector of its flat place and its landing
            mid, d = mids[0]
            made = Crease.through(mid, mid + np.array([-d[1], d[0]]))
        err = crease_distance_mm(made, planned, layout)
        out["crease_mm"] = None if err is None else round(float(err), 1)
        out["tip_mm"] = round(max(landings), 1)
    return out


def _camera(layout: NapkinLayout, yaw: float, offset: tuple, rng: np.random.Generator,
            setup: PhysicsSetup) -> tuple[CameraPose, Lighting]:
    """A random camera that sees the whole napkin even unfolded, and random light."""
    unfolded = make_state("01", None, [], layout=layout, yaw=yaw, offset_m=offset)
    pose, _ = random_camera(unfolded, rng, intrinsics=setup.intrinsics)
    return pose, Lighting.random(rng)


def _look(xyz: NDArray, cm: Any, layout: NapkinLayout, yaw: float, offset: tuple,
          pose: CameraPose, lighting: Lighting, rng: np.random.Generator,
          setup: PhysicsSetup, refs: ReferenceSet) -> Any:
    """Render the physics cloth at ``xyz`` and classify it."""
    from ..sim.physics.export import cloth_state

    state = cloth_state(xyz, cm.shape, layout, radius_m=cm.material.radius_m, yaw=yaw,
                        offset_m=offset)
    r = render(state, pose, intrinsics=setup.intrinsics, lighting=lighting,
               sensor=SensorModel(), rng=rng, layout=layout)
    frame = _frame(r)
    return frame, classify_frame(frame, refs, layout=layout)


def run_physics_trial(
    start: StateKey,
    goal: StateKey,
    kind: str,
    seed: tuple[int, ...],
    references: ReferenceSet,
    *,
    setup: PhysicsSetup | None = None,
    layout: NapkinLayout | None = None,
) -> PhysicsRow:
    """One physics trial (see the module's description)."""
    from ..planning.verify import verify_fold

    setup = setup or PhysicsSetup()
    layout = layout or default_layout()
    rng = np.random.default_rng(list(seed))
    yaw = float(rng.uniform(0, 2 * np.pi))
    offset = tuple(float(v) for v in rng.uniform(-0.05, 0.05, size=2))
    xyz, cm = settled_start(start, rng, layout, setup)
    pose, lighting = _camera(layout, yaw, offset, rng, setup)
    made: dict[str, Any] = {}
    if kind == "short":  # the first step laid short of the plan; then plan again
        frame, result = _look(xyz, cm, layout, yaw, offset, pose, lighting, rng, setup,
                              references)
        short = replace(setup.motion, place_offset_m=-setup.short_mm * 1e-3)
        try:
            first = plan_frame(result, frame, ("02", goal[1][0] if goal[1] else "A"),
                               layout, motion=short)
        except PlanRefused as exc:
            return PhysicsRow(start, goal, kind, _verdict(result), None, None, "refused",
                              note=str(exc))
        cm, ex = execute_step(xyz, first.steps[0], pose, layout, yaw, offset, setup)
        xyz = ex.xyz
        start = first.steps[0].expect
    frame, result = _look(xyz, cm, layout, yaw, offset, pose, lighting, rng, setup,
                          references)
    seen = _verdict(result)
    if seen is None:
        return PhysicsRow(start, goal, kind, None, None, None, "cannot tell",
                          note=result.reason or "")
    try:
        plan = plan_frame(result, frame, goal, layout, motion=setup.motion)
    except PlanRefused as exc:
        return PhysicsRow(start, goal, kind, seen, None, None, "refused", note=str(exc))
    if not plan.steps:
        return PhysicsRow(start, goal, kind, seen, None, seen, "wrong", note="no step")
    step = plan.steps[0]
    before, before_image = xyz, frame.color
    cm, ex = execute_step(xyz, step, pose, layout, yaw, offset, setup)
    _, lines = plan_steps(seen, goal, layout)
    made = cloth_measures(before, ex.xyz, cm.uv, step, layout, lines[0])
    made.update(hands=len(step.hands), settled=ex.settled,
                sim_s=round(ex.steps * cm.model.opt.timestep, 2))
    frame, after = _look(ex.xyz, cm, layout, yaw, offset, pose, lighting, rng, setup,
                         references)
    got = _verdict(after)
    crease = Crease.through(*step.crease_mm) if step.crease_mm is not None else None
    check = verify_fold(after, step.expect, layout, fold=step.fold if crease else None,
                        crease=crease, tolerance_mm=setup.tolerance_mm)
    if got is None:
        outcome = "cannot tell"
    else:
        outcome = "right" if got == step.expect and seen == start else "wrong"
    note = "" if check.success else "; ".join(check.reasons)
    images = (before_image, frame.color) if setup.keep_images else ()
    return PhysicsRow(start, goal, kind, seen, step.expect, got, outcome, check.success,
                      made, note if outcome == "right" else (after.reason or note), images)


def _spread(values: list[float]) -> dict[str, float | None]:
    if not values:
        return {"median": None, "p90": None, "max": None}
    v = np.asarray(values, dtype=float)
    return {k: round(float(np.quantile(v, q)), 1)
            for k, q in (("median", 0.5), ("p90", 0.9), ("max", 1.0))}


def _txt(key: StateKey | None) -> str | None:
    if key is None:
        return None
    return f"{key[0]}/{key[1]}" if key[1] else key[0]


def physics_table(rows: list[PhysicsRow]) -> dict[str, Any]:
    """The success table: outcomes per kind and in all, each trial's line (start, goal,
    outcome, verify, the cloth's measures) and the spread of the crease, tip and base
    drag errors (mm) of the one-step folds."""
    by_kind: dict[str, Counter] = {}
    for r in rows:
        by_kind.setdefault(r.kind, Counter())[r.outcome] += 1
    folds = [r.made for r in rows if r.kind == "one step" and "crease_mm" in r.made]
    return {
        "trials": len(rows),
        "right": sum(r.outcome == "right" for r in rows),
        "by_kind": {k: dict(c) for k, c in by_kind.items()},
        "one_step_success": _share([r for r in rows if r.kind == "one step"]),
        "rows": [
            {"start": _txt(r.start), "goal": _txt(r.goal), "kind": r.kind,
             "seen": _txt(r.seen), "expect": _txt(r.expect), "after": _txt(r.after),
             "outcome": r.outcome, "verified": r.verified, **r.made, "note": r.note}
            for r in rows
        ],
        "crease_mm": _spread([m["crease_mm"] for m in folds if m.get("crease_mm") is not None]),
        "tip_mm": _spread([m["tip_mm"] for m in folds if m.get("tip_mm") is not None]),
        "base_drag_mm": _spread([m["base_drag_mm"] for m in folds]),
    }


def _share(rows: list[PhysicsRow]) -> float | None:
    return round(sum(r.outcome == "right" for r in rows) / len(rows), 4) if rows else None
