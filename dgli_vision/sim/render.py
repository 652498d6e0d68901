"""Synthetic RGB-D renderer: a cloth state seen by a pinhole camera above the table.

Open3D's ``RaycastingScene`` (CPU) casts one ray per pixel through its centre (see
:mod:`dgli_vision.core.camera` for the conventions). The napkin carries the stickers of SPEC
section 2 on both faces, drawn into a texture in material coordinates; colours are
shaded with a Lambert model in linear light (plus, under ``sheen``, a large area light's
Blinn-Phong reflection in the stickers' vinyl and the napkin's fabric), then a
switchable sensor model adds what a real RGB-D camera does: exposure and white-balance
jitter, blur, colour noise, depth noise growing with distance, 1 mm quantisation, and
dropouts at depth edges and at random.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.camera import DEFAULT_INTRINSICS, CameraPose, Intrinsics
from ..core.colour import linear_to_srgb
from ..core.layout import NapkinLayout, default_layout
from .cloth.states import VISIBLE_FRACTION, ClothState, disc_samples, normalize_rng
from .conditions import (
    Conditions,
    SceneObject,
    apply_lens_distortion,
    grasp_frame,
    highlight_spot,
    jpeg_roundtrip,
    realistic_depth,
    scene_objects,
    shadow_factor,
    wood_albedo,
)
from .photo_effects import auto_exposed, kelvin_rgb, mosaic_demosaic, photo_light, vignetting
from .render_scene import Lighting, RaycastScene, sample_texture, sticker_texture
from .render_sheen import SHEEN_EXPOSURE_PEAK, SheenLobes, sheen_lobes

__all__ = [
    "CONDITION_EFFECTS",
    "EFFECT_STAGES",
    "ConditionEffect",
    "Lighting",
    "RenderResult",
    "SensorModel",
    "render",
    "sticker_texture",
]


@dataclass(frozen=True)
class SensorModel:
    """What the sensor adds; ``SensorModel(enabled=False)`` renders clean images.

    Attributes
    ----------
    enabled : bool
        Master switch.
    colour_noise : float
        Standard deviation of additive colour noise, 8-bit levels.
    exposure_jitter : float
        Relative exposure jitter (uniform in +-).
    white_balance_jitter : float
        Relative per-channel gain jitter (uniform in +-).
    blur_sigma_px : float
        Gaussian blur of the colour image, pixels.
    depth_noise_mm : float
        Depth noise standard deviation at 0.5 m, mm (grows with the square of depth).
    edge_dropout : float
        Probability that a pixel at a depth edge (jump > 10 mm) reads 0.
    random_dropout : float
        Probability that any pixel reads 0.
    """

    enabled: bool = True
    colour_noise: float = 2.5
    exposure_jitter: float = 0.15
    white_balance_jitter: float = 0.06
    blur_sigma_px: float = 0.7
    depth_noise_mm: float = 1.0
    edge_dropout: float = 0.5
    random_dropout: float = 0.002


@dataclass(frozen=True, eq=False)
class RenderResult:
    """A rendered RGB-D pair and its ground truth.

    Attributes
    ----------
    color : ndarray of uint8, shape (H, W, 3)
        RGB image.
    depth_mm : ndarray of uint16, shape (H, W)
        z-depth in mm, 0 = no reading.
    sticker_points_cam : ndarray, shape (16, 3)
        Sticker centres in the camera frame, metres.
    visible_fraction : ndarray, shape (16,)
        Fraction of each sticker's disc the camera sees.
    pose : CameraPose
    intrinsics : Intrinsics
    """

    color: NDArray[np.uint8]
    depth_mm: NDArray[np.uint16]
    sticker_points_cam: NDArray[np.float64]
    visible_fraction: NDArray[np.float64]
    pose: CameraPose
    intrinsics: Intrinsics
    info: dict = field(default_factory=dict)

    @property
    def visible(self) -> NDArray[np.bool_]:
        """Stickers at least half seen, shape (16,)."""
        return self.visible_fraction >= VISIBLE_FRACTION


def _info(cond: Conditions, sheen: SheenLobes | None) -> dict:
    """The render's ``info``: the conditions, and the sticker a large light washes out."""
    info: dict = {"conditions": cond.label} if cond.names else {}
    if sheen is not None:
        info["sheen_sticker"] = sheen.sticker
    return info


