"""What ``dgli render --engine cycles --scene varied`` draws beyond the standard scene:
scenes unlike the ones the detector was tuned on.

* the napkin **anywhere in the view** (the camera aims off the napkin, so it may sit in a
  corner of a tilted view, seen obliquely);
* a **table** of varnished wood (a procedural grain of drawn colour, ring size and
  direction) in one render of two, else matte of any drawn grey or colour;
* a **bar lamp** in one render of two, placed where a sticker (one the camera sees)
  mirrors it into the camera: its streak in the glossy laminate crosses that sticker
  and its neighbours, at any angle;
* area lamps of **2,700-6,500 K** each, independently;
* **woven cotton** of a wider range of threads and bump;
* a **camera pipeline** and **time-of-flight model** whose parameters are drawn too
  (exposure, blur, vignetting, white balance, depth noise and dropouts).

Everything is drawn from the generator given (no ``bpy`` here: the draw is tested
without Blender); :mod:`dgli_vision.sim.cycles_scene` builds the scene.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.camera import CameraPose, Intrinsics, look_at_table
from ..core.errors import InvalidValueError
from .camera_pipeline import CameraModel, ToFModel
from .cloth.states import ClothState
from .render_scene import Lighting

__all__ = [
    "SCENES",
    "WoodTable",
    "draw_pipeline",
    "draw_varied_look",
    "offset_camera",
]

#: ``--scene`` choices: ``standard`` (the scene of the earlier rounds, the default) and
#: ``varied`` (this module's draws).
SCENES = ("standard", "varied")


@dataclass(frozen=True)
class WoodTable:
    """A varnished wooden table top (a procedural grain).

    Attributes
    ----------
    light_rgb, dark_rgb : tuple of float
        Linear albedo of the early and the late wood of a ring.
    ring_mm : float
        Spacing of the growth rings across the grain.
    stretch : float
        How much longer the grain's figure runs along the grain than across it.
    direction_deg : float
        Direction of the grain on the table (world x is 0).
    distortion : float
        How much the rings wander (the wave texture's distortion).
    roughness : float
        The varnish's roughness (0.15: a glossy table mirroring the lamps).
    seed : float
        Offset of the figure (which part of the log the top is cut from).
    """

    light_rgb: tuple[float, float, float]
    dark_rgb: tuple[float, float, float]
    ring_mm: float
    stretch: float
    direction_deg: float
    distortion: float
    roughness: float
    seed: float

    def to_json(self) -> dict[str, Any]:
        """JSON-ready form (for ``truth.json``)."""
        return {
            "light_rgb": [round(v, 4) for v in self.light_rgb],
            "dark_rgb": [round(v, 4) for v in self.dark_rgb],
            "ring_mm": round(self.ring_mm, 2),
            "stretch": round(self.stretch, 2),
            "direction_deg": round(self.direction_deg, 1),
            "distortion": round(self.distortion, 2),
            "roughness": round(self.roughness, 3),
        }


def draw_wood(rng: np.random.Generator) -> WoodTable:
    """A wooden table from pale oak to dark walnut, its grain in any direction."""
    t = float(rng.uniform(0, 1))  # 0: pale oak, 1: walnut
    pale, dark = np.array([0.52, 0.33, 0.16]), np.array([0.13, 0.065, 0.03])
    light = pale * (1 - t) + dark * t
    light = light * rng.uniform(0.9, 1.1, 3)
    late = light * float(rng.uniform(0.45, 0.75))
    return WoodTable(
        light_rgb=tuple(float(v) for v in np.clip(light, 0.01, 0.9)),
        dark_rgb=tuple(float(v) for v in np.clip(late, 0.005, 0.9)),
        ring_mm=float(rng.uniform(3.0, 14.0)),
        stretch=float(rng.uniform(6.0, 20.0)),
        direction_deg=float(rng.uniform(0, 180)),
        distortion=float(rng.uniform(2.0, 8.0)),
        roughness=float(rng.uniform(0.15, 0.55)),
        seed=float(rng.uniform(0, 100)),
    )


def offset_camera(
    state: ClothState,
    rng: np.random.Generator,
    distance_m: tuple[float, float],
    max_tilt_deg: float,
    intrinsics: Intrinsics,
    fits: Any,
) -> tuple[CameraPose, dict[str, Any]]:
    """A camera ``distance_m`` from the napkin's centre (and from its aim point), tilted
    up to ``max_tilt_deg``, aimed anywhere such that the whole napkin is still in view:
    the napkin lies anywhere in the frame, seen off the optical axis.

    ``fits(state, pose, intrinsics, margin_px)`` says whether the napkin is in view.
    Draws that leave it out are redrawn, the aim's offset shrinking after many misses.

    Returns
    -------
    pose : CameraPose
    info : dict
        ``envelope`` ``"wide"``, ``distance_m`` (to the napkin's centre),
        ``aim_distance_m``, ``height_m``, ``tilt_deg``, ``tilt_direction_deg``,
        ``yaw_deg``, ``offset_px`` (where the napkin's centre is from the image's).
    """
    lo, hi = distance_m
    centre = np.append(state.mesh.xyz[:, :2].mean(axis=0), 0.0)
    for attempt in range(400):
        reach = max(0.0, 1.0 - attempt / 300)
        dist = float(rng.uniform(lo, hi))
        tilt = float(rng.uniform(0, max_tilt_deg))
        tdir, yaw = float(rng.uniform(0, 360)), float(rng.uniform(0, 360))
        a, b = rng.uniform(-1, 1, 2) * reach
        height = dist * np.cos(np.radians(tilt))
        pose = look_at_table(height, tilt_rad=np.radians(tilt),
                             tilt_direction_rad=np.radians(tdir), yaw_rad=np.radians(yaw),
                             target=centre)
        # shift the aim along the image's axes (on the table) by up to half the view
        half_w = dist * intrinsics.width / 2 / intrinsics.fx
        half_h = dist * intrinsics.height / 2 / intrinsics.fy
        shift = a * half_w * pose.rotation[:, 0] + b * half_h * pose.rotation[:, 1]
        target = centre + np.array([shift[0], shift[1], 0.0])
        pose = look_at_table(height, tilt_rad=np.radians(tilt),
                             tilt_direction_rad=np.radians(tdir), yaw_rad=np.radians(yaw),
                             target=target)
        cam = pose.world_to_camera(centre[None])[0]
        if lo <= np.linalg.norm(cam) <= hi and fits(state, pose, intrinsics, 20.0):
            px = intrinsics.project(cam[None])[0]
            return pose, {
                "envelope": "wide",
                "distance_m": round(float(np.linalg.norm(cam)), 4),
                "aim_distance_m": round(dist, 4),
                "height_m": round(float(height), 4),
                "tilt_deg": round(tilt, 3),
                "tilt_direction_deg": round(tdir, 3),
                "yaw_deg": round(yaw, 3),
                "offset_px": [round(float(px[0] - intrinsics.cx), 1),
                              round(float(px[1] - intrinsics.cy), 1)],
            }
    raise InvalidValueError("no camera pose of envelope 'wide' sees the whole napkin")


def _bar_spot(
    state: ClothState, visible: np.ndarray | None, rng: np.random.Generator
) -> tuple[np.ndarray, int | None]:
    """Where the bar's streak is to cross the napkin: a sticker the camera sees (its
    index among ``state.sticker_points``), else a point near the napkin's centre."""
    if visible is not None:
        seen = np.flatnonzero(np.asarray(visible) > 0.5)
        if len(seen):
            k = int(rng.choice(seen))
            return state.sticker_points[k] + np.append(rng.uniform(-0.01, 0.01, 2), 0), k
    centre = state.mesh.xyz.mean(axis=0) * np.array([1, 1, 0])
    return centre + np.append(rng.uniform(-0.12, 0.12, 2), 0.0), None


def draw_varied_look(
    state: ClothState,
    pose: CameraPose,
    lighting: Lighting,
    rng: np.random.Generator,
    visible: np.ndarray | None = None,
) -> Any:
    """The lights, fabric, table and laminate of a ``--scene varied`` render.

    Parameters
    ----------
    state, pose
        The cloth and the camera.
    lighting : Lighting
        The napkin's albedo (and the matte table's, unless drawn again).
    rng : Generator
    visible : ndarray, shape (16,), optional
        How much of each sticker the camera sees: the bar lamp's streak is aimed at one
        of those seen.

    Returns
    -------
    PhotoLook
        With ``table`` (``"wood"`` or ``"matte"``), ``wood`` and, for a bar lamp,
        ``bar_sticker`` (the sticker its streak crosses).
    """
    from .cycles_scene import AreaLight, PhotoLook, towards

    centre = state.mesh.xyz.mean(axis=0) * np.array([1, 1, 0])
    kelvin = float(rng.uniform(2700, 6500))
    bar = bool(rng.random() < 0.5)
    bar_sticker = None
    if bar:
        spot, bar_sticker = _bar_spot(state, visible, rng)
        view = pose.position - spot
        mirror = np.array([-view[0], -view[1], view[2]]) / np.linalg.norm(view)
        dist = float(rng.uniform(0.6, 1.4))
        size = (float(rng.uniform(0.6, 1.2)), float(rng.uniform(0.03, 0.10)))
        key = AreaLight(tuple(spot + dist * mirror), tuple(spot), size, kelvin,
                        120.0 * dist**2 * float(rng.uniform(2.0, 5.0)),
                        roll_deg=float(rng.uniform(0, 180)))
    else:
        dist = float(rng.uniform(0.8, 2.2))
        pos = towards(centre, rng.uniform(0, 60), rng.uniform(0, 360), dist)
        side = float(rng.uniform(0.15, 1.0))
        key = AreaLight(tuple(pos), tuple(centre), (side, side * float(rng.uniform(0.5, 1))),
                        kelvin, 120.0 * dist**2 * float(rng.uniform(0.6, 1.6)),
                        roll_deg=float(rng.uniform(0, 180)))
    lights = [key]
    for _ in range(int(rng.integers(0, 3))):  # 0-2 more lamps, each of its own colour
        fd = float(rng.uniform(0.8, 2.5))
        fpos = towards(centre, rng.uniform(10, 75), rng.uniform(0, 360), fd)
        lights.append(AreaLight(
            tuple(fpos), tuple(centre), (float(rng.uniform(0.2, 1.2)),) * 2,
            float(rng.uniform(2700, 6500)), 120.0 * fd**2 * float(rng.uniform(0.1, 0.6)),
        ))
    wood = draw_wood(rng) if rng.random() < 0.5 else None
    table_rgb = lighting.table_rgb
    if wood is None:  # a matte table of any grey or colour, dark to light
        table_rgb = tuple(float(v) for v in rng.uniform(0.03, 0.45) * rng.uniform(0.7, 1.3, 3))
    return PhotoLook(
        lights=tuple(lights),
        ambient=float(rng.uniform(0.02, 0.3)),
        ambient_kelvin=float(rng.uniform(2700, 6500)),
        napkin_rgb=lighting.napkin_rgb,
        table_rgb=table_rgb,
        thread_mm=float(rng.uniform(0.3, 1.0)),
        bump=float(rng.uniform(0.2, 0.8)),
        sheen=float(rng.uniform(0.2, 0.9)),
        laminate_roughness=float(rng.uniform(0.01, 0.15)),
        camera_body=True,
        bar_lamp=bar,
        table="wood" if wood is not None else "matte",
        wood=wood,
        bar_sticker=bar_sticker,
        scene="varied",
    )


def draw_pipeline(rng: np.random.Generator) -> tuple[CameraModel, ToFModel]:
    """A colour camera and a depth camera of drawn parameters around the defaults: auto
    exposure aiming lower or higher, more or less blur and vignetting, a worse white
    balance, more depth noise and dropouts."""
    camera = CameraModel(
        exposure_target=(float(rng.uniform(0.10, 0.18)), float(rng.uniform(0.22, 0.34))),
        vignetting=(0.05, float(rng.uniform(0.2, 0.5))),
        full_well_e=float(rng.uniform(3000, 10000)),
        read_noise_e=float(rng.uniform(2, 8)),
        adc_bits=int(rng.choice([10, 12])),
        white_balance_error=float(rng.uniform(0.03, 0.12)),
        white_balance_strength=(float(rng.uniform(0.5, 0.8)), 1.0),
        blur_sigma_px=(0.3, float(rng.uniform(0.6, 1.2))),
    )
    tof = ToFModel(
        noise_mm=float(rng.uniform(2.0, 6.0)),
        flying_pixel=float(rng.uniform(0.3, 0.7)),
        edge_dropout=float(rng.uniform(0.1, 0.4)),
        specular_cone_deg=float(rng.uniform(5.0, 12.0)),
        grazing_cos=float(rng.uniform(0.08, 0.2)),
        random_dropout=float(rng.uniform(0.0, 0.01)),
    )
    return camera, tof


def check_scene(scene: str) -> str:
    """``scene`` if it is one of :data:`SCENES`."""
    if scene not in SCENES:
        raise InvalidValueError(f"unknown scene {scene!r}; expected one of {SCENES}")
    return scene
