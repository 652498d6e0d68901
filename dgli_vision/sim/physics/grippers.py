"""Simulated grippers: move each hand along its timed path, hold and let go, settle.

A hand's path is a list of timed waypoints in the sim frame (:mod:`.model`) with the
gripper's state from each waypoint to the next (:class:`HandPath`); between waypoints
the hand moves in a straight line at constant speed. When a gripper closes, its
``connect`` equality is switched on with the grasped vertex where it is then (no snap),
so the vertex follows the hand; when it opens the equality is switched off. After the
last waypoint the cloth settles with every gripper open.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ...core.errors import InvalidValueError
from . import require_mujoco
from .model import ClothModel

__all__ = ["Execution", "HandPath", "execute"]


@dataclass(frozen=True, eq=False)
class HandPath:
    """One hand's motion.

    Attributes
    ----------
    t_s : ndarray, shape (k,)
        Waypoint times, s, increasing.
    points : ndarray, shape (k, 3)
        Waypoints, sim frame, metres.
    closed : ndarray of bool, shape (k,)
        The gripper is closed from waypoint i to waypoint i + 1 (the last: after it).
    """

    t_s: NDArray[np.float64]
    points: NDArray[np.float64]
    closed: NDArray[np.bool_]

    def __post_init__(self) -> None:
        k = len(self.t_s)
        if k < 2 or np.shape(self.points) != (k, 3) or np.shape(self.closed) != (k,):
            raise InvalidValueError(
                f"a hand's path needs k >= 2 times, (k, 3) points and k gripper states; "
                f"got {np.shape(self.t_s)}, {np.shape(self.points)}, {np.shape(self.closed)}"
            )
        if np.any(np.diff(self.t_s) < 0):
            raise InvalidValueError("a hand's waypoint times must not decrease")

    def at(self, t: float) -> tuple[NDArray[np.float64], bool]:
        """Where the hand is at time ``t`` and whether its gripper is closed."""
        i = int(np.searchsorted(self.t_s, t, side="right")) - 1
        if i < 0:
            return self.points[0].copy(), False
        if i >= len(self.t_s) - 1:
            return self.points[-1].copy(), bool(self.closed[-1])
        span = self.t_s[i + 1] - self.t_s[i]
        f = 0.0 if span <= 0 else (t - self.t_s[i]) / span
        return self.points[i] + f * (self.points[i + 1] - self.points[i]), bool(self.closed[i])


@dataclass(frozen=True, eq=False)
class Execution:
    """What a run did.

    Attributes
    ----------
    xyz : ndarray, shape (n, 3)
        The grid's vertices once settled, sim frame, metres.
    held : ndarray, shape (hands, 3)
        Where each grasped vertex was when its gripper last opened (nan: never held).
    steps : int
        Simulator steps taken.
    settled : bool
        The cloth came to rest (every vertex slower than ``rest_m_s``) before the
        settling time ran out.
    """

    xyz: NDArray[np.float64]
    held: NDArray[np.float64]
    steps: int
    settled: bool


def _switch(cm: ClothModel, k: int, hand: NDArray, on: bool) -> None:
    """Close (``on``) or open hand ``k``'s gripper on its vertex, where it lies now."""
    eq = cm.model.eq(f"grip{k}").id
    if on:
        vertex = cm.data.flexvert_xpos[cm.flex_index[cm.hand_vertices[k]]]
        cm.model.eq_data[eq, 0:3] = vertex - hand
        cm.model.eq_data[eq, 3:6] = 0.0
    cm.data.eq_active[eq] = on


def execute(
    cm: ClothModel,
    paths: list[HandPath],
    *,
    settle_s: float = 1.5,
    rest_m_s: float = 0.01,
) -> Execution:
    """Move the hands of ``cm`` along ``paths`` (one per hand), then let the cloth
    settle with every gripper open for at most ``settle_s`` (stopping once every vertex
    is slower than ``rest_m_s``).

    Returns
    -------
    Execution
    """
    mujoco = require_mujoco()
    if len(paths) != len(cm.hand_vertices):
        raise InvalidValueError(f"{len(cm.hand_vertices)} hands, {len(paths)} paths")
    dt = cm.model.opt.timestep
    end = max((float(p.t_s[-1]) for p in paths), default=0.0)
    closed = [False] * len(paths)
    held = np.full((len(paths), 3), np.nan)
    steps = 0
    for step in range(int(np.ceil(end / dt))):
        t = (step + 1) * dt
        for k, p in enumerate(paths):
            where, shut = p.at(t)
            cm.data.mocap_pos[k] = where
            if shut != closed[k]:
                if not shut:
                    held[k] = cm.data.flexvert_xpos[cm.flex_index[cm.hand_vertices[k]]]
                _switch(cm, k, where, shut)
                closed[k] = shut
        mujoco.mj_step(cm.model, cm.data)
        steps += 1
    for k in range(len(paths)):
        if closed[k]:
            held[k] = cm.data.flexvert_xpos[cm.flex_index[cm.hand_vertices[k]]]
            _switch(cm, k, cm.data.mocap_pos[k], False)
    settled = False
    for step in range(int(np.ceil(settle_s / dt))):
        mujoco.mj_step(cm.model, cm.data)
        steps += 1
        if step % 25 == 24 and float(np.abs(cm.data.qvel).max()) < rest_m_s:
            settled = True
            break
    return Execution(cm.positions(), held, steps, settled)
