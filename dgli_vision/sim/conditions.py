"""Capture conditions for the renderer: what real cameras and real labs add to SPEC's scene.

Each named condition (DESIGN.md, "Capture conditions the tool must survive") is drawn
from a seeded generator into one frozen :class:`Conditions`; the renderer
(:func:`dgli_vision.sim.render.render`) applies it. Scene conditions add geometry or change
appearance (a wood table, objects, a gripper and arm, a shadow, glossy stickers); sensor
conditions change the images (a colour cast, dim exposure and noise, JPEG, lens
distortion, realistic depth); ``vga`` changes the camera (see
:func:`dgli_vision.sim.dataset.render_samples`).

The figures are the ranges of the robust-perception issue; they are ours, drawn to cover
each condition, not tuned to any held-out set.

This module is the catalogue: the :class:`Conditions` a render is made under and how each
named condition draws its parameters. What the conditions add to the scene's geometry is
in :mod:`dgli_vision.sim.condition_scene`, what they do to appearance and to the images in
:mod:`dgli_vision.sim.condition_effects`; both are re-exported here.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import replace

import numpy as np

from ..core.errors import InvalidValueError
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
from .condition_params import Conditions, Grasp, Sheen
from .condition_scene import (
    SceneObject,
    grasp_frame,
    held_corner,
    held_gripper,
    scene_objects,
    turn_over,
)
from .photo_effects import draw_photo

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
    "photo": lambda c, rng: replace(c, photo=draw_photo(rng)),
    "far": lambda c, rng: replace(c, camera_range_m=(0.7, 1.0), tilt_range_deg=(0.0, 25.0)),
    "head": lambda c, rng: replace(c, camera_range_m=(1.0, 1.2), tilt_range_deg=(20.0, 35.0)),
}


def _draw_one(name: str, c: Conditions, rng: np.random.Generator) -> Conditions:
    """``c`` with the parameters of condition ``name`` drawn from ``rng``."""
    drawer = _DRAWERS.get(name)
    if drawer is None:
        raise InvalidValueError(
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
        :data:`~dgli_vision.sim.condition_names.COMBO_POOL`.
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
