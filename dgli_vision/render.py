"""Synthetic RGB-D renderer: a cloth state seen by a pinhole camera above the table.

Open3D's ``RaycastingScene`` (CPU) casts one ray per pixel through its centre (see
:mod:`dgli_vision.camera` for the conventions). The napkin carries the stickers of SPEC
section 2 on both faces, drawn into a texture in material coordinates; colours are
shaded with a Lambert model in linear light (plus, under ``sheen``, a large area light's
Blinn-Phong reflection in the stickers' vinyl and the napkin's fabric), then a
switchable sensor model adds what a real RGB-D camera does: exposure and white-balance
jitter, blur, colour noise, depth noise growing with distance, 1 mm quantisation, and
dropouts at depth edges and at random.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from .camera import DEFAULT_INTRINSICS, CameraPose, Intrinsics
from .cloth.states import VISIBLE_FRACTION, ClothState, disc_samples, normalize_rng
from .colour import linear_to_srgb, srgb_to_linear
from .conditions import (
    Conditions,
    SceneObject,
    Sheen,
    apply_lens_distortion,
    area_light_lobe,
    grasp_frame,
    highlight_spot,
    jpeg_roundtrip,
    mirror_light_direction,
    realistic_depth,
    scene_objects,
    shadow_factor,
    sheen_sticker,
    specular_for_saturation,
    wood_albedo,
)
from .layout import NapkinLayout, default_layout

__all__ = ["Lighting", "RenderResult", "SensorModel", "render", "sticker_texture"]

_TEXTURE_PX_PER_MM = 2.0


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


@dataclass(frozen=True)
class Lighting:
    """Scene appearance.

    Attributes
    ----------
    light_direction : tuple of float
        Direction towards the light, world frame (normalised here).
    ambient : float
        Fraction of light that does not depend on the surface normal.
    table_rgb : tuple of float
        Table albedo, linear RGB in [0, 1] (matte, unsaturated).
    napkin_rgb : tuple of float
        Napkin albedo, linear RGB (white or light grey).
    """

    light_direction: tuple[float, float, float] = (0.2, -0.3, 1.0)
    ambient: float = 0.4
    table_rgb: tuple[float, float, float] = (0.18, 0.16, 0.14)
    napkin_rgb: tuple[float, float, float] = (0.82, 0.82, 0.80)

    @classmethod
    def random(cls, rng: np.random.Generator) -> Lighting:
        """Lighting and colours varied within SPEC's limits."""
        tilt, az = rng.uniform(0, np.radians(35)), rng.uniform(0, 2 * np.pi)
        light = (np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt))
        hue = rng.uniform(0, 1)
        sat = rng.uniform(0.0, 0.3)
        val = rng.uniform(0.08, 0.35)
        base = np.array([np.cos(2 * np.pi * (hue - k / 3)) for k in range(3)])
        table = np.clip(val * (1 + sat * base), 0, 1)
        grey = rng.uniform(0.65, 0.9)
        napkin = np.clip(grey * (1 + rng.uniform(-0.03, 0.03, 3)), 0, 1)
        return cls(
            tuple(float(v) for v in light),
            float(rng.uniform(0.3, 0.55)),
            tuple(float(v) for v in table),
            tuple(float(v) for v in napkin),
        )


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


