"""What the capture conditions add to the scene's geometry: solids on the table (objects,
black mats), a gripper and its arm over the napkin or holding a corner (``clutter``,
``depth``, ``gripper``, ``grasp``), and the napkin turned over (``backface``).

The condition catalogue is :mod:`dgli_vision.sim.conditions`, which re-exports these names.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ..core.layout import NapkinLayout, default_layout
from .cloth.states import ClothState, boundary_uv, sticker_visibility

if TYPE_CHECKING:
    from .condition_params import Conditions, Grasp

__all__ = [
    "SceneObject",
    "grasp_frame",
    "held_corner",
    "held_gripper",
    "scene_objects",
    "turn_over",
]


@dataclass(frozen=True)
class SceneObject:
    """A solid added to the scene.

    Attributes
    ----------
    vertices : ndarray, shape (n, 3)
        World coordinates, metres.
    triangles : ndarray of int, shape (k, 3)
    albedo : tuple of float
        Linear RGB in [0, 1].
    has_depth : bool
        False for surfaces the depth sensor cannot read (black mats).
    kind : str
        What it is (``"cup"``, ``"gripper"``...).
    """

    vertices: NDArray[np.float64]
    triangles: NDArray[np.int32]
    albedo: tuple[float, float, float]
    has_depth: bool = True
    kind: str = ""


def turn_over(
    state: ClothState, axis_deg: float, layout: NapkinLayout | None = None
) -> ClothState:
    """The cloth turned over, back face up: rotated 180 degrees about the horizontal axis
    at azimuth ``axis_deg`` through its centre, and laid back on the table.

    The order of the layers reverses (the bottom layer is now on top). The stickers are
    printed on both faces at the same material points, so they stay where the cloth
    carries them. Class and variant are kept: they are the front-up state's.
    """
    layout = layout or default_layout()
    xyz = state.mesh.xyz
    centre = xyz[:, :2].mean(axis=0)
    a = np.radians(axis_deg)
    axis = np.array([np.cos(a), np.sin(a)])
    d = xyz[:, :2] - centre
    out = np.empty_like(xyz)
    out[:, :2] = centre + 2 * (d @ axis)[:, None] * axis - d  # 180 degrees about the axis
    out[:, 2] = xyz[:, 2].max() + xyz[:, 2].min() - xyz[:, 2]  # lowest layer back on the table
    mesh = state.mesh.with_xyz(out)
    return replace(
        state,
        mesh=mesh,
        sticker_points=mesh.interpolate(layout.sticker_uv),
        visible_fraction=sticker_visibility(mesh, layout, thickness_m=layout.thickness_mm * 1e-3),
        corner_points=mesh.interpolate(layout.corner_uv),
        boundary=mesh.interpolate(boundary_uv(layout)),
        params={**state.params, "turned_over_axis_deg": float(axis_deg)},
    )


def held_corner(fold_word: str, grasp: Grasp) -> str:
    """The corner a gripper holds while making a fold (a word of
    :func:`dgli_vision.core.fold_graph.folds_of`: ``"B over"``, ``"AB strip over"``...): the
    folded corner, or one of the folded side's two."""
    where = fold_word.split()[0]
    return where if len(where) == 1 else where[grasp.corner % 2]


def grasp_frame(
    state: ClothState, corner: str, layout: NapkinLayout | None = None
) -> tuple[NDArray, NDArray, NDArray]:
    """Where a gripper takes a corner of the cloth: the corner's tip (3,), world metres;
    the unit direction out of the cloth from the tip, in the cloth's plane there; and the
    unit normal of the cloth at the tip."""
    layout = layout or default_layout()
    k = "ABCD".index(corner)
    c = layout.corner_uv
    here = c[k]
    e_out = (c[(k + 1) % 4] - here) / np.linalg.norm(c[(k + 1) % 4] - here)
    e_in = (c[(k - 1) % 4] - here) / np.linalg.norm(c[(k - 1) % 4] - here)
    tip, p_out, p_in, inner = state.mesh.interpolate(
        np.stack([here, here + 15 * e_out, here + 15 * e_in, here + 10 * (e_out + e_in)])
    )
    normal = np.cross(p_out - tip, p_in - tip)
    normal /= np.linalg.norm(normal)
    away = tip - inner
    away -= (away @ normal) * normal
    return tip, away / np.linalg.norm(away), normal