@dataclass(frozen=True, eq=False)
class _ViewHits:
    """Where the camera's pixel rays meet the scene (``n = H * W`` rays, row-major).

    Attributes
    ----------
    rays : dict of ndarray
        Open3D's ray-casting results (see :meth:`RaycastScene.cast`).
    dirs : ndarray, shape (n, 3)
        World ray directions, camera-z component 1.
    t_hit : ndarray, shape (n,)
        z-depth of each hit, metres (inf: none).
    on_cloth, on_table : ndarray of bool, shape (n,)
    hit_xy : ndarray, shape (n, 2) or None
        World (x, y) of every hit, for the conditions that need it (wood, shadow).
    """

    rays: dict[str, NDArray]
    dirs: NDArray[np.float64]
    t_hit: NDArray[np.float64]
    on_cloth: NDArray[np.bool_]
    on_table: NDArray[np.bool_]
    hit_xy: NDArray[np.float64] | None


@dataclass(frozen=True, eq=False)
class _Surface:
    """What the camera sees at every pixel before light: albedo and the cloth's texture.

    Attributes
    ----------
    albedo : ndarray, shape (n, 3)
        Linear RGB.
    no_depth : ndarray of bool, shape (n,)
        Pixels on solids the depth sensor cannot read.
    cloth_uv : ndarray, shape (k, 2)
        Material coordinates (mm) of the cloth hits.
    tex : ndarray, shape (k, 4)
        The sticker texture at ``cloth_uv``.
    """

    albedo: NDArray[np.float64]
    no_depth: NDArray[np.bool_]
    cloth_uv: NDArray[np.float64]
    tex: NDArray[np.float32]


@dataclass(frozen=True, eq=False)
class _Stage:
    """What a condition's effect receives: the conditions, the view and the surface (None
    where the stage has none), ``value`` (what the stage makes, and the effect returns
    changed), and what some effects also need."""

    cond: Conditions
    view: _ViewHits | None
    surface: _Surface | None
    value: Any
    state: ClothState | None = None
    layout: NapkinLayout | None = None
    rng: np.random.Generator | None = None
    intrinsics: Intrinsics | None = None
    gain: NDArray | None = None
    scene: RaycastScene | None = None
    pose: CameraPose | None = None
    lighting: Lighting | None = None
    kept: dict = field(default_factory=dict)


@dataclass(frozen=True)
class ConditionEffect:
    """How one capture condition changes the render, at one stage of it.

    Attributes
    ----------
    condition : str
        The condition (:data:`~dgli_vision.sim.condition_names.CONDITION_NAMES`).
    stage : str
        Where in the render it acts (:data:`EFFECT_STAGES`): ``"surface"`` (the albedo
        of every pixel, ``value`` is the (n, 3) albedo), ``"shade"`` (the shading (n,)
        before it multiplies the albedo; not under ``photo``), ``"light"`` (linear light
        (n, 3) before the exposure), ``"exposed"`` (after it), ``"depth"`` (the depth in
        mm, float (H, W), before its units) or ``"camera"`` (the 8-bit colour and the
        uint16 depth as the camera delivers them).
    applies : callable
        ``applies(conditions) -> bool``.
    apply : callable
        ``apply(stage) -> value``: the stage's value changed (:class:`_Stage`).
    needs_table_xy : bool
        Needs the world (x, y) of every hit (``view.hit_xy``).
    """

    condition: str
    stage: str
    applies: Callable[[Conditions], bool]
    apply: Callable[[_Stage], Any]
    needs_table_xy: bool = False


#: The stages of a render at which conditions act, in order.
EFFECT_STAGES = ("surface", "shade", "light", "exposed", "depth", "camera")


