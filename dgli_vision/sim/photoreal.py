"""Labelled path-traced pairs (``dgli render --engine cycles``): the rasteriser's states,
seen from the camera envelopes a lab or a robot has, rendered by Cycles
(:mod:`dgli_vision.sim.cycles_scene`).

Importing this module does not import ``bpy``; rendering does.
"""

from __future__ import annotations

import zlib
from typing import Any

import numpy as np

from ..core.camera import DEFAULT_INTRINSICS, CameraPose, Intrinsics, look_at_table
from ..core.errors import InvalidValueError
from ..core.layout import NapkinLayout, default_layout
from .cloth.states import VARIANTS, ClothState, sample_state
from .dataset import NOMINAL_HEIGHT_M, RenderedSample, _fits, sample_name
from .photo_variety import check_scene, draw_pipeline, draw_varied_look, offset_camera
from .render_scene import Lighting

__all__ = [
    "ENVELOPES",
    "WIDE_ENVELOPE",
    "envelope_of",
    "envelope_range",
    "photo_camera",
    "render_photo_sample",
    "varied_draws",
]

#: Camera envelopes: distance from the camera to the napkin's centre along its axis (m)
#: and the largest tilt of the axis from the vertical (degrees). ``spec``: SPEC's
#: envelope; ``far``: a camera on a stand farther back; ``head``: a robot's head camera.
ENVELOPES: dict[str, tuple[tuple[float, float], float]] = {
    "spec": ((0.45, 0.80), 15.0),
    "far": ((0.70, 1.00), 25.0),
    "head": ((1.00, 1.20), 35.0),
}
#: ``wide``: a camera 1.0-2.0 m from the napkin, tilted up to 35 degrees, stickers 18 down
#: to 9 px across at the nominal focal length (beyond SPEC; not in ``all``).
WIDE_ENVELOPE: tuple[tuple[float, float], float] = ((1.0, 2.0), 35.0)
#: ``--envelope all`` takes the three of :data:`ENVELOPES` in turn over the pairs.
ENVELOPE_CHOICES = (*ENVELOPES, "wide", "all")


def envelope_range(envelope: str) -> tuple[tuple[float, float], float]:
    """Distances (m) and largest tilt (degrees) of a single envelope."""
    if envelope == "wide":
        return WIDE_ENVELOPE
    if envelope not in ENVELOPES:
        raise InvalidValueError(
            f"unknown envelope {envelope!r}; expected one of {ENVELOPE_CHOICES}"
        )
    return ENVELOPES[envelope]


def envelope_of(envelope: str, class_id: str, k: int) -> str:
    """The envelope of pair ``k`` of a class: ``envelope``, or under ``"all"`` each in
    turn, shifted by the class, so every class and every envelope gets its share."""
    if envelope == "all":
        return list(ENVELOPES)[(int(class_id) + k) % len(ENVELOPES)]
    envelope_range(envelope)  # known
    return envelope


def photo_camera(
    state: ClothState,
    rng: np.random.Generator,
    envelope: str,
    *,
    intrinsics: Intrinsics = DEFAULT_INTRINSICS,
    nominal: bool = False,
) -> tuple[CameraPose, dict[str, Any]]:
    """A camera of ``envelope`` that sees the whole napkin (20 px margin).

    Distance, tilt, its direction and the yaw are drawn uniformly; draws that leave part
    of the napkin out of view are redrawn, after many misses from farther away.

    Returns
    -------
    pose : CameraPose
    info : dict
        ``envelope``, ``distance_m``, ``height_m``, ``tilt_deg``, ``tilt_direction_deg``,
        ``yaw_deg``.
    """
    (lo, hi), max_tilt = envelope_range(envelope)
    centre = state.mesh.xyz[:, :2].mean(axis=0)
    for attempt in range(300):
        if nominal:
            dist, tilt, tdir = NOMINAL_HEIGHT_M, 0.0, 0.0
            yaw = float(rng.uniform(0, 360)) if attempt else 0.0
        else:
            grow = min(1.0, attempt / 150)
            dist = float(rng.uniform(lo + grow * (hi - lo) * 0.5, hi))
            tilt = float(rng.uniform(0, max_tilt))
            tdir, yaw = float(rng.uniform(0, 360)), float(rng.uniform(0, 360))
        height = dist * np.cos(np.radians(tilt))
        target = (*(centre + (0 if nominal else rng.uniform(-0.02, 0.02, 2))), 0.0)
        pose = look_at_table(
            height,
            tilt_rad=np.radians(tilt),
            tilt_direction_rad=np.radians(tdir),
            yaw_rad=np.radians(yaw),
            target=target,
        )
        if _fits(state, pose, intrinsics, 20.0):
            return pose, {
                "envelope": "nominal" if nominal else envelope,
                "distance_m": round(dist, 4),
                "height_m": round(float(height), 4),
                "tilt_deg": round(tilt, 3),
                "tilt_direction_deg": round(tdir, 3),
                "yaw_deg": round(yaw, 3),
            }
    raise InvalidValueError(f"no camera pose of envelope {envelope!r} sees the whole napkin")