def _box_in_frame(origin: NDArray, axes: NDArray, lo: tuple, hi: tuple):
    """A box given in the frame ``axes`` (3 x 3, columns) at ``origin``, world vertices."""
    v, t = _box(np.asarray(lo, np.float64), np.asarray(hi, np.float64))
    return origin + v @ axes.T, t


def held_gripper(
    tip: NDArray,
    away: NDArray,
    normal: NDArray,
    rng: np.random.Generator,
    centre: NDArray | None = None,
) -> SceneObject:
    """A dark two-finger gripper whose fingers close on the cloth at a corner's tip, and
    its arm going up and away.

    The fingers (8 mm thick, 20 mm wide) lie on either side of the cloth, 12 mm over the
    tip; the palm is beyond the tip; the arm rises gently (about 22 degrees) away from the
    napkin's ``centre`` (world, optional), where the robot stands.
    """
    side = np.cross(normal, away)
    axes = np.stack([away, side, normal], axis=1)
    gap = 0.0015  # half the opening: a cloth thickness and a little
    parts = [
        _box_in_frame(tip, axes, (-0.012, -0.01, gap), (0.038, 0.01, gap + 0.008)),
        _box_in_frame(tip, axes, (-0.012, -0.01, -gap - 0.008), (0.038, 0.01, -gap)),
        _box_in_frame(tip, axes, (0.038, -0.035, -0.025), (0.075, 0.035, 0.025)),
    ]
    palm = tip + 0.056 * away
    level = np.zeros(3)
    if centre is not None and np.linalg.norm(tip[:2] - centre[:2]) > 0.05:
        level[:2] = (tip[:2] - centre[:2]) / np.linalg.norm(tip[:2] - centre[:2])
    elif np.linalg.norm(away[:2]) > 0.3:  # the tip is near the middle: along the fingers
        level[:2] = away[:2]
    else:  # and the fingers upright: sideways
        level[:2] = side[:2]
    rise = level / np.linalg.norm(level) + np.array([0.0, 0.0, 0.4])
    rise /= np.linalg.norm(rise)
    for k in range(6):
        c = palm + rise * (0.07 + 0.07 * k)
        parts.append(_box(c - 0.035, c + 0.035))
    v, t = _merged(parts)
    dark = tuple(float(x) for x in rng.uniform(0.02, 0.06) * np.ones(3))
    return SceneObject(v, t, dark, kind="gripper")


# --- scene geometry --------------------------------------------------------------------


def _box(lo: NDArray, hi: NDArray) -> tuple[NDArray, NDArray]:
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    v = np.array(
        [[x, y, z] for z in (z0, z1) for y in (y0, y1) for x in (x0, x1)], dtype=np.float64
    )
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    t = [(a, b, c) for a, b, c, d in quads] + [(a, c, d) for a, b, c, d in quads]
    return v, np.array(t, np.int32)


def _cylinder(centre: NDArray, radius: float, z0: float, z1: float, n: int = 32):
    ang = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([centre[0] + radius * np.cos(ang), centre[1] + radius * np.sin(ang)], 1)
    v = np.concatenate(
        [
            np.column_stack([ring, np.full(n, z0)]),
            np.column_stack([ring, np.full(n, z1)]),
            [[centre[0], centre[1], z0], [centre[0], centre[1], z1]],
        ]
    )
    k = np.arange(n)
    k1 = (k + 1) % n
    side = np.concatenate([np.stack([k, k1, n + k1], 1), np.stack([k, n + k1, n + k], 1)])
    caps = np.concatenate(
        [
            np.stack([np.full(n, 2 * n), k1, k], 1),
            np.stack([np.full(n, 2 * n + 1), n + k, n + k1], 1),
        ]
    )
    return v, np.concatenate([side, caps]).astype(np.int32)


