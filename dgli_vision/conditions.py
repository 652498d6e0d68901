"""Capture conditions for the renderer: what real cameras and real labs add to SPEC's scene.

Each named condition (DESIGN.md, "Capture conditions the tool must survive") is drawn
from a seeded generator into one frozen :class:`Conditions`; the renderer
(:func:`dgli_vision.render.render`) applies it. Scene conditions add geometry or change
appearance (a wood table, objects, a gripper and arm, a shadow, glossy stickers); sensor
conditions change the images (a colour cast, dim exposure and noise, JPEG, lens
distortion, realistic depth); ``vga`` changes the camera (see
:func:`dgli_vision.dataset.render_samples`).

The figures are the ranges of the robust-perception issue; they are ours, drawn to cover
each condition, not tuned to any held-out set.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from .camera import Intrinsics
from .cloth.states import ClothState, boundary_uv, sticker_visibility
from .condition_names import COMBO_POOL, CONDITION_HELP, CONDITION_NAMES
from .layout import NapkinLayout, default_layout

__all__ = [
    "CONDITION_HELP",
    "CONDITION_NAMES",
    "Conditions",
    "Grasp",
    "SceneObject",
    "Sheen",
    "apply_lens_distortion",
    "area_light_lobe",
    "draw_conditions",
    "draw_lens",
    "grasp_frame",
    "held_corner",
    "held_gripper",
    "jpeg_roundtrip",
    "mirror_light_direction",
    "realistic_depth",
    "scene_objects",
    "specular_for_saturation",
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


@dataclass(frozen=True)
class Sheen:
    """A large area light (a softbox, a window) mirrored in semi-gloss vinyl stickers.

    The light is placed where the mirror direction of one sticker points, so the
    Blinn-Phong lobe of the vinyl washes that sticker and its neighbours to pastel; the
    napkin's fabric adds a broad, weak sheen of the same light.

    Attributes
    ----------
    shininess : float
        Blinn-Phong exponent of the stickers' vinyl (150-600).
    light_radius_deg : float
        Angular radius of the area light seen from the napkin, degrees.
    saturation : float
        HSV saturation the stickers reach where the lobe is full (0.1-0.3); the specular
        strength is solved for it.
    cloth_strength : float
        Peak of the fabric's sheen, linear light (relative to a white of 1).
    cloth_shininess : float
        Blinn-Phong exponent of the fabric's broad sheen.
    """

    shininess: float
    light_radius_deg: float
    saturation: float
    cloth_strength: float
    cloth_shininess: float


@dataclass(frozen=True)
class Grasp:
    """A robot's gripper holding the corner it folds (``grasp``).

    Attributes
    ----------
    settle_deg : float
        How far the held fold has turned from flat, degrees: 100-170 (a fold in progress,
        past 90 so the state is already the folded class), or 180 (laid flat, finished,
        still held).
    rise_deg : float
        For a flat napkin (class 01): the first fold of a corner lifted this far, degrees
        (20-80, below 90 so the state is still flat by the 90-degree rule).
    corner : int
        Which corner that first fold takes (0-3 for A-D); its parity also picks which of a
        side's two corners the gripper holds when a whole side is folded.
    """

    settle_deg: float
    rise_deg: float
    corner: int


@dataclass(frozen=True)
class Conditions:
    """Capture conditions of one render; the default is SPEC's clean scene.

    Attributes
    ----------
    names : tuple of str
        The named conditions drawn (for labels and reports).
    seed : int
        Seeds the placement of objects, mats, the shadow and the highlight.
    colour_gains : tuple of float
        Per-channel gains in linear light (a colour cast), 1 = balanced.
    exposure : float
        Exposure relative to normal (linear light).
    colour_noise : float or None
        Sensor noise sigma in 8-bit levels, overriding the sensor model's.
    jpeg_quality : int or None
        Round-trip the colour image through JPEG at this quality.
    highlight : bool
        Glossy stickers with a lamp's mirror highlight on one of them.
    sheen : Sheen or None
        Semi-gloss stickers under a large light: a corner's stickers washed to pastel.
    shadow : float
        Fraction of the light a soft arm shadow across the napkin blocks (0 = none).
    clutter : int
        Number of saturated objects on the table around the napkin.
    gripper_height_m : float or None
        Height of a dark gripper's lowest point above the napkin's top, metres.
    distortion : tuple of float
        OpenCV's distortion coefficients ``(k1, k2, p1, p2, k3)`` of the lens; empty for
        an ideal one.
    distortion_known : bool
        The lens is the set's own and its coefficients are written with the intrinsics
        (``distortion-known``); otherwise the intrinsics say nothing of it.
    realistic_depth : bool
        Flying pixels, parallax holes, registration offset, more noise, black mats.
    depth_noise_mm : float
        Depth noise sigma at 0.5 m with ``realistic_depth``, mm.
    registration_px : tuple of int
        Offset (du, dv) of the depth image against colour, pixels.
    wood_table : bool
        A light-wood table instead of a matte grey one.
    mirror : bool
        The camera mirrors its image: colour and depth flipped left to right together,
        intrinsics unchanged.
    backface_axis_deg : float or None
        The napkin lies back face up: the cloth turned over about a horizontal axis at
        this azimuth (degrees) through its centre (:func:`turn_over`).
    depth_scale : float
        Depth in the wrong units: every reading multiplied by this factor.
    grasp : Grasp or None
        A gripper holds the corner being folded (the state's ``params["held_corner"]``).
    """

    names: tuple[str, ...] = ()
    seed: int = 0
    colour_gains: tuple[float, float, float] = (1.0, 1.0, 1.0)
    exposure: float = 1.0
    colour_noise: float | None = None
    jpeg_quality: int | None = None
    highlight: bool = False
    sheen: Sheen | None = None
    shadow: float = 0.0
    clutter: int = 0
    gripper_height_m: float | None = None
    distortion: tuple[float, ...] = ()
    distortion_known: bool = False
    realistic_depth: bool = False
    depth_noise_mm: float = 1.0
    registration_px: tuple[int, int] = (0, 0)
    wood_table: bool = False
    mirror: bool = False
    backface_axis_deg: float | None = None
    depth_scale: float = 1.0
    grasp: Grasp | None = None

    @property
    def distortion_k1(self) -> float:
        """The lens's first radial coefficient (0 for an ideal lens)."""
        return float(self.distortion[0]) if self.distortion else 0.0

    @property
    def label(self) -> str:
        """``"clean"`` or the names joined by ``+``."""
        return "+".join(self.names) or "clean"


def _draw_one(name: str, c: Conditions, rng: np.random.Generator) -> Conditions:
    if name == "jpeg":
        return replace(c, jpeg_quality=int(rng.integers(70, 93)))
    if name == "cast":
        if rng.random() < 0.6:  # tungsten
            gains = (rng.uniform(1.25, 1.45), 1.0, rng.uniform(0.55, 0.72))
        else:  # daylight through a window / LED: blue
            gains = (rng.uniform(0.6, 0.78), rng.uniform(0.9, 1.0), rng.uniform(1.25, 1.45))
        return replace(c, colour_gains=tuple(float(g) for g in gains))
    if name == "dim":
        return replace(c, exposure=float(rng.uniform(0.35, 0.55)), colour_noise=rng.uniform(6, 10))
    if name == "gloss":
        return replace(c, highlight=True)
    if name == "sheen":
        sheen = Sheen(
            shininess=float(rng.uniform(150, 600)),
            light_radius_deg=float(rng.uniform(5, 9)),
            saturation=float(rng.uniform(0.15, 0.27)),
            cloth_strength=float(rng.uniform(0.1, 0.25)),
            cloth_shininess=float(rng.uniform(30, 80)),
        )
        return replace(c, sheen=sheen)
    if name == "shadow":
        return replace(c, shadow=float(rng.uniform(0.35, 0.6)))
    if name == "clutter":
        return replace(c, clutter=int(rng.integers(3, 7)))
    if name == "gripper":
        return replace(c, gripper_height_m=float(rng.uniform(0.06, 0.20)))
    if name == "distortion":
        return replace(c, distortion=draw_lens(rng))
    if name == "distortion-known":
        return replace(c, distortion=draw_lens(rng), distortion_known=True)
    if name == "depth":
        off = rng.integers(1, 4) * rng.choice([-1, 1], 2) * (rng.random(2) < 0.7)
        if not off.any():
            off[0] = 1
        return replace(
            c,
            realistic_depth=True,
            depth_noise_mm=float(rng.uniform(2.0, 4.0)),
            registration_px=(int(off[0]), int(off[1])),
        )
    if name in ("vga", "clean"):
        return c  # the camera is chosen by the data set
    if name == "wood":
        return replace(c, wood_table=True)
    if name == "mirror":
        return replace(c, mirror=True)
    if name == "backface":
        return replace(c, backface_axis_deg=float(rng.uniform(0, 180)))
    if name == "grasp":
        settle = 180.0 if rng.random() < 1 / 3 else float(rng.uniform(100, 170))
        grasp = Grasp(settle, float(rng.uniform(20, 80)), int(rng.integers(4)))
        return replace(c, grasp=grasp)
    if name == "depthscale":
        if rng.random() < 0.5:  # a round wrong unit factor
            scale = float(rng.choice([0.8, 1.25]))
        else:
            scale = float(rng.uniform(0.75, 0.85) if rng.random() < 0.5 else rng.uniform(1.2, 1.3))
        return replace(c, depth_scale=scale)
    raise ValueError(f"unknown condition {name!r}; expected one of {', '.join(CONDITION_NAMES)}")


def draw_lens(rng: np.random.Generator) -> tuple[float, float, float, float, float]:
    """OpenCV distortion coefficients ``(k1, k2, p1, p2, k3)`` of a lens: radial k1
    0.06-0.12 and k2 -0.06-0, tangential p1, p2 within +-0.002, k3 = 0."""
    k1 = float(rng.uniform(0.06, 0.12))
    k2 = float(rng.uniform(-0.06, 0.0))
    p1, p2 = (float(p) for p in rng.uniform(-0.002, 0.002, 2))
    return (k1, k2, p1, p2, 0.0)


def draw_conditions(names: Iterable[str], rng: np.random.Generator) -> Conditions:
    """Draw the parameters of the named conditions.

    Parameters
    ----------
    names : iterable of str
        Names from :data:`CONDITION_NAMES`; ``"combo"`` draws three conditions of
        :data:`~dgli_vision.condition_names.COMBO_POOL`.
    rng : Generator

    Returns
    -------
    Conditions
    """
    chosen: list[str] = []
    for name in names:
        if name == "combo":
            pool = [n for n in COMBO_POOL if n not in chosen]
            chosen += [str(n) for n in rng.choice(pool, 3, replace=False)]
        elif name not in chosen:
            chosen.append(name)
    c = Conditions(names=tuple(chosen), seed=int(rng.integers(2**31)))
    for name in chosen:
        c = _draw_one(name, c, rng)
    return c


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
    :func:`dgli_vision.fold_graph.folds_of`: ``"B over"``, ``"AB strip over"``...): the
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
    vs, ts, n = [], [], 0
    for v, t in parts:
        vs.append(v)
        ts.append(t + n)
        n += len(v)
    dark = tuple(float(x) for x in rng.uniform(0.02, 0.06) * np.ones(3))
    return SceneObject(np.concatenate(vs), np.concatenate(ts), dark, kind="gripper")


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
    lo, hi = napkin_xyz[:, :2].min(axis=0), napkin_xyz[:, :2].max(axis=0)
    objects: list[SceneObject] = []
    for _ in range(conditions.clutter):
        kind = str(rng.choice(["cup", "box", "cap", "tape", "post-it"]))
        albedo = _OBJECT_COLOURS[int(rng.integers(len(_OBJECT_COLOURS)))]
        size = {"cup": 0.05, "box": 0.06, "cap": 0.02, "tape": 0.08, "post-it": 0.04}[kind]
        p = _free_spot(rng, (lo, hi), view_xy, size + 0.01)
        if p is None:
            continue
        if kind == "cup":
            v, t = _cylinder(p, rng.uniform(0.035, 0.045), 0.0, rng.uniform(0.08, 0.11))
        elif kind == "cap":
            v, t = _cylinder(p, rng.uniform(0.012, 0.018), 0.0, rng.uniform(0.008, 0.015))
        elif kind == "box":
            half = rng.uniform(0.025, 0.05, 2)
            v, t = _box(np.r_[p - half, 0.0], np.r_[p + half, rng.uniform(0.03, 0.1)])
        elif kind == "tape":
            half = np.array([rng.uniform(0.05, 0.09), rng.uniform(0.01, 0.013)])
            v, t = _box(np.r_[p - half, 0.0], np.r_[p + half, 0.0005])
        else:  # post-it
            v, t = _box(np.r_[p - 0.038, 0.0], np.r_[p + 0.038, 0.0005])
            albedo = (0.85, 0.75, 0.02)
        v = _rotate_z(v, p, rng.uniform(0, np.pi))
        objects.append(SceneObject(v, t, albedo, kind=kind))
    if conditions.realistic_depth:  # one or two black mats on the table, without depth
        for _ in range(int(rng.integers(1, 3))):
            p = _free_spot(rng, (lo, hi), view_xy, 0.05)
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
    if conditions.gripper_height_m is not None:
        top = float(napkin_xyz[:, 2].max())
        p = rng.uniform(lo + 0.03, hi - 0.03)
        yaw = rng.uniform(0, 2 * np.pi)
        z0 = top + conditions.gripper_height_m
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
        n = 0
        vs, ts = [], []
        for v, t in parts:
            vs.append(v)
            ts.append(t + n)
            n += len(v)
        v = _rotate_z(np.concatenate(vs), np.r_[p, 0.0], yaw)
        objects.append(SceneObject(v, np.concatenate(ts), dark, kind="gripper"))
    if held is not None:
        objects.append(held_gripper(*held, rng, centre=napkin_xyz.mean(axis=0)))
    return objects


