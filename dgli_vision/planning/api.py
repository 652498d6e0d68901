"""One call from code: an image (or a known state) and a goal to a plan."""

from __future__ import annotations

from typing import Any

from ..classifier.affordances import napkin_maps
from ..classifier.pipeline import FrameResult, classify_frame
from ..core.fold_graph import StateKey
from ..core.frame import RGBDFrame
from ..core.layout import NapkinLayout, layout_of_size
from .plan import Plan, PlanRefused, parse_state, plan_geometry

__all__ = ["plan", "plan_frame"]


def _key(state: str | StateKey, *, need_variant: bool) -> StateKey:
    if isinstance(state, str):
        try:
            return parse_state(state, need_variant=need_variant)
        except ValueError as exc:
            raise PlanRefused(str(exc)) from None
    return state[0], state[1]


def plan_frame(
    result: FrameResult, frame: RGBDFrame, goal: StateKey, layout: NapkinLayout
) -> Plan:
    """The plan from a classified frame to ``goal``, placed in the frame's camera.

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
    return plan_geometry(start, goal, layout, maps, result.affordances, frame.intrinsics)


def plan(
    color: Any = None,
    depth: Any = None,
    *,
    goal: str | StateKey,
    start: str | StateKey | None = None,
    intrinsics: Any = None,
    references: Any = None,
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

    Returns
    -------
    Plan
        ``plan.to_json()`` is the object ``dgli plan --json`` prints.

    Raises
    ------
    PlanRefused
        No plan (the message says why); other ``DgliError`` for unreadable input.
    """
    from ..classifier.api import frame_from, reference_set_of

    target = _key(goal, need_variant=False)
    if start is not None:
        return plan_geometry(_key(start, need_variant=True), target, layout_of_size(None),
                             None, None, None)
    if color is None or depth is None:
        raise PlanRefused("give a colour and a depth image, or a start state")
    frame = frame_from(color, depth, intrinsics)
    refs = reference_set_of(references)
    layout = layout_of_size(refs.napkin_mm)
    result = classify_frame(frame, refs, layout=layout)
    return plan_frame(result, frame, target, layout)