def _rotate_z(v: NDArray, centre: NDArray, angle: float) -> NDArray:
    c, s = np.cos(angle), np.sin(angle)
    out = v.copy()
    d = v[:, :2] - centre[:2]
    out[:, 0] = centre[0] + c * d[:, 0] - s * d[:, 1]
    out[:, 1] = centre[1] + s * d[:, 0] + c * d[:, 1]
    return out


#: Saturated object colours (linear RGB): the sticker hues themselves and their neighbours.
_OBJECT_COLOURS = (
    (0.67, 0.02, 0.02),  # sticker red
    (0.83, 0.58, 0.007),  # sticker yellow
    (0.013, 0.35, 0.045),  # sticker green
    (0.013, 0.08, 0.58),  # sticker blue
    (0.9, 0.25, 0.01),  # orange
    (0.5, 0.02, 0.35),  # magenta
    (0.02, 0.4, 0.45),  # teal
)


def _free_spot(
    rng: np.random.Generator,
    keep_out: tuple[NDArray, NDArray],
    view: tuple[NDArray, NDArray],
    size_m: float,
) -> NDArray | None:
    lo, hi = keep_out
    for _ in range(200):
        p = rng.uniform(view[0], view[1])
        if np.all(p > lo - size_m) and np.all(p < hi + size_m):
            continue
        return p
    return None


def _merged(parts: list[tuple[NDArray, NDArray]]) -> tuple[NDArray, NDArray]:
    """One solid of several (vertices, triangles) parts: vertices stacked, triangle
    indices shifted to match."""
    vs, ts, n = [], [], 0
    for v, t in parts:
        vs.append(v)
        ts.append(t + n)
        n += len(v)
    return np.concatenate(vs), np.concatenate(ts)


_CLUTTER_SIZES_M = {"cup": 0.05, "box": 0.06, "cap": 0.02, "tape": 0.08, "post-it": 0.04}


def _clutter_shape(kind: str, p: NDArray, rng: np.random.Generator) -> tuple[NDArray, NDArray]:
    """Vertices and triangles of one object of ``kind`` standing at table point ``p``."""
    if kind == "cup":
        return _cylinder(p, rng.uniform(0.035, 0.045), 0.0, rng.uniform(0.08, 0.11))
    if kind == "cap":
        return _cylinder(p, rng.uniform(0.012, 0.018), 0.0, rng.uniform(0.008, 0.015))
    if kind == "box":
        half = rng.uniform(0.025, 0.05, 2)
        return _box(np.r_[p - half, 0.0], np.r_[p + half, rng.uniform(0.03, 0.1)])
    if kind == "tape":
        half = np.array([rng.uniform(0.05, 0.09), rng.uniform(0.01, 0.013)])
        return _box(np.r_[p - half, 0.0], np.r_[p + half, 0.0005])
    return _box(np.r_[p - 0.038, 0.0], np.r_[p + 0.038, 0.0005])  # post-it


def _clutter(
    count: int,
    rng: np.random.Generator,
    keep_out: tuple[NDArray, NDArray],
    view_xy: tuple[NDArray, NDArray],
) -> list[SceneObject]:
    """Up to ``count`` saturated objects on the table, off the napkin (``keep_out``)."""
    objects = []
    for _ in range(count):
        kind = str(rng.choice(["cup", "box", "cap", "tape", "post-it"]))
        albedo = _OBJECT_COLOURS[int(rng.integers(len(_OBJECT_COLOURS)))]
        p = _free_spot(rng, keep_out, view_xy, _CLUTTER_SIZES_M[kind] + 0.01)
        if p is None:
            continue
        v, t = _clutter_shape(kind, p, rng)
        if kind == "post-it":
            albedo = (0.85, 0.75, 0.02)
        v = _rotate_z(v, p, rng.uniform(0, np.pi))
        objects.append(SceneObject(v, t, albedo, kind=kind))
    return objects