def _wood(stage: _Stage) -> NDArray:
    view, albedo = stage.view, stage.value
    albedo[view.on_table] = wood_albedo(view.hit_xy[view.on_table], stage.cond.seed)
    return albedo


def _shadow(stage: _Stage) -> NDArray:
    centre = stage.state.mesh.xyz.mean(axis=0)
    return stage.value * shadow_factor(stage.view.hit_xy, stage.cond, centre)


def _realistic_depth(stage: _Stage) -> NDArray:
    return realistic_depth(stage.value, stage.cond, stage.rng)


def _lens(stage: _Stage) -> tuple[NDArray, NDArray]:
    color, depth_mm = stage.value
    return apply_lens_distortion(color, depth_mm, stage.intrinsics, stage.cond.distortion)


def _mirror(stage: _Stage) -> tuple[NDArray, NDArray]:
    color, depth_mm = stage.value  # the camera flips its image left to right, both alike
    return color[:, ::-1].copy(), depth_mm[:, ::-1].copy()


def _jpeg(stage: _Stage) -> tuple[NDArray, NDArray]:
    color, depth_mm = stage.value
    return jpeg_roundtrip(color, stage.cond.jpeg_quality), depth_mm


def _pixel_rays(pose: CameraPose, intrinsics: Intrinsics) -> tuple[NDArray, NDArray]:
    """Origins and world directions (H * W, 3) of one ray per pixel (camera-z 1)."""
    dirs_cam = intrinsics.ray_directions().reshape(-1, 3)
    dirs = dirs_cam @ pose.rotation.T  # world directions with camera-z component 1
    return np.broadcast_to(pose.position, dirs.shape), dirs


def _condition_objects(
    cond: Conditions,
    state: ClothState,
    pose: CameraPose,
    dirs: NDArray,
    intrinsics: Intrinsics,
    layout: NapkinLayout,
) -> list[SceneObject]:
    """The solids the conditions add, placed within the table area the camera sees."""
    h, w = intrinsics.height, intrinsics.width
    corner = state.params.get("held_corner") if cond.grasp is not None else None
    if not (cond.clutter or cond.gripper_height_m is not None or cond.realistic_depth or corner):
        return []
    corners = dirs.reshape(h, w, 3)[[0, 0, -1, -1], [0, -1, 0, -1]]
    table_xy = pose.position[:2] + corners[:, :2] * (-pose.position[2] / corners[:, 2:])
    view = (table_xy.min(axis=0) + 0.03, table_xy.max(axis=0) - 0.03)
    held = grasp_frame(state, corner, layout) if corner else None
    return scene_objects(cond, state.mesh.xyz, view, held)


def _cast_view(
    scene: RaycastScene, origins: NDArray, dirs: NDArray, pose: CameraPose, cond: Conditions
) -> _ViewHits:
    """Cast the pixel rays into the scene."""
    hits = scene.cast(origins, dirs)
    t_hit = hits["t_hit"].astype(np.float64)  # = z-depth, metres
    gid = hits["geometry_ids"]
    hit_xy = None
    if any(e.needs_table_xy for e in _effects(cond)):
        hit_xy = pose.position[:2] + dirs[:, :2] * np.where(np.isfinite(t_hit), t_hit, 0)[:, None]
    return _ViewHits(hits, dirs, t_hit, gid == scene.cloth_id, gid == scene.table_id, hit_xy)


def _surface(
    view: _ViewHits,
    scene: RaycastScene,
    cond: Conditions,
    lighting: Lighting,
    layout: NapkinLayout,
) -> _Surface:
    """Albedo (linear RGB) of every pixel: table (or wood), the objects, the textured cloth."""
    n = len(view.t_hit)
    gid = view.rays["geometry_ids"]
    on_table, on_cloth = view.on_table, view.on_cloth
    albedo = np.zeros((n, 3))
    albedo[on_table] = lighting.table_rgb  # a condition may lay another table (below)
    no_depth = np.zeros(n, bool)
    for oid, obj in scene.objects.items():
        mine = gid == oid
        albedo[mine] = obj.albedo
        no_depth |= mine & (not obj.has_depth)
    cloth_uv = scene.material_uv(view.rays, on_cloth)
    tex = sample_texture(sticker_texture(layout), cloth_uv)
    albedo[on_cloth] = tex[:, :3] + tex[:, 3:] * np.asarray(lighting.napkin_rgb)
    surface = _Surface(albedo, no_depth, cloth_uv, tex)
    for effect in _effects(cond, "surface"):
        effect.apply(_Stage(cond, view, surface, albedo))
    return surface


