"""One call from code: an image (or a known state) and a goal to a plan."""

from __future__ import annotations

from typing import Any

from ..classifier.affordances import napkin_maps
from ..classifier.pipeline import FrameResult, classify_frame
from ..core.fold_graph import StateKey
from ..core.frame import RGBDFrame
from ..core.layout import NapkinLayout, layout_of_size
from .motion import DEFAULT_MOTION, MotionParams
from .plan import Plan, PlanRefused, PlanStep, parse_state, plan_geometry
from .verify import DEFAULT_TOLERANCE_MM, FoldCheck

__all__ = ["plan", "plan_frame", "verify"]


def _key(state: str | StateKey, *, need_variant: bool) -> StateKey:
    if isinstance(state, str):
        try:
            return parse_state(state, need_variant=need_variant)
        except ValueError as exc:
            raise PlanRefused(str(exc)) from None
    return state[0], state[1]


def plan_frame(
    result: FrameResult, frame: RGBDFrame, goal: StateKey, layout: NapkinLayout, *,
    motion: MotionParams = DEFAULT_MOTION,
) -> Plan:
    """The plan from a classified frame to ``goal``, placed in the frame's camera, its
    hands moving as ``motion`` says.

    Raises
    ------
    PlanRefused
        The state could not be told (the reason is the verdict's), no sequence of folds
        leads to the goal, or the first step's corner cannot be placed.
    """
    p = result.prediction
    if p is None:
        raise PlanRefused(f"no plan: the state cannot be told: {result.reason}")
    start = (p.class_id, p.variant)
    maps = napkin_maps(result.observation, p.class_id, p.variant, layout)
    return plan_geometry(start, goal, layout, maps, result.affordances, frame.intrinsics,
                         motion=motion)


def plan(
    color: Any = None,
    depth: Any = None,
    *,
    goal: str | StateKey,
    start: str | StateKey | None = None,
    intrinsics: Any = None,
    references: Any = None,
    extrinsics: Any = None,
    mirroring: str | None = None,
) -> Plan:
    """The next folds towards ``goal``: from a colour + depth pair (classified first),
    or from a known state ``start`` (then the steps carry no points).

    Parameters
    ----------
    color, depth : path or ndarray, optional
        As :func:`~dgli_vision.classifier.api.classify_pair` takes them.
    goal : str or (class, variant)
        ``"08"``, ``"02/A"``, ``"05/AB/B"``; a class with variants given alone means
        its nearest state.
    start : str or (class, variant), optional
        Plan without an image, from this state.
    intrinsics, references : optional
        As for :func:`~dgli_vision.classifier.api.classify_pair`.
    extrinsics : Extrinsics, path or (4, 4) array, optional
        The camera-to-base transform (:mod:`dgli_vision.core.extrinsics`): the steps'
        grasp and place points, fold lines and hands (grasps, places, every waypoint)
        are then in the robot's base frame (as with ``--extrinsics``); default the
        camera frame.
    mirroring : {"no", "yes", "unknown"}, optional
        The camera's handedness, as for
        :func:`~dgli_vision.classifier.api.classify_pair`.

    Returns
    -------
    Plan
        ``plan.to_json()`` is the object ``dgli plan --json`` prints (without its
        ``"frame"``).

    Raises
    ------
    PlanRefused
        No plan (the message says why); other ``DgliError`` for unreadable input.
    """
    from ..classifier.api import frame_from, reference_set_of
    from ..core.extrinsics import extrinsics_of

    ext = extrinsics_of(extrinsics)
    target = _key(goal, need_variant=False)
    if start is not None:
        return plan_geometry(_key(start, need_variant=True), target, layout_of_size(None),
                             None, None, None)
    if color is None or depth is None:
        raise PlanRefused("give a colour and a depth image, or a start state")
    frame = frame_from(color, depth, intrinsics)
    refs = reference_set_of(references)
    layout = layout_of_size(refs.napkin_mm)
    result = classify_frame(frame, refs, layout=layout, mirroring=mirroring)
    made = plan_frame(result, result.frame_as_read(frame), target, layout)
    return made if ext is None else _in_frame(made, ext)


def _in_frame(made: Plan, ext: Any) -> Plan:
    """``made`` with its steps' 3D points in the frame of ``ext``."""
    from dataclasses import replace

    from ..core.extrinsics import moved_point

    def hand(h: Any) -> Any:
        path = tuple(replace(w, point=moved_point(ext, w.point)) for w in h.path)
        return replace(h, grasp_point=moved_point(ext, h.grasp_point),
                       place_point=moved_point(ext, h.place_point), path=path)

    def step(s: PlanStep) -> PlanStep:
        line = None if s.fold_line is None else tuple(moved_point(ext, q) for q in s.fold_line)
        return replace(s, grasp_point=moved_point(ext, s.grasp_point),
                       place_point=moved_point(ext, s.place_point), fold_line=line,
                       hands=tuple(hand(h) for h in s.hands))

    return replace(made, steps=tuple(step(s) for s in made.steps))


def _expected(expect: str | StateKey) -> StateKey:
    """``expect`` as a state key (a variant of None: any)."""
    from ..core.errors import InvalidValueError

    if isinstance(expect, str):
        try:
            return parse_state(expect, need_variant=False)
        except ValueError as exc:
            raise InvalidValueError(f"expect: {exc}") from None
    if not isinstance(expect, tuple) or len(expect) != 2:
        raise InvalidValueError(
            f"expect must be a state such as '02/B' or ('02', 'B'); got {expect!r}"
        )
    return parse_state("/".join(v for v in expect if v), need_variant=False)


