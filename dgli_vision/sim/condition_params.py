"""What each capture condition draws: the frozen parameters the renderer and the image
effects read (:class:`Conditions`, with its :class:`Sheen` and :class:`Grasp`).

Drawn from a seeded generator by :func:`~dgli_vision.sim.conditions.draw_conditions`.
"""

from __future__ import annotations

from dataclasses import dataclass

from .photo_effects import Photo

__all__ = ["Conditions", "Grasp", "Sheen"]


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
    photo : Photo or None
        The look of a photograph (a lamp's fall-off, two colour temperatures, sheen,
        vignetting, auto exposure and white balance, a colour mosaic).
    camera_range_m : tuple of float or None
        Distance of the camera from the napkin along its axis (min, max), metres, with
        ``tilt_range_deg``; None: the data set's heights.
    tilt_range_deg : tuple of float
        Tilt of the camera from the vertical (min, max), degrees, with ``camera_range_m``.
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
    photo: Photo | None = None
    camera_range_m: tuple[float, float] | None = None
    tilt_range_deg: tuple[float, float] = (0.0, 12.0)

    @property
    def label(self) -> str:
        """``"clean"`` or the names joined by ``+``."""
        return "+".join(self.names) or "clean"