def _lit(
    view: _ViewHits, surface: _Surface, cond: Conditions, lighting: Lighting, state: ClothState
) -> NDArray[np.float64]:
    """Linear light (n, 3): Lambert shading, two-sided (both faces are the same cloth),
    under the arm's shadow when there is one."""
    light = np.asarray(lighting.light_direction, dtype=np.float64)
    light /= np.linalg.norm(light)
    normals = view.rays["primitive_normals"].astype(np.float64)
    lambert = np.abs(normals @ light)
    shade = lighting.ambient + (1 - lighting.ambient) * lambert
    for effect in _effects(cond, "shade"):
        shade = effect.apply(_Stage(cond, view, surface, shade, state=state))
    return surface.albedo * shade[:, None]


def _photo_lit(
    view: _ViewHits, surface: _Surface, cond: Conditions, pose: CameraPose, state: ClothState
) -> NDArray[np.float64]:
    """Linear light (n, 3) under ``photo``: a lamp at a finite distance and a fill light,
    the fabric's sheen on the cloth and the laminate's lobe on the stickers."""
    photo = cond.photo
    hit = np.isfinite(view.t_hit)
    t = np.where(hit, view.t_hit, 1.0)
    points = pose.position + view.dirs * t[:, None]
    to_camera = -view.dirs / np.linalg.norm(view.dirs, axis=1)[:, None]
    normals = view.rays["primitive_normals"].astype(np.float64)
    diffuse, sheen, gloss, mirrored = photo_light(
        photo, points, normals, to_camera, state.mesh.xyz.mean(axis=0)
    )
    linear = surface.albedo * diffuse
    lamp = kelvin_rgb(photo.lamp_kelvin) * (1 - photo.fill)
    napkin = surface.tex[:, 3]  # 1 on bare cloth, 0 on a sticker
    shine = photo.sheen * napkin * sheen[view.on_cloth] + photo.gloss * (1 - napkin) * gloss[
        view.on_cloth
    ]
    linear[view.on_cloth] += shine[:, None] * lamp
    room = photo.laminate * (1 - napkin) * mirrored[view.on_cloth]
    linear[view.on_cloth] += room[:, None] * kelvin_rgb(photo.fill_kelvin)
    linear[~hit] = 0.0
    return linear


def _photo_colour(
    linear: NDArray, shape: tuple[int, int], cond: Conditions, sensor: SensorModel,
    rng: np.random.Generator,
) -> NDArray[np.uint8]:
    """The 8-bit colour image under ``photo``: lens blur and vignetting, auto white
    balance and exposure, a colour mosaic with shot noise, demosaicing, sRGB."""
    import cv2

    image = linear.reshape(*shape, 3)
    if sensor.enabled:
        image = cv2.GaussianBlur(image, (0, 0), cond.photo.blur_px)
    image = image * vignetting(shape, cond.photo.vignetting)[..., None]
    image = mosaic_demosaic(auto_exposed(image, cond.photo), rng)
    return np.clip(np.rint(linear_to_srgb(image) * 255.0), 0, 255).astype(np.uint8)


def _add_highlight(stage: _Stage) -> NDArray:
    """Glossy vinyl: add a mirror highlight on a sticker, not on the cloth (in place)."""
    linear, view, surface = stage.value, stage.view, stage.surface
    spot = highlight_spot(stage.cond, stage.layout.sticker_uv, stage.state.visible)
    if spot is None:
        return linear
    centre, sigma, peak, _ = spot
    lobe = np.exp(-((surface.cloth_uv - centre) ** 2).sum(axis=1) / (2 * sigma**2))
    linear[view.on_cloth] += (peak * lobe * (1 - surface.tex[:, 3]))[:, None]
    return linear