def cycles_seed(seed: int, class_id: str, k: int) -> int:
    """Cycles' seed of pair ``k`` of a class (a 31-bit hash of the three)."""
    return zlib.crc32(f"{seed}/{class_id}/{k}".encode()) & 0x7FFFFFFF


def render_photo_sample(
    class_id: str,
    k: int,
    seed: int,
    *,
    envelope: str = "all",
    samples: int = 32,
    threads: int = 2,
    nominal: bool = False,
    clean: bool = False,
    intrinsics: Intrinsics = DEFAULT_INTRINSICS,
    layout: NapkinLayout | None = None,
    scene: str = "standard",
) -> RenderedSample:
    """Pair ``k`` of class ``class_id`` path-traced by Cycles.

    The state is the one :func:`dgli_vision.sim.dataset.render_sample` draws for the same
    seed, class and number (the same variant, folds and wrinkles); the camera comes from
    the pair's envelope (:func:`envelope_of`), then the light and the materials; the
    camera pipeline and the depth model draw from a stream of their own, and Cycles'
    seed is the pair's, so a pair renders the same every time.

    ``scene="varied"`` (:mod:`dgli_vision.sim.photo_variety`) aims the camera anywhere
    the napkin stays in view, draws a wooden or matte table, a bar lamp whose streak
    crosses a sticker the camera sees, lamps of their own colours, and the camera
    pipeline's and depth model's parameters; the standard scene is as it was.
    """
    from .cycles_scene import draw_look, render_cycles

    layout = layout or default_layout()
    rng = np.random.default_rng([seed, int(class_id), k, 7])
    options = VARIANTS[class_id]
    variant = options[(k + seed) % len(options)]
    state = sample_state(class_id, variant, rng, layout=layout)
    env = envelope_of(envelope, class_id, k)
    if check_scene(scene) == "varied":
        pose, camera, lighting, look, models = _varied_draws(
            state, rng, env, intrinsics, layout, nominal
        )
    else:
        pose, camera = photo_camera(state, rng, env, intrinsics=intrinsics, nominal=nominal)
        lighting = Lighting.random(rng)
        look = draw_look(state, pose, lighting, rng)
        models = {}
    result = render_cycles(
        state,
        pose,
        intrinsics,
        look,
        np.random.default_rng([seed, int(class_id), k, 41]),
        layout=layout,
        samples=samples,
        seed=cycles_seed(seed, class_id, k),
        threads=threads,
        clean=clean,
        **models,
    )
    return RenderedSample(sample_name(class_id, k), state, result, camera, lighting)


def _varied_draws(
    state: ClothState,
    rng: np.random.Generator,
    envelope: str,
    intrinsics: Intrinsics,
    layout: NapkinLayout,
    nominal: bool,
) -> tuple[CameraPose, dict[str, Any], Lighting, Any, dict[str, Any]]:
    """The camera, lighting, look and camera models of a ``--scene varied`` pair."""
    from .render import _visible_fraction
    from .render_scene import RaycastScene

    if nominal:
        pose, camera = photo_camera(state, rng, envelope, intrinsics=intrinsics, nominal=True)
    else:
        distances, tilt = envelope_range(envelope)
        pose, camera = offset_camera(state, rng, distances, tilt, intrinsics, _fits)
    lighting = Lighting.random(rng)
    visible = _visible_fraction(state, pose, RaycastScene(state), intrinsics, layout)
    look = draw_varied_look(state, pose, lighting, rng, visible)
    colour, tof = draw_pipeline(rng)
    return pose, camera, lighting, look, {"camera": colour, "tof": tof}


def varied_draws(
    class_id: str, k: int, seed: int, *, envelope: str = "wide",
    intrinsics: Intrinsics = DEFAULT_INTRINSICS, layout: NapkinLayout | None = None,
) -> dict[str, Any]:
    """What pair ``k`` of a class draws under ``--scene varied``, without rendering it
    (no Blender): ``pose``, ``camera`` (the envelope's draw), ``look`` and the camera
    ``models``, exactly as :func:`render_photo_sample` draws them."""
    layout = layout or default_layout()
    rng = np.random.default_rng([seed, int(class_id), k, 7])
    options = VARIANTS[class_id]
    state = sample_state(class_id, options[(k + seed) % len(options)], rng, layout=layout)
    env = envelope_of(envelope, class_id, k)
    pose, camera, _, look, models = _varied_draws(state, rng, env, intrinsics, layout, False)
    return {"state": state, "pose": pose, "camera": camera, "look": look,
            "colour_model": models["camera"], "tof_model": models["tof"]}