@lru_cache(maxsize=4)
def _texture_cached(layout: NapkinLayout) -> NDArray[np.float32]:
    import cv2

    s = _TEXTURE_PX_PER_MM
    h, w = int(round(layout.height_mm * s)) + 1, int(round(layout.width_mm * s)) + 1
    # Label image: 0 napkin, k + 1 colour k (drawn at 4x and averaged for soft edges).
    names = list(layout.colours_srgb)
    lin = np.array([srgb_to_linear(np.array(layout.colours_srgb[n]) / 255.0) for n in names])
    ss = 4
    canvas = np.zeros((h * ss, w * ss), np.uint8)
    for uv, disc, dot in zip(layout.sticker_uv, layout.sticker_disc, layout.sticker_dot):
        centre = (int(round(uv[0] * s * ss)), int(round(uv[1] * s * ss)))
        cv2.circle(
            canvas,
            centre,
            int(round(layout.disc_diameter_mm / 2 * s * ss)),
            names.index(disc) + 1,
            -1,
        )
        cv2.circle(
            canvas,
            centre,
            int(round(layout.dot_diameter_mm / 2 * s * ss)),
            names.index(dot) + 1,
            -1,
        )
    weights = np.zeros((h, w, len(names) + 1), np.float32)
    for k in range(len(names) + 1):
        weights[..., k] = cv2.resize(
            (canvas == k).astype(np.float32), (w, h), interpolation=cv2.INTER_AREA
        )
    tex = weights[..., 1:] @ lin.astype(np.float32)  # (h, w, 3) linear colour of stickers
    tex = np.concatenate([tex, weights[..., :1]], axis=2)  # last channel: napkin weight
    tex.flags.writeable = False
    return tex


def sticker_texture(layout: NapkinLayout | None = None) -> NDArray[np.float32]:
    """Texture (h, w, 4) in material coordinates at 2 px/mm: linear RGB of the stickers
    and, in channel 3, the weight of the bare napkin (1 off the stickers)."""
    return _texture_cached(layout or default_layout())