def _exposed(
    linear: NDArray, cond: Conditions, sensor: SensorModel, rng: np.random.Generator
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Linear light through the camera's exposure and channel gains (the condition's, then
    the sensor's jitter); returns it and the total gain per channel (3,)."""
    gain = cond.exposure * np.asarray(cond.colour_gains)  # the camera's, per channel
    if cond.exposure != 1.0 or cond.colour_gains != (1.0, 1.0, 1.0):
        linear = linear * cond.exposure * np.asarray(cond.colour_gains)
    if sensor.enabled:
        exposure = 1 + rng.uniform(-sensor.exposure_jitter, sensor.exposure_jitter)
        gains = 1 + rng.uniform(-sensor.white_balance_jitter, sensor.white_balance_jitter, 3)
        linear = linear * exposure * gains
        gain = gain * exposure * gains
    return linear, gain


def _add_sheen(stage: _Stage) -> NDArray:
    """Semi-gloss vinyl and fabric under a large light, then the camera's auto-exposure:
    the brightest pixel stays below white. The lobes are kept for the render's info."""
    sheen = sheen_lobes(
        stage.cond, stage.state, stage.scene, stage.pose, stage.lighting, stage.layout,
        stage.view.rays, stage.view.dirs, stage.surface.tex,
    )
    stage.kept["sheen"] = sheen
    linear = stage.value
    if sheen is None:
        return linear
    linear[stage.view.on_cloth] += sheen.light(stage.gain)
    return linear * min(1.0, SHEEN_EXPOSURE_PEAK / max(float(linear.max()), 1e-9))


def _colour_sensor(
    srgb: NDArray, sensor: SensorModel, cond: Conditions, rng: np.random.Generator
) -> NDArray[np.uint8]:
    """The 8-bit colour image: the sensor's blur and noise on the sRGB levels (H, W, 3)."""
    if sensor.enabled:
        import cv2

        if sensor.blur_sigma_px > 0:
            srgb = cv2.GaussianBlur(srgb.astype(np.float32), (0, 0), sensor.blur_sigma_px)
        noise = sensor.colour_noise if cond.colour_noise is None else cond.colour_noise
        srgb = srgb + rng.normal(0.0, noise, srgb.shape)
    return np.clip(np.rint(srgb), 0, 255).astype(np.uint8)


def _depth_edges(depth: NDArray) -> NDArray[np.bool_]:
    """Pixels (H, W) on either side of a depth jump of more than 10 mm."""
    jump = np.zeros(depth.shape, bool)
    dz_x = np.abs(np.diff(depth, axis=1)) > 10
    dz_y = np.abs(np.diff(depth, axis=0)) > 10
    jump[:, 1:] |= dz_x
    jump[:, :-1] |= dz_x
    jump[1:] |= dz_y
    jump[:-1] |= dz_y
    return jump


def _depth_image(
    view: _ViewHits,
    no_depth: NDArray,
    shape: tuple[int, int],
    cond: Conditions,
    sensor: SensorModel,
    rng: np.random.Generator,
) -> NDArray[np.uint16]:
    """The depth image in mm (0 = no reading): noise growing with depth, dropouts at edges
    and at random, the realistic-depth effects and the wrong-units scale."""
    depth = np.where(np.isfinite(view.t_hit), view.t_hit, 0.0).reshape(shape) * 1000.0  # mm
    depth[no_depth.reshape(shape)] = 0.0
    valid = depth > 0
    if sensor.enabled:
        noise_mm = cond.depth_noise_mm if cond.realistic_depth else sensor.depth_noise_mm
        sigma = noise_mm * (depth / 500.0) ** 2
        depth = depth + rng.normal(0.0, 1.0, depth.shape) * sigma
        jump = _depth_edges(depth)
        drop = (jump & (rng.random(shape) < sensor.edge_dropout)) | (
            rng.random(shape) < sensor.random_dropout
        )
        valid &= ~drop
    depth = np.where(valid, depth, 0.0)
    for effect in _effects(cond, "depth"):
        depth = effect.apply(_Stage(cond, view, None, depth, rng=rng))
    return np.clip(np.rint(depth * cond.depth_scale), 0, 65535).astype(np.uint16)


def _camera_output(
    color: NDArray[np.uint8],
    depth_mm: NDArray[np.uint16],
    intrinsics: Intrinsics,
    cond: Conditions,
) -> tuple[NDArray[np.uint8], NDArray[np.uint16]]:
    """The images as the camera delivers them: through its lens, mirrored, JPEG-coded
    (the effects at ``"camera"``, in the order of :data:`CONDITION_EFFECTS`)."""
    images = (color, depth_mm)
    for effect in _effects(cond, "camera"):
        images = effect.apply(_Stage(cond, None, None, images, intrinsics=intrinsics))
    return images


def _visible_fraction(
    state: ClothState,
    pose: CameraPose,
    scene: RaycastScene,
    intrinsics: Intrinsics,
    layout: NapkinLayout,
) -> NDArray[np.float64]:
    """Truth: how much of each sticker's disc (16,) the camera sees."""
    h, w = intrinsics.height, intrinsics.width
    offsets = disc_samples(layout)
    uv = (layout.sticker_uv[:, None, :] + offsets[None]).reshape(-1, 2)
    pts = state.mesh.interpolate(uv)
    ray_dirs = pts - pose.position
    sample_hits = scene.cast(np.broadcast_to(pose.position, ray_dirs.shape), ray_dirs)
    seen = sample_hits["geometry_ids"] == scene.cloth_id
    hit_uv = np.full((len(pts), 2), np.inf)
    hit_uv[seen] = scene.material_uv(sample_hits, seen)
    # Seen: the ray meets the cloth at this very material point (within 4 mm).
    seen &= np.linalg.norm(hit_uv - uv, axis=1) < 4.0
    pix = intrinsics.project(pose.world_to_camera(pts))
    inside = (pix[:, 0] >= 0) & (pix[:, 0] <= w - 1) & (pix[:, 1] >= 0) & (pix[:, 1] <= h - 1)
    seen &= inside
    return seen.reshape(len(layout.sticker_uv), -1).mean(axis=1)


def _sticker_points_cam(
    state: ClothState, pose: CameraPose, intrinsics: Intrinsics, cond: Conditions
) -> NDArray[np.float64]:
    """Truth: sticker centres (16, 3) in the camera frame, where the (mirrored) image
    shows them through the same intrinsics."""
    points_cam = pose.world_to_camera(state.sticker_points)
    if cond.mirror:
        w = intrinsics.width
        points_cam[:, 0] = (w - 1 - 2 * intrinsics.cx) * points_cam[:, 2] / intrinsics.fx - (
            points_cam[:, 0]
        )
    return points_cam


#: What each capture condition does to the image, walked by :func:`render` stage by
#: stage (in this order within a stage). A condition that only draws other parameters
#: (``cast``, ``dim``, ``vga``, ``far``...) or adds objects to the scene
#: (:mod:`~dgli_vision.sim.condition_scene`) needs no row.
CONDITION_EFFECTS: tuple[ConditionEffect, ...] = (
    ConditionEffect("wood", "surface", lambda c: c.wood_table, _wood, needs_table_xy=True),
    ConditionEffect("shadow", "shade", lambda c: bool(c.shadow), _shadow, needs_table_xy=True),
    ConditionEffect("gloss", "light", lambda c: c.highlight, _add_highlight),
    ConditionEffect("sheen", "exposed", lambda c: c.sheen is not None, _add_sheen),
    ConditionEffect("depth", "depth", lambda c: c.realistic_depth, _realistic_depth),
    ConditionEffect("distortion", "camera", lambda c: any(c.distortion), _lens),
    ConditionEffect("mirror", "camera", lambda c: c.mirror, _mirror),
    ConditionEffect("jpeg", "camera", lambda c: c.jpeg_quality is not None, _jpeg),
)


def _effects(cond: Conditions, stage: str | None = None) -> list[ConditionEffect]:
    """The effects of :data:`CONDITION_EFFECTS` that apply to ``cond`` (at ``stage``)."""
    return [
        e for e in CONDITION_EFFECTS
        if (stage is None or e.stage == stage) and e.applies(cond)
    ]


def render(
    state: ClothState,
    pose: CameraPose,
    *,
    intrinsics: Intrinsics = DEFAULT_INTRINSICS,
    layout: NapkinLayout | None = None,
    lighting: Lighting | None = None,
    sensor: SensorModel | None = None,
    rng: np.random.Generator | int | None = None,
    conditions: Conditions | None = None,
) -> RenderResult:
    """Render a cloth state to a registered colour + depth pair.

    Parameters
    ----------
    state : ClothState
        The cloth, world coordinates (metres, z up).
    pose : CameraPose
        Camera pose (see :func:`dgli_vision.core.camera.look_at_table`).
    intrinsics : Intrinsics, keyword-only
        Default: SPEC's nominal Kinect colour camera.
    layout : NapkinLayout, keyword-only
        Sticker layout (default: packaged).
    lighting : Lighting, keyword-only
        Default: ``Lighting()``.
    sensor : SensorModel, keyword-only
        Default: ``SensorModel()`` (noisy); ``SensorModel(enabled=False)`` for clean.
    rng : Generator or int, keyword-only
        Drives the sensor noise.
    conditions : Conditions, keyword-only
        Capture conditions (:mod:`dgli_vision.sim.conditions`); default: SPEC's clean scene.
        A lens's distortion is the condition's: the images are rendered through the
        pinhole of ``intrinsics`` and then distorted, and the result's intrinsics carry
        the coefficients when the condition makes them known (``distortion-known``).

    Returns
    -------
    RenderResult
    """
    layout = layout or default_layout()
    lighting = lighting or Lighting()
    sensor = sensor or SensorModel()
    cond = conditions or Conditions()
    rng = normalize_rng(rng)
    given = intrinsics
    intrinsics = replace(intrinsics, distortion=())  # rays: the ideal pinhole camera
    shape = (intrinsics.height, intrinsics.width)
    origins, dirs = _pixel_rays(pose, intrinsics)
    scene = RaycastScene(state, _condition_objects(cond, state, pose, dirs, intrinsics, layout))
    view = _cast_view(scene, origins, dirs, pose, cond)
    surface = _surface(view, scene, cond, lighting, layout)
    if cond.photo is not None:
        linear = _photo_lit(view, surface, cond, pose, state)
    else:
        linear = _lit(view, surface, cond, lighting, state)
    kept: dict = {}
    for effect in _effects(cond, "light"):
        linear = effect.apply(
            _Stage(cond, view, surface, linear, state=state, layout=layout, kept=kept)
        )
    linear, gain = _exposed(linear, cond, sensor, rng)
    for effect in _effects(cond, "exposed"):
        linear = effect.apply(
            _Stage(cond, view, surface, linear, state=state, layout=layout, kept=kept,
                   gain=gain, scene=scene, pose=pose, lighting=lighting)
        )
    sheen = kept.get("sheen")
    if cond.photo is not None:
        color = _photo_colour(linear, shape, cond, sensor, rng)
    else:
        srgb = linear_to_srgb(linear).reshape(*shape, 3) * 255.0
        color = _colour_sensor(srgb, sensor, cond, rng)
    depth_mm = _depth_image(view, surface.no_depth, shape, cond, sensor, rng)
    color, depth_mm = _camera_output(color, depth_mm, intrinsics, cond)
    return RenderResult(
        color=color,
        depth_mm=depth_mm,
        sticker_points_cam=_sticker_points_cam(state, pose, intrinsics, cond),
        visible_fraction=_visible_fraction(state, pose, scene, intrinsics, layout),
        pose=pose,
        intrinsics=replace(intrinsics, distortion=cond.distortion)
        if cond.distortion_known
        else given,
        info=_info(cond, sheen),
    )