def wood_albedo(xy: NDArray[np.float64], seed: int) -> NDArray[np.float64]:
    """Linear-RGB albedo (n, 3) of a light-wood table at world points (n, 2) metres.

    sRGB about (205, 172, 135): HSV saturation about 0.3, with grain stripes.
    """
    rng = np.random.default_rng([seed, 13])
    base = np.array([0.61, 0.41, 0.24]) * rng.uniform(0.85, 1.1)
    ang = rng.uniform(0, np.pi)
    t = xy @ np.array([np.cos(ang), np.sin(ang)])
    s = xy @ np.array([-np.sin(ang), np.cos(ang)])
    grain = 0.1 * np.sin(2 * np.pi * t / 0.012 + 3 * np.sin(2 * np.pi * s / 0.3))
    grain += 0.05 * np.sin(2 * np.pi * t / 0.05)
    tint = 1 + grain[:, None] * np.array([0.6, 1.0, 1.6])
    return np.clip(base * tint, 0, 1)


def shadow_factor(xy: NDArray[np.float64], conditions: Conditions, centre: NDArray) -> NDArray:
    """Light left (n,) at world points (n, 2) under a soft arm shadow across the napkin."""
    rng = np.random.default_rng([conditions.seed, 17])
    ang = rng.uniform(0, np.pi)
    normal = np.array([-np.sin(ang), np.cos(ang)])
    offset = rng.uniform(-0.08, 0.08)
    half_width = rng.uniform(0.03, 0.075)
    soft = rng.uniform(0.015, 0.035)
    d = np.abs((xy - centre[:2]) @ normal - offset)
    inside = np.clip((half_width + soft - d) / (2 * soft), 0, 1)
    inside = inside * inside * (3 - 2 * inside)  # smoothstep
    return 1.0 - conditions.shadow * inside


