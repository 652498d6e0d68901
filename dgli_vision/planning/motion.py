"""A plan step's motion per hand: the grasp, the timed path, the gripper along it.

A fold (or unfold) turns a flap about its fold line. Each hand grasps one point of the
flap (a corner; for a strip or a half fold the two corners of the side, one per hand),
and carries it along an arc about the fold line to where the fold lays it:

- **approach**: from ``approach_m`` above the grasp point, gripper open;
- **grasp**: down onto it; the gripper closes;
- **lift**, **carry**, **lower**: an arc about the fold line, in the plane through the
  grasp point square to the line, from the grasp point over the line to the place
  point. Its distance from the line is the grasped point's own (``r``) at both ends and
  ``arc_ratio * r`` at the top: the flap never hangs taut between the hand and the
  crease, so it does not pull the napkin that stays across the table (on physics cloth
  a taut flap drags the base 15-20 mm towards the crease: docs/planning.md);
- **drag** (optional): ``drag_m`` along the table past the place point, straightening
  the flap's edge;
- **release**: the gripper opens; **retreat**: ``approach_m`` straight up.

All points are in the camera frame of the image (or in the robot's frame through
:func:`~dgli_vision.core.extrinsics.in_frame`); times in seconds from the step's start,
from the speeds of :class:`MotionParams`. With two hands both follow the same phases at
the same times (the longer arc sets the pace), so the side stays straight.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.errors import InvalidValueError

__all__ = ["DEFAULT_MOTION", "PHASES", "Hand", "MotionParams", "Waypoint", "hands_motion"]

#: The phases of a hand's path, in order (``drag`` only where ``drag_m`` > 0).
PHASES = ("approach", "grasp", "lift", "carry", "lower", "drag", "release", "retreat")


@dataclass(frozen=True)
class MotionParams:
    """How the hands move (chosen from what works on physics cloth: docs/planning.md).

    Attributes
    ----------
    approach_m : float
        Height above the grasp (and place) point the hand comes from and leaves to, m.
    arc_ratio : float
        The carry arc's distance from the fold line at its top, as a share of the
        grasped point's distance from it (1: a rigid turn of the flap; below 1 the flap
        hangs slack).
    arc_points : int
        Waypoints on the arc (lift, carry and lower together), ends included.
    lift_speed_m_s : float
        Speed of the approach, the grasp and the retreat, m/s.
    carry_speed_m_s : float
        Speed along the arc and the drag (the longer hand's), m/s.
    grip_s : float
        Time to close or open a gripper, s.
    drag_m : float
        How far the hand drags the placed point along the table past the place point
        (away from the fold line) before letting go, m.
    place_offset_m : float
        The place point moved this far away from the fold line (negative: towards it), m.
    """

    approach_m: float = 0.05
    arc_ratio: float = 0.9
    arc_points: int = 13
    lift_speed_m_s: float = 0.1
    carry_speed_m_s: float = 0.2
    grip_s: float = 0.3
    drag_m: float = 0.0
    place_offset_m: float = 0.0

    def __post_init__(self) -> None:
        if not 0.3 <= self.arc_ratio <= 1.2:
            raise InvalidValueError(f"arc_ratio must be in [0.3, 1.2]; got {self.arc_ratio}")
        if self.arc_points < 3:
            raise InvalidValueError(f"arc_points must be at least 3; got {self.arc_points}")
        for name in ("lift_speed_m_s", "carry_speed_m_s", "approach_m"):
            if not getattr(self, name) > 0:
                raise InvalidValueError(f"{name} must be positive; got {getattr(self, name)}")
        if self.grip_s < 0 or self.drag_m < 0:
            raise InvalidValueError("grip_s and drag_m must not be negative")


DEFAULT_MOTION = MotionParams()


@dataclass(frozen=True)
class Waypoint:
    """One timed point of a hand's path.

    Attributes
    ----------
    point : tuple of 3 float
        Camera frame, metres.
    t : float
        Seconds from the step's start.
    gripper : str
        ``"open"`` or ``"closed"`` from this waypoint to the next.
    phase : str
        One of :data:`PHASES`: the phase this waypoint ends.
    """

    point: tuple[float, float, float]
    t: float
    gripper: str
    phase: str

    def to_json(self) -> dict[str, Any]:
        """``{"point", "t", "gripper", "phase"}``."""
        return {"point": [round(float(v), 5) for v in self.point], "t": round(self.t, 3),
                "gripper": self.gripper, "phase": self.phase}


@dataclass(frozen=True)
class Hand:
    """One hand's part of a step.

    Attributes
    ----------
    grasps : str
        What is grasped: ``"corner B"``, or ``"corner C of side CD"``.
    grasp_point : tuple of 3 float
        Where it is now, camera frame, metres.
    grasp_pixel : tuple of 2 float or None
    place_point : tuple of 3 float
        Where the path puts it down (before any drag).
    path : tuple of Waypoint
    lift_height : float
        The path's highest point above the table, m.
    speeds : dict
        ``{"lift_m_s", "carry_m_s"}``: the speeds the times come from.
    """

    grasps: str
    grasp_point: tuple[float, float, float]
    grasp_pixel: tuple[float, float] | None
    place_point: tuple[float, float, float]
    path: tuple[Waypoint, ...]
    lift_height: float
    speeds: dict[str, float]

    def to_json(self) -> dict[str, Any]:
        """``{"grasp": {"point", "pixel", "what"}, "place": {"point"}, "path": [...],
        "lift_height", "speeds"}``."""

        def pt(p: Any, nd: int = 5) -> Any:
            return None if p is None else [round(float(v), nd) for v in p]

        return {
            "grasp": {"point": pt(self.grasp_point), "pixel": pt(self.grasp_pixel, 1),
                      "what": self.grasps},
            "place": {"point": pt(self.place_point)},
            "path": [w.to_json() for w in self.path],
            "lift_height": round(self.lift_height, 4),
            "speeds": self.speeds,
        }


def _arc(
    grasp: NDArray, place: NDArray, foot: NDArray, up: NDArray, params: MotionParams
) -> NDArray[np.float64]:
    """The arc's points (arc_points, 3): from ``grasp`` over the fold line (through
    ``foot``, the grasp's foot on it) to ``place``, its distance from the line shrunk
    to ``arc_ratio`` at the top. The ends' heights above the table are blended along."""
    h0, h1 = float(np.dot(grasp - foot, up)), float(np.dot(place - foot, up))
    out_g = grasp - foot - h0 * up  # along the table, from the line to the grasp
    r = float(np.linalg.norm(out_g))
    side = out_g / r
    theta = np.linspace(0.0, np.pi, params.arc_points)
    shrink = 1.0 - (1.0 - params.arc_ratio) * np.sin(theta)
    far = float(np.dot(place - foot, -side))  # the place's distance on the other side
    radius = r + (far - r) * theta / np.pi  # from the grasp's distance to the place's
    across = np.cos(theta)[:, None] * side * np.where(theta < np.pi / 2, r, far)[:, None]
    across *= shrink[:, None]
    height = (shrink * radius * np.sin(theta))[:, None] * up
    ends = (h0 + (h1 - h0) * theta / np.pi)[:, None] * up
    pts = foot + across + height + ends
    along = place - foot - h1 * up + far * side  # the place's offset along the line
    pts += (theta / np.pi)[:, None] * along
    pts[0], pts[-1] = grasp, place
    return pts


def _timed(
    legs: list[tuple[str, list[NDArray], str, float]], grip_s: float
) -> list[tuple[float, str, str]]:
    """Times, gripper states and phases of the waypoints of every hand, from the legs
    ``(phase, [segment length per hand], gripper after, speed)``."""
    t, out = 0.0, []
    for phase, lengths, gripper, speed in legs:
        if phase in ("grasp", "release"):
            t += grip_s if speed == 0 else max(lengths) / speed
        else:
            t += max(lengths) / speed
        out.append((t, gripper, phase))
    return out


def hands_motion(
    grasps: list[tuple[str, NDArray, tuple[float, float] | None, NDArray]],
    line: tuple[NDArray, NDArray],
    up: NDArray,
    params: MotionParams = DEFAULT_MOTION,
) -> tuple[Hand, ...]:
    """The hands of one step.

    Parameters
    ----------
    grasps : list of (what, grasp point, grasp pixel, place point)
        One per hand, camera frame, metres; the place points on the far side of the
        fold line (for a fold, each grasp's mirror image).
    line : (ndarray, ndarray)
        The fold line's two ends on the table, camera frame.
    up : ndarray, shape (3,)
        The table's normal, towards the camera side the cloth is on (unit).
    params : MotionParams

    Returns
    -------
    tuple of Hand
    """
    a, b = (np.asarray(p, dtype=float) for p in line)
    up = np.asarray(up, dtype=float) / np.linalg.norm(up)
    along = (b - a) / np.linalg.norm(b - a)
    paths = []
    for _what, g, _px, p in grasps:
        g, p = np.asarray(g, dtype=float), np.asarray(p, dtype=float)
        foot = a + np.dot(g - a, along) * along
        foot -= np.dot(foot - a, up) * up  # on the table
        side = g - foot
        side -= np.dot(side, up) * up
        side /= np.linalg.norm(side)
        p = p - params.place_offset_m * side  # away from the line, on the far side
        arc = _arc(g, p, foot, up, params)
        drag = p - params.drag_m * side
        paths.append((g + params.approach_m * up, g, arc, drag, p))
    pts_of: list[list[NDArray]] = [[] for _ in paths]
    legs: list[tuple[str, list[float], str, float]] = []

    def leg(phase: str, points: list[NDArray], gripper: str, speed: float) -> None:
        lengths = [float(np.linalg.norm(q - (pts[-1] if pts else q)))
                   for q, pts in zip(points, pts_of)]
        for q, pts in zip(points, pts_of):
            pts.append(q)
        legs.append((phase, lengths, gripper, speed))

    leg("approach", [w[0] for w in paths], "open", params.lift_speed_m_s)
    leg("grasp", [w[1] for w in paths], "closed", params.lift_speed_m_s)
    leg("grasp", [w[1] for w in paths], "closed", 0.0)  # the gripper closes
    n = params.arc_points
    for k in range(1, n):
        phase = "lift" if k <= n // 4 else ("lower" if k >= n - n // 4 else "carry")
        leg(phase, [w[2][k] for w in paths], "closed", params.carry_speed_m_s)
    if params.drag_m > 0:
        leg("drag", [w[3] for w in paths], "closed", params.carry_speed_m_s)
    leg("release", [pts[-1] for pts in pts_of], "open", 0.0)
    leg("retreat", [pts[-1] + params.approach_m * up for pts in pts_of], "open",
        params.lift_speed_m_s)
    times = _timed(legs, params.grip_s)
    hands = []
    for (what, g, px, _p), w, pts in zip(grasps, paths, pts_of):
        start = Waypoint(tuple(float(v) for v in pts[0]), 0.0, "open", "approach")
        rest = [Waypoint(tuple(float(v) for v in q), t, gr, ph)
                for q, (t, gr, ph) in zip(pts[1:], times[1:])]
        table = float(np.dot(w[1], up))
        peak = max(float(np.dot(q, up)) for q in w[2]) - table
        hands.append(Hand(what, tuple(float(v) for v in g), px, tuple(float(v) for v in w[4]),
                          (start, *rest), peak,
                          {"lift_m_s": params.lift_speed_m_s,
                           "carry_m_s": params.carry_speed_m_s}))
    return tuple(hands)