def _sample_texture(tex: NDArray, uv_mm: NDArray) -> NDArray:
    """Bilinear lookup of the texture at material points (n, 2) mm -> (n, 4)."""
    import cv2

    s = _TEXTURE_PX_PER_MM
    n = len(uv_mm)
    cols = 1024  # remap maps must stay below 32767 rows
    rows = max(1, -(-n // cols))
    maps = np.zeros((2, rows * cols), np.float32)
    maps[:, :n] = (uv_mm * s).T
    out = cv2.remap(
        tex,
        maps[0].reshape(rows, cols),
        maps[1].reshape(rows, cols),
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REPLICATE,
    )
    return out.reshape(-1, 4)[:n]


class _Scene:
    """Open3D raycasting scene of one cloth state and the table."""

    def __init__(self, state: ClothState, objects: list[SceneObject] = ()) -> None:
        import open3d as o3d

        self._o3d = o3d
        self.scene = o3d.t.geometry.RaycastingScene()
        tri = state.mesh.triangles()
        self.triangles = tri
        self.uv = state.mesh.uv
        self.cloth_id = self.scene.add_triangles(
            o3d.core.Tensor(state.mesh.xyz.astype(np.float32)),
            o3d.core.Tensor(tri.astype(np.uint32)),
        )
        big = 5.0  # the table: a 10 m square just below the cloth's lowest layer
        z = -2e-4
        table_v = np.array(
            [[-big, -big, z], [big, -big, z], [big, big, z], [-big, big, z]], np.float32
        )
        table_t = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
        self.table_id = self.scene.add_triangles(
            o3d.core.Tensor(table_v), o3d.core.Tensor(table_t)
        )
        self.objects = {
            self.scene.add_triangles(
                o3d.core.Tensor(obj.vertices.astype(np.float32)),
                o3d.core.Tensor(obj.triangles.astype(np.uint32)),
            ): obj
            for obj in objects
        }

    def cast(self, origins: NDArray, directions: NDArray) -> dict[str, NDArray]:
        rays = np.concatenate([origins, directions], axis=-1).astype(np.float32)
        result = self.scene.cast_rays(self._o3d.core.Tensor(rays))
        return {
            k: result[k].numpy()
            for k in (
                "t_hit",
                "geometry_ids",
                "primitive_ids",
                "primitive_uvs",
                "primitive_normals",
            )
        }

    def material_uv(self, hits: dict[str, NDArray], mask: NDArray) -> NDArray:
        """Material coordinates (k, 2) mm of the cloth hits selected by ``mask``."""
        tri = self.triangles[hits["primitive_ids"][mask]]
        b = hits["primitive_uvs"][mask].astype(np.float64)
        w0 = 1.0 - b[:, 0] - b[:, 1]
        return (
            w0[:, None] * self.uv[tri[:, 0]]
            + b[:, :1] * self.uv[tri[:, 1]]
            + b[:, 1:] * self.uv[tri[:, 2]]
        )


#: Linear level the brightest pixel is exposed to under ``sheen`` (sRGB about 231): a
#: camera's auto-exposure keeps the large light's reflection from blowing out.
_SHEEN_EXPOSURE_PEAK = 0.8
#: HSV saturations every printed colour keeps in the full lobe under ``sheen``: pastel,
#: yet never so pale and bright that it reads as a highlight (chroma below a quarter of
#: the brightness, the tool's definition).
_SHEEN_SATURATION = (0.13, 0.3)


@dataclass(frozen=True, eq=False)
class _SheenLobes:
    """A large area light's reflection on the cloth hits (see :func:`_sheen_lobes`)."""

    sheen: Sheen
    vinyl: NDArray[np.float64]
    fabric: NDArray[np.float64]
    napkin: NDArray[np.float32]
    sticker: int
    diffuse: NDArray[np.float64]
    printed: NDArray[np.float64]

    def light(self, gain: NDArray) -> NDArray[np.float64]:
        """Linear light (k, 3) the reflection adds as the camera sees it through ``gain``
        (3,): the vinyl's strength makes the chosen sticker's disc reach the drawn
        saturation in the image, within the strengths that keep every printed colour
        (``printed``, as lit there) in :data:`_SHEEN_SATURATION`."""
        sheen = self.sheen

        def solve(diffuse: NDArray, saturation: float) -> float:
            return specular_for_saturation(
                diffuse * gain, saturation, tint=gain, peak=_SHEEN_EXPOSURE_PEAK
            )

        strength = solve(self.diffuse, sheen.saturation)
        # every printed colour in the full lobe stays within the pastel range
        lo = max(solve(c, _SHEEN_SATURATION[1]) for c in self.printed)
        hi = min(solve(c, _SHEEN_SATURATION[0]) for c in self.printed)
        strength = max(lo, min(strength, hi))
        grey = strength * self.vinyl * (1 - self.napkin) + (
            sheen.cloth_strength * self.fabric * self.napkin
        )
        return grey[:, None] * gain


def _sheen_lobes(
    cond: Conditions,
    state: ClothState,
    scene: _Scene,
    pose: CameraPose,
    lighting: Lighting,
    layout: NapkinLayout,
    hits: dict[str, NDArray],
    dirs: NDArray,
    tex: NDArray,
) -> _SheenLobes | None:
    """The lobes of a large area light on the cloth hits; None without ``sheen`` or when
    no sticker is in view.

    The light stands where the mirror direction of the chosen sticker's centre points,
    so that sticker lies in the full lobe of the vinyl (stickers) and of the fabric.
    """
    sheen = cond.sheen
    sid = sheen_sticker(cond, state.visible)
    if sheen is None or sid is None:
        return None
    point = state.sticker_points[sid]
    probe = scene.cast(pose.position[None], (point - pose.position)[None])
    normal = probe["primitive_normals"][0].astype(np.float64)
    view = pose.position - point
    view /= np.linalg.norm(view)
    light = mirror_light_direction(normal, view)
    sun = np.asarray(lighting.light_direction, np.float64)
    shade = lighting.ambient + (1 - lighting.ambient) * abs(normal @ sun / np.linalg.norm(sun))
    printed = srgb_to_linear(np.array(list(layout.colours_srgb.values())) / 255.0) * shade
    disc = srgb_to_linear(np.array(layout.colours_srgb[layout.sticker_disc[sid]]) / 255.0)
    on_cloth = hits["geometry_ids"] == scene.cloth_id
    normals = hits["primitive_normals"][on_cloth].astype(np.float64)
    views = -dirs[on_cloth] / np.linalg.norm(dirs[on_cloth], axis=1)[:, None]
    radius = np.radians(sheen.light_radius_deg)
    return _SheenLobes(
        sheen=sheen,
        vinyl=area_light_lobe(normals, views, light, radius, sheen.shininess),
        fabric=area_light_lobe(normals, views, light, radius, sheen.cloth_shininess),
        napkin=tex[:, 3],
        sticker=sid,
        diffuse=disc * shade,
        printed=printed,
    )


def _info(cond: Conditions, sheen: _SheenLobes | None) -> dict:
    """The render's ``info``: the conditions, and the sticker a large light washes out."""
    info: dict = {"conditions": cond.label} if cond.names else {}
    if sheen is not None:
        info["sheen_sticker"] = sheen.sticker
    return info


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
        Camera pose (see :func:`dgli_vision.camera.look_at_table`).
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
        Capture conditions (:mod:`dgli_vision.conditions`); default: SPEC's clean scene.
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
    h, w = intrinsics.height, intrinsics.width
    dirs_cam = intrinsics.ray_directions().reshape(-1, 3)
    dirs = dirs_cam @ pose.rotation.T  # world directions with camera-z component 1
    origins = np.broadcast_to(pose.position, dirs.shape)
    objects = []
    corner = state.params.get("held_corner") if cond.grasp is not None else None
    if cond.clutter or cond.gripper_height_m is not None or cond.realistic_depth or corner:
        corners = dirs.reshape(h, w, 3)[[0, 0, -1, -1], [0, -1, 0, -1]]
        table_xy = pose.position[:2] + corners[:, :2] * (-pose.position[2] / corners[:, 2:])
        view = (table_xy.min(axis=0) + 0.03, table_xy.max(axis=0) - 0.03)
        held = grasp_frame(state, corner, layout) if corner else None
        objects = scene_objects(cond, state.mesh.xyz, view, held)
    scene = _Scene(state, objects)
    hits = scene.cast(origins, dirs)
    t_hit = hits["t_hit"].astype(np.float64)  # = z-depth, metres
    gid = hits["geometry_ids"]
    on_cloth = gid == scene.cloth_id
    on_table = gid == scene.table_id
    hit_xy = None  # world (x, y) of every hit, for the conditions that need it
    if cond.wood_table or cond.shadow:
        hit_xy = pose.position[:2] + dirs[:, :2] * np.where(np.isfinite(t_hit), t_hit, 0)[:, None]

    # Albedo (linear RGB) of every pixel.
    albedo = np.zeros((h * w, 3))
    if hit_xy is not None and cond.wood_table:
        albedo[on_table] = wood_albedo(hit_xy[on_table], cond.seed)
    else:
        albedo[on_table] = lighting.table_rgb
    no_depth = np.zeros(h * w, bool)
    for oid, obj in scene.objects.items():
        mine = gid == oid
        albedo[mine] = obj.albedo
        no_depth |= mine & (not obj.has_depth)
    cloth_uv = scene.material_uv(hits, on_cloth)
    tex = _sample_texture(sticker_texture(layout), cloth_uv)
    albedo[on_cloth] = tex[:, :3] + tex[:, 3:] * np.asarray(lighting.napkin_rgb)
    # Lambert shading, two-sided (both faces are the same cloth).
    light = np.asarray(lighting.light_direction, dtype=np.float64)
    light /= np.linalg.norm(light)
    normals = hits["primitive_normals"].astype(np.float64)
    lambert = np.abs(normals @ light)
    shade = lighting.ambient + (1 - lighting.ambient) * lambert
    if hit_xy is not None and cond.shadow:
        shade = shade * shadow_factor(hit_xy, cond, state.mesh.xyz.mean(axis=0))
    linear = albedo * shade[:, None]
    sheen = _sheen_lobes(cond, state, scene, pose, lighting, layout, hits, dirs, tex)
    spot = highlight_spot(cond, layout.sticker_uv, state.visible)
    if spot is not None:  # glossy vinyl: a mirror highlight on a sticker, not on the cloth
        centre, sigma, peak, _ = spot
        lobe = np.exp(-((cloth_uv - centre) ** 2).sum(axis=1) / (2 * sigma**2))
        linear[on_cloth] += (peak * lobe * (1 - tex[:, 3]))[:, None]
    gain = cond.exposure * np.asarray(cond.colour_gains)  # the camera's, per channel
    if cond.exposure != 1.0 or cond.colour_gains != (1.0, 1.0, 1.0):
        linear = linear * cond.exposure * np.asarray(cond.colour_gains)
    if sensor.enabled:
        exposure = 1 + rng.uniform(-sensor.exposure_jitter, sensor.exposure_jitter)
        gains = 1 + rng.uniform(-sensor.white_balance_jitter, sensor.white_balance_jitter, 3)
        linear = linear * exposure * gains
        gain = gain * exposure * gains
    if sheen is not None:  # semi-gloss vinyl and fabric under a large light
        linear[on_cloth] += sheen.light(gain)
        # auto-exposure: the brightest pixel stays below white
        linear = linear * min(1.0, _SHEEN_EXPOSURE_PEAK / max(float(linear.max()), 1e-9))
    srgb = linear_to_srgb(linear).reshape(h, w, 3) * 255.0
    if sensor.enabled:
        import cv2

        if sensor.blur_sigma_px > 0:
            srgb = cv2.GaussianBlur(srgb.astype(np.float32), (0, 0), sensor.blur_sigma_px)
        noise = sensor.colour_noise if cond.colour_noise is None else cond.colour_noise
        srgb = srgb + rng.normal(0.0, noise, srgb.shape)
    color = np.clip(np.rint(srgb), 0, 255).astype(np.uint8)

    depth = np.where(np.isfinite(t_hit), t_hit, 0.0).reshape(h, w) * 1000.0  # mm
    depth[no_depth.reshape(h, w)] = 0.0
    valid = depth > 0
    if sensor.enabled:
        noise_mm = cond.depth_noise_mm if cond.realistic_depth else sensor.depth_noise_mm
        sigma = noise_mm * (depth / 500.0) ** 2
        depth = depth + rng.normal(0.0, 1.0, depth.shape) * sigma
        jump = np.zeros((h, w), bool)
        dz_x = np.abs(np.diff(depth, axis=1)) > 10
        dz_y = np.abs(np.diff(depth, axis=0)) > 10
        jump[:, 1:] |= dz_x
        jump[:, :-1] |= dz_x
        jump[1:] |= dz_y
        jump[:-1] |= dz_y
        drop = (jump & (rng.random((h, w)) < sensor.edge_dropout)) | (
            rng.random((h, w)) < sensor.random_dropout
        )
        valid &= ~drop
    depth = np.where(valid, depth, 0.0)
    if cond.realistic_depth:
        depth = realistic_depth(depth, cond, rng)
    depth_mm = np.clip(np.rint(depth * cond.depth_scale), 0, 65535).astype(np.uint16)
    if any(cond.distortion):
        color, depth_mm = apply_lens_distortion(color, depth_mm, intrinsics, cond.distortion)
    if cond.mirror:  # the camera flips its image left to right, colour and depth alike
        color, depth_mm = color[:, ::-1].copy(), depth_mm[:, ::-1].copy()
    if cond.jpeg_quality is not None:
        color = jpeg_roundtrip(color, cond.jpeg_quality)

    # Truth: sticker centres in the camera frame, and how much of each disc is seen.
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
    fraction = seen.reshape(len(layout.sticker_uv), -1).mean(axis=1)
    points_cam = pose.world_to_camera(state.sticker_points)
    if cond.mirror:  # where the mirrored image shows them, through the same intrinsics
        points_cam[:, 0] = (w - 1 - 2 * intrinsics.cx) * points_cam[:, 2] / intrinsics.fx - (
            points_cam[:, 0]
        )
    return RenderResult(
        color=color,
        depth_mm=depth_mm,
        sticker_points_cam=points_cam,
        visible_fraction=fraction,
        pose=pose,
        intrinsics=replace(intrinsics, distortion=cond.distortion)
        if cond.distortion_known
        else given,
        info=_info(cond, sheen),
    )