def _black_mats(
    rng: np.random.Generator,
    keep_out: tuple[NDArray, NDArray],
    view_xy: tuple[NDArray, NDArray],
) -> list[SceneObject]:
    """One or two black mats on the table, which the depth sensor cannot read."""
    objects = []
    for _ in range(int(rng.integers(1, 3))):
        p = _free_spot(rng, keep_out, view_xy, 0.05)
        if p is None:
            continue
        half = rng.uniform(0.04, 0.12, 2)
        v, t = _box(np.r_[p - half, -1.9e-4], np.r_[p + half, -1.5e-4])
        objects.append(
            SceneObject(
                _rotate_z(v, p, rng.uniform(0, np.pi)),
                t,
                (0.015, 0.015, 0.015),
                has_depth=False,
                kind="mat",
            )
        )
    return objects


def _hovering_gripper(
    height_m: float,
    napkin_xyz: NDArray[np.float64],
    keep_out: tuple[NDArray, NDArray],
    rng: np.random.Generator,
) -> SceneObject:
    """A dark open gripper ``height_m`` above the napkin's top, and its arm going up and out
    of the napkin's area."""
    lo, hi = keep_out
    top = float(napkin_xyz[:, 2].max())
    p = rng.uniform(lo + 0.03, hi - 0.03)
    yaw = rng.uniform(0, 2 * np.pi)
    z0 = top + height_m
    dark = tuple(float(x) for x in rng.uniform(0.02, 0.06) * np.ones(3))
    parts = []
    for dx in (-0.03, 0.03):  # two fingers
        parts.append(
            _box(
                np.r_[p[0] + dx - 0.008, p[1] - 0.012, z0],
                np.r_[p[0] + dx + 0.008, p[1] + 0.012, z0 + 0.05],
            )
        )
    parts.append(
        _box(
            np.r_[p - np.array([0.045, 0.03]), z0 + 0.05],
            np.r_[p + np.array([0.045, 0.03]), z0 + 0.12],
        )
    )
    # the arm: from the wrist outwards and upwards, out of the napkin's area
    arm_dir = rng.uniform(0, 2 * np.pi)
    reach = np.array([np.cos(arm_dir), np.sin(arm_dir)])
    for k in range(6):
        c = p + reach * (0.03 + 0.07 * k)
        parts.append(
            _box(np.r_[c - 0.04, z0 + 0.12 + 0.02 * k], np.r_[c + 0.04, z0 + 0.2 + 0.02 * k])
        )
    v, t = _merged(parts)
    return SceneObject(_rotate_z(v, np.r_[p, 0.0], yaw), t, dark, kind="gripper")


def scene_objects(
    conditions: Conditions,
    napkin_xyz: NDArray[np.float64],
    view_xy: tuple[NDArray, NDArray],
    held: tuple[NDArray, NDArray, NDArray] | None = None,
) -> list[SceneObject]:
    """The solids a condition adds: objects on the table, black mats, a gripper and arm.

    Parameters
    ----------
    conditions : Conditions
    napkin_xyz : ndarray, shape (n, 3)
        The cloth's mesh vertices, world metres (objects keep off it, the gripper is over it).
    view_xy : tuple of ndarray
        Lower and upper world (x, y) of the table area the camera sees.
    held : tuple of ndarray, optional
        The corner a gripper holds (:func:`grasp_frame`), under ``grasp``.

    Returns
    -------
    list of SceneObject
    """
    rng = np.random.default_rng([conditions.seed, 11])
    napkin = (napkin_xyz[:, :2].min(axis=0), napkin_xyz[:, :2].max(axis=0))
    objects = _clutter(conditions.clutter, rng, napkin, view_xy)
    if conditions.realistic_depth:
        objects += _black_mats(rng, napkin, view_xy)
    if conditions.gripper_height_m is not None:
        objects.append(_hovering_gripper(conditions.gripper_height_m, napkin_xyz, napkin, rng))
    if held is not None:
        objects.append(held_gripper(*held, rng, centre=napkin_xyz.mean(axis=0)))
    return objects