def highlight_spot(conditions: Conditions, sticker_uv: NDArray, visible: NDArray):
    """Material centre (2,) mm and sigma (mm) and peak of the mirror highlight, or None."""
    rng = np.random.default_rng([conditions.seed, 19])
    ids = np.flatnonzero(visible)
    if not conditions.highlight or ids.size == 0:
        return None
    sid = int(rng.choice(ids))
    r = rng.uniform(0, 10.0)
    a = rng.uniform(0, 2 * np.pi)
    centre = sticker_uv[sid] + r * np.array([np.cos(a), np.sin(a)])
    return centre, float(rng.uniform(2.0, 5.0)), float(rng.uniform(1.5, 5.0)), sid


def sheen_sticker(conditions: Conditions, visible: NDArray) -> int | None:
    """Id of the sticker the large light is mirrored in (one the camera sees), or None."""
    ids = np.flatnonzero(visible)
    if conditions.sheen is None or ids.size == 0:
        return None
    return int(np.random.default_rng([conditions.seed, 29]).choice(ids))


def mirror_light_direction(normal: NDArray, view: NDArray) -> NDArray[np.float64]:
    """Unit direction (3,) towards a light whose mirror reflection at a surface of unit
    ``normal`` reaches the viewer in unit direction ``view`` (both from the surface)."""
    n = normal if normal @ view >= 0 else -normal
    light = 2 * (n @ view) * n - view
    return light / np.linalg.norm(light)


