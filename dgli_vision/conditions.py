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

This module is the catalogue: the :class:`Conditions` a render is made under and how each
named condition draws its parameters. What the conditions add to the scene's geometry is
in :mod:`dgli_vision.condition_scene`, what they do to appearance and to the images in
:mod:`dgli_vision.condition_effects`; both are re-exported here.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, replace

import numpy as np

from .condition_effects import (
    apply_lens_distortion,
    area_light_lobe,
    highlight_spot,
    jpeg_roundtrip,
    mirror_light_direction,
    realistic_depth,
    shadow_factor,
    sheen_sticker,
    specular_for_saturation,
    wood_albedo,
)
from .condition_names import COMBO_POOL, CONDITION_HELP, CONDITION_NAMES
from .condition_scene import (
    SceneObject,
    grasp_frame,
    held_corner,
    held_gripper,
    scene_objects,
    turn_over,
)

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
    "highlight_spot",
    "jpeg_roundtrip",
    "mirror_light_direction",
    "realistic_depth",
    "scene_objects",
    "shadow_factor",
    "sheen_sticker",
    "specular_for_saturation",
    "turn_over",
    "wood_albedo",
]


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


def _draw_cast(c: Conditions, rng: np.random.Generator) -> Conditions:
    if rng.random() < 0.6:  # tungsten
        gains = (rng.uniform(1.25, 1.45), 1.0, rng.uniform(0.55, 0.72))
    else:  # daylight through a window / LED: blue
        gains = (rng.uniform(0.6, 0.78), rng.uniform(0.9, 1.0), rng.uniform(1.25, 1.45))
    return replace(c, colour_gains=tuple(float(g) for g in gains))


def _draw_sheen(c: Conditions, rng: np.random.Generator) -> Conditions:
    sheen = Sheen(
        shininess=float(rng.uniform(150, 600)),
        light_radius_deg=float(rng.uniform(5, 9)),
        saturation=float(rng.uniform(0.15, 0.27)),
        cloth_strength=float(rng.uniform(0.1, 0.25)),
        cloth_shininess=float(rng.uniform(30, 80)),
    )
    return replace(c, sheen=sheen)


def _draw_depth(c: Conditions, rng: np.random.Generator) -> Conditions:
    off = rng.integers(1, 4) * rng.choice([-1, 1], 2) * (rng.random(2) < 0.7)
    if not off.any():
        off[0] = 1
    return replace(
        c,
        realistic_depth=True,
        depth_noise_mm=float(rng.uniform(2.0, 4.0)),
        registration_px=(int(off[0]), int(off[1])),
    )


def _draw_grasp(c: Conditions, rng: np.random.Generator) -> Conditions:
    settle = 180.0 if rng.random() < 1 / 3 else float(rng.uniform(100, 170))
    grasp = Grasp(settle, float(rng.uniform(20, 80)), int(rng.integers(4)))
    return replace(c, grasp=grasp)


def _draw_depthscale(c: Conditions, rng: np.random.Generator) -> Conditions:
    if rng.random() < 0.5:  # a round wrong unit factor
        scale = float(rng.choice([0.8, 1.25]))
    else:
        scale = float(rng.uniform(0.75, 0.85) if rng.random() < 0.5 else rng.uniform(1.2, 1.3))
    return replace(c, depth_scale=scale)


#: How each condition draws its parameters into a :class:`Conditions` (``vga`` and
#: ``clean`` draw nothing: the camera is chosen by the data set).
_DRAWERS: dict[str, Callable[[Conditions, np.random.Generator], Conditions]] = {
    "jpeg": lambda c, rng: replace(c, jpeg_quality=int(rng.integers(70, 93))),
    "cast": _draw_cast,
    "dim": lambda c, rng: replace(
        c, exposure=float(rng.uniform(0.35, 0.55)), colour_noise=rng.uniform(6, 10)
    ),
    "gloss": lambda c, rng: replace(c, highlight=True),
    "sheen": _draw_sheen,
    "shadow": lambda c, rng: replace(c, shadow=float(rng.uniform(0.35, 0.6))),
    "clutter": lambda c, rng: replace(c, clutter=int(rng.integers(3, 7))),
    "gripper": lambda c, rng: replace(c, gripper_height_m=float(rng.uniform(0.06, 0.20))),
    "distortion": lambda c, rng: replace(c, distortion=draw_lens(rng)),
    "distortion-known": lambda c, rng: replace(
        c, distortion=draw_lens(rng), distortion_known=True
    ),
    "depth": _draw_depth,
    "vga": lambda c, rng: c,
    "clean": lambda c, rng: c,
    "wood": lambda c, rng: replace(c, wood_table=True),
    "mirror": lambda c, rng: replace(c, mirror=True),
    "backface": lambda c, rng: replace(c, backface_axis_deg=float(rng.uniform(0, 180))),
    "grasp": _draw_grasp,
    "depthscale": _draw_depthscale,
}


def _draw_one(name: str, c: Conditions, rng: np.random.Generator) -> Conditions:
    """``c`` with the parameters of condition ``name`` drawn from ``rng``."""
    drawer = _DRAWERS.get(name)
    if drawer is None:
        raise ValueError(
            f"unknown condition {name!r}; expected one of {', '.join(CONDITION_NAMES)}"
        )
    return drawer(c, rng)


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