def _legs(legs: str | dict[str, float] | None) -> dict[str, float] | None:
    """Legs as ``"AB=180,DA=175"`` or ``{"AB": 180, "DA": 175}``, checked."""
    from ..core.errors import InvalidValueError
    from .verify import parse_legs

    if legs is None:
        return None
    if isinstance(legs, dict):
        legs = ",".join(f"{edge}={mm}" for edge, mm in legs.items())
    if not isinstance(legs, str):
        raise InvalidValueError(
            f"legs must be 'AB=180,DA=175' or {{'AB': 180, 'DA': 175}}; got {legs!r}"
        )
    return parse_legs(legs)


def verify(
    color: Any,
    depth: Any,
    *,
    expect: str | StateKey | None = None,
    legs: str | dict[str, float] | None = None,
    inset: float | None = None,
    tip: tuple[float, float] | None = None,
    step: PlanStep | None = None,
    offset: float | None = None,
    tolerance: float = DEFAULT_TOLERANCE_MM,
    intrinsics: Any = None,
    references: Any = None,
    mirroring: str | None = None,
) -> FoldCheck:
    """Did the fold work? The frame taken after a fold against the state it should
    have made and, optionally, the fold's planned sizes (what ``dgli verify`` does).

    Parameters
    ----------
    color, depth : path or ndarray
        The frame after the fold, as :func:`~dgli_vision.classifier.api.classify_pair`
        takes them.
    expect : str or (class, variant), keyword-only
        The state the fold should make: ``"02/B"``, ``("02", "B")``; a class alone
        (``"09"``) accepts any variant. Not needed with ``step``.
    legs : str or dict, optional
        A corner fold's planned legs in mm, ``"AB=180,DA=175"`` or ``{"AB": 180, "DA":
        175}`` (both legs of one corner; needs ``expect``'s variant).
    inset : float, optional
        A strip's or half fold's planned inset, mm.
    tip : (float, float), optional
        Where the corner should land on the flat napkin, (u, v) mm.
    step : PlanStep, optional
        A step of :func:`plan`: its expected state, its fold and its planned crease
        (in place of ``expect`` and the sizes).
    offset : float, optional
        A diagonal fold's planned offset from its diagonal, mm (positive towards the
        moving corner; 0: on the diagonal).
    tolerance : float
        How far (mm) a planned size may be missed (20).
    intrinsics, references, mirroring : optional
        As for :func:`~dgli_vision.classifier.api.classify_pair`.

    Returns
    -------
    FoldCheck
        ``success`` True (the state and every planned size within ``tolerance``), False
        (failed: ``reasons`` says why; undo or redo the fold) or None (cannot tell:
        ``reasons`` says why; look again). ``check.to_json()`` is the object ``dgli
        verify --json`` prints.

    Raises
    ------
    DgliError
        Input that is not an RGB-D frame (as ``classify_pair``), or a request no frame
        could satisfy (:class:`~dgli_vision.core.errors.InvalidValueError`, naming the
        mistake: an unknown state, two of ``legs``/``inset``/``tip``/``offset``, sizes of a fold
        the expected state does not have, legs without the expected variant).
    """
    from ..classifier.api import frame_from, reference_set_of
    from ..core.errors import InvalidValueError
    from ..core.fold_measure import Crease
    from .verify import check_request, verify_fold

    if not (isinstance(tolerance, (int, float)) and 0 < tolerance < 1000):
        raise InvalidValueError(f"tolerance must be a number of mm in (0, 1000); got "
                                f"{tolerance!r}")
    sizes: dict[str, Any] = {}
    if step is not None:
        if expect is not None or any(v is not None for v in (legs, inset, tip, offset)):
            raise InvalidValueError("give a plan's step, or expect= and its sizes, not both")
        key = step.expect
        if step.crease_mm is not None:
            sizes = {"fold": step.fold, "crease": Crease.through(*step.crease_mm)}
    elif expect is None:
        raise InvalidValueError("give expect= (the state the fold should make) or step=")
    else:
        key = _expected(expect)
        sizes = _requested_sizes(legs, inset, tip, offset)
        check_request(key, **sizes)
    frame = frame_from(color, depth, intrinsics)
    refs = reference_set_of(references)
    layout = layout_of_size(refs.napkin_mm)
    result = classify_frame(frame, refs, layout=layout, mirroring=mirroring)
    return verify_fold(result, key, layout, tolerance_mm=float(tolerance), **sizes)


def _requested_sizes(legs: Any, inset: Any, tip: Any, offset: Any) -> dict[str, Any]:
    """:func:`verify`'s sizes of the fold asked for, checked: each a number of mm in its
    range (one line naming the one that is not)."""
    import math

    from ..core.errors import InvalidValueError

    if tip is not None:
        try:
            uv = tuple(float(v) for v in tip)
        except (TypeError, ValueError):
            uv = ()
        if len(uv) != 2 or not all(math.isfinite(v) for v in uv):
            raise InvalidValueError(f"tip must be (u, v) in mm; got {tip!r}")
        tip = uv
    if inset is not None and not (isinstance(inset, (int, float)) and 0 < inset < 1000):
        raise InvalidValueError(f"inset must be a number of mm in (0, 1000); got {inset!r}")
    if offset is not None and not (
        isinstance(offset, (int, float)) and math.isfinite(offset) and abs(offset) < 1000
    ):
        raise InvalidValueError(f"offset must be a number of mm in (-1000, 1000); got "
                                f"{offset!r}")
    return {"legs": _legs(legs), "inset_mm": inset, "tip_mm": tip, "offset_mm": offset}