def area_light_lobe(
    normals: NDArray,
    views: NDArray,
    light: NDArray,
    radius_rad: float,
    shininess: float,
) -> NDArray[np.float64]:
    """Blinn-Phong specular lobe (n,) in [0, 1] of a disc-shaped area light.

    The light is a disc of angular radius ``radius_rad`` around the unit direction
    ``light``. Each surface point takes the point of the disc nearest its mirror
    direction (the *representative point* of area lights): inside the disc's mirror
    image the lobe is full (1), outside it falls off as ``(n . h) ** shininess`` with the
    half-vector ``h`` between that point and the view.

    Parameters
    ----------
    normals, views : ndarray, shape (n, 3)
        Unit surface normals (either side) and unit directions from the surface to the
        camera.
    """
    n = normals * np.where((normals * views).sum(axis=1) < 0, -1.0, 1.0)[:, None]
    mirror = 2 * (n * views).sum(axis=1)[:, None] * n - views
    cos_off = np.clip(mirror @ light, -1.0, 1.0)
    across = mirror - cos_off[:, None] * light
    norm = np.linalg.norm(across, axis=1)
    across = across / np.maximum(norm, 1e-12)[:, None]
    inside = np.arccos(cos_off) <= radius_rad
    nearest = np.cos(radius_rad) * light + np.sin(radius_rad) * across
    to_light = np.where(inside[:, None], mirror, nearest)
    half = to_light + views
    half /= np.maximum(np.linalg.norm(half, axis=1), 1e-12)[:, None]
    return np.clip((n * half).sum(axis=1), 0.0, 1.0) ** shininess


def specular_for_saturation(
    diffuse: NDArray, saturation: float, *, tint: NDArray | None = None, peak: float = 0.8
) -> float:
    """Grey specular light (linear) that, added to a surface's ``diffuse`` linear RGB (3,),
    leaves it with this HSV ``saturation`` in sRGB (bisection; 0 if already paler).

    ``tint`` (3,) multiplies the added light, as a camera's channel gains do. The sum is
    judged as exposed with its brightest channel at ``peak`` (linear): an exposure that
    keeps it from clipping."""
    from .colour import linear_to_srgb

    grey = np.ones(3) if tint is None else np.asarray(tint, np.float64)

    def sat(extra: float) -> float:
        lin = np.asarray(diffuse, np.float64) + extra * grey
        v = linear_to_srgb(lin * (peak / max(float(lin.max()), 1e-12)))
        return float(1 - v.min() / max(v.max(), 1e-12))

    if sat(0.0) <= saturation:
        return 0.0
    lo, hi = 0.0, 1.0
    while sat(hi) > saturation:
        hi *= 2
    for _ in range(40):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if sat(mid) > saturation else (lo, mid)
    return (lo + hi) / 2


# --- image effects ---------------------------------------------------------------------


def jpeg_roundtrip(rgb: NDArray[np.uint8], quality: int) -> NDArray[np.uint8]:
    """The RGB image as a JPEG of ``quality`` would decode."""
    import cv2

    ok, buf = cv2.imencode(".jpg", rgb[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:  # pragma: no cover - OpenCV always encodes uint8 RGB
        raise RuntimeError("JPEG encoding failed")
    return cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1].copy()


def apply_lens_distortion(
    color: NDArray[np.uint8],
    depth_mm: NDArray[np.uint16],
    intrinsics: Intrinsics,
    coefficients: float | Sequence[float],
) -> tuple[NDArray[np.uint8], NDArray[np.uint16]]:
    """Images as seen through a lens with distortion (OpenCV's model).

    Each output (distorted) pixel takes the value of the ideal pinhole image at its
    undistorted position (OpenCV's ``undistortPoints`` with ``P = K``), colour
    bilinearly, depth from the nearest pixel.

    Parameters
    ----------
    color, depth_mm : ndarray
        The ideal pinhole images.
    intrinsics : Intrinsics
        Its camera matrix is used (its own ``distortion`` is not).
    coefficients : float or sequence of float
        ``k1`` alone (radial), or OpenCV's ``(k1, k2, p1, p2[, k3...])``.
    """
    import cv2

    if np.ndim(coefficients) == 0:
        coefficients = (float(coefficients),)
    d = [float(c) for c in coefficients]
    n = next((k for k in (4, 5, 8, 12, 14) if k >= len(d)), len(d))
    dist = np.array(d + [0.0] * (n - len(d)), np.float64)
    h, w = depth_mm.shape
    vv, uu = np.mgrid[0:h, 0:w].astype(np.float32)
    pts = np.stack([uu.ravel(), vv.ravel()], 1)[:, None, :]
    k = intrinsics.matrix()
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 20, 1e-6)
    und = cv2.undistortPoints(pts, k, dist, P=k, criteria=criteria)
    mx = und[:, 0, 0].reshape(h, w).astype(np.float32)
    my = und[:, 0, 1].reshape(h, w).astype(np.float32)
    color = cv2.remap(color, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    depth = cv2.remap(depth_mm, mx, my, cv2.INTER_NEAREST, borderValue=0)
    return color, depth


def realistic_depth(
    depth_mm: NDArray[np.float64],
    conditions: Conditions,
    rng: np.random.Generator,
) -> NDArray[np.float64]:
    """Flying pixels and parallax holes at depth edges, and the registration offset.

    Parameters
    ----------
    depth_mm : ndarray, shape (H, W)
        Ideal z-depth, mm (0 = none).

    Returns
    -------
    ndarray, shape (H, W)
        Depth in mm, 0 where there is no reading.
    """
    import cv2

    d = depth_mm.copy()
    valid = d > 0
    # Flying pixels: at a jump, a pixel reads a mix of the two sides.
    near = cv2.erode(np.where(valid, d, 1e9).astype(np.float32), np.ones((3, 3), np.uint8))
    far = cv2.dilate(d.astype(np.float32), np.ones((3, 3), np.uint8))
    edge = valid & ((far - near) > 15)
    mix = rng.random(d.shape)
    fly = edge & (rng.random(d.shape) < 0.6)
    d[fly] = (near * mix + far * (1 - mix))[fly]
    # Parallax holes: the projector sits to one side, so the far side of each jump
    # facing it sees no pattern for a few pixels.
    jump = np.zeros(d.shape, bool)
    jump[:, 1:] = (d[:, :-1] - d[:, 1:]) < -15  # far pixel right of a near one
    width = int(rng.integers(2, 7))
    shadow = cv2.dilate(jump.astype(np.uint8), np.ones((1, width), np.uint8), anchor=(0, 0))
    d[shadow.astype(bool)] = 0
    du, dv = conditions.registration_px
    d = np.roll(d, (dv, du), axis=(0, 1))
    if dv > 0:
        d[:dv] = 0
    elif dv < 0:
        d[dv:] = 0
    if du > 0:
        d[:, :du] = 0
    elif du < 0:
        d[:, du:] = 0
    return d
