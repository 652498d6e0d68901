"""A physically based render path: the simulator's cloth states path-traced by Blender's
Cycles (``bpy``, the ``photoreal`` extra, on the CPU), then seen through a colour camera's
pipeline and a time-of-flight depth camera (:mod:`dgli_vision.sim.camera_pipeline`).

What is modelled: a woven-cotton napkin (a procedural plain weave as bump, slubs in its
albedo, the fabric's own sheen), the stickers of SPEC section 2 printed in its colours
under a clear glossy laminate (a real specular coat), a matte table, area lights of
2,700-6,500 K (a black body's colour) with soft shadows and the fall-off of their
distance across the napkin, sometimes a bar lamp whose reflection crosses the napkin, a
fill light and the room's ambient light, and the camera's own body shading the scene
below it. The depth is the exact z-depth of the same geometry (Open3D's ray casting
through the same pixel centres), through the ToF model.

``bpy`` is imported here only: nothing else in the package needs it.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.camera import CameraPose, Intrinsics
from ..core.errors import InvalidInputError, MissingExtraError
from ..core.layout import NapkinLayout, default_layout
from .camera_pipeline import CameraModel, ToFModel, blackbody_rgb, colour_camera, tof_depth
from .cloth.states import ClothState
from .render import RenderResult, _sticker_points_cam, _visible_fraction
from .render_scene import TEXTURE_PX_PER_MM, Lighting, RaycastScene, sticker_texture

__all__ = [
    "AreaLight",
    "PhotoLook",
    "check_bpy",
    "draw_look",
    "import_bpy",
    "render_cycles",
]

#: What to install when ``bpy`` is missing.
INSTALL_HINT = "pip install dgli_vision[photoreal]"


def check_bpy() -> None:
    """Fail early, without importing it, when ``bpy`` is not installed (importing it sets
    Blender's environment, which worker processes spawned afterwards must not inherit).

    Raises
    ------
    MissingExtraError
    """
    import importlib.util

    try:
        found = importlib.util.find_spec("bpy") is not None
    except (ImportError, ValueError):
        found = False
    if not found:
        raise MissingExtraError(
            f"--engine cycles needs Blender as a Python module (bpy, Python 3.11): "
            f"{INSTALL_HINT}"
        )


def import_bpy() -> Any:
    """Blender as a Python module.

    Raises
    ------
    MissingExtraError
        ``bpy`` is not installed (or not for this Python).
    """
    try:
        import bpy
    except ImportError as exc:
        raise MissingExtraError(
            f"--engine cycles needs Blender as a Python module (bpy, Python 3.11): "
            f"{INSTALL_HINT} ({exc})"
        ) from None
    return bpy


@dataclass(frozen=True)
class AreaLight:
    """A rectangular area light facing the point it aims at.

    Attributes
    ----------
    position : tuple of float
        World, metres.
    target : tuple of float
        The point it faces.
    size_m : tuple of float
        Its sides, metres.
    kelvin : float
        Colour temperature.
    power_w : float
        Blender's power, watts.
    roll_deg : float
        Turn of the light about its own axis (a bar lamp's direction).
    """

    position: tuple[float, float, float]
    target: tuple[float, float, float]
    size_m: tuple[float, float]
    kelvin: float
    power_w: float
    roll_deg: float = 0.0


@dataclass(frozen=True)
class PhotoLook:
    """Everything a Cycles render draws besides the cloth and the camera.

    Attributes
    ----------
    lights : tuple of AreaLight
    ambient : float
        The room's light (the world's strength).
    ambient_kelvin : float
    napkin_rgb, table_rgb : tuple of float
        Linear albedos (from :class:`~dgli_vision.sim.render_scene.Lighting`).
    thread_mm : float
        The weave's thread pitch.
    bump : float
        The weave's bump strength.
    sheen : float
        The fabric's sheen weight.
    laminate_roughness : float
        Roughness of the stickers' clear coat.
    camera_body : bool
        The camera's body and mount are in the scene (they shade it, unseen by the camera).
    bar_lamp : bool
        The key light is a bar whose reflection crosses the napkin.
    table : str
        ``"matte"`` (of ``table_rgb``) or ``"wood"`` (of ``wood``).
    wood : WoodTable or None
        The wooden table's grain (:mod:`dgli_vision.sim.photo_variety`).
    bar_sticker : int or None
        The sticker (index of ``ClothState.sticker_points``) the bar's streak is aimed at.
    scene : str
        ``"standard"`` or ``"varied"`` (what drew it: ``--scene``).
    """

    lights: tuple[AreaLight, ...]
    ambient: float
    ambient_kelvin: float
    napkin_rgb: tuple[float, float, float]
    table_rgb: tuple[float, float, float]
    thread_mm: float = 0.6
    bump: float = 0.35
    sheen: float = 0.5
    laminate_roughness: float = 0.05
    camera_body: bool = True
    bar_lamp: bool = False
    table: str = "matte"
    wood: Any = None
    bar_sticker: int | None = None
    scene: str = "standard"

    def to_json(self) -> dict[str, Any]:
        """JSON-ready form (for ``truth.json``)."""
        out = {
            "lights": [
                {
                    "position_m": [round(v, 4) for v in li.position],
                    "size_m": [round(v, 3) for v in li.size_m],
                    "kelvin": round(li.kelvin),
                    "power_w": round(li.power_w, 1),
                }
                for li in self.lights
            ],
            "ambient": round(self.ambient, 4),
            "bar_lamp": self.bar_lamp,
            "thread_mm": round(self.thread_mm, 3),
            "sheen": round(self.sheen, 3),
            "laminate_roughness": round(self.laminate_roughness, 3),
        }
        if self.scene != "standard":  # the standard scene's entries stay as they were
            out["scene"] = self.scene
            out["table"] = self.table
            out["bump"] = round(self.bump, 3)
            if self.wood is not None:
                out["wood"] = self.wood.to_json()
            if self.bar_sticker is not None:
                out["bar_sticker"] = self.bar_sticker
            for entry, li in zip(out["lights"], self.lights):
                entry["roll_deg"] = round(li.roll_deg, 1)
        return out


def towards(centre: NDArray, polar_deg: float, azimuth_deg: float, dist: float) -> NDArray:
    p, a = np.radians(polar_deg), np.radians(azimuth_deg)
    return centre + dist * np.array([np.sin(p) * np.cos(a), np.sin(p) * np.sin(a), np.cos(p)])


def draw_look(
    state: ClothState, pose: CameraPose, lighting: Lighting, rng: np.random.Generator
) -> PhotoLook:
    """Lights, fabric and laminate for one render, drawn from ``rng``.

    A key light (a soft box of 0.2-0.8 m, 0.9-1.8 m from the napkin, up to 50 degrees
    from overhead; in one render of three a 1 m bar lamp placed where the napkin mirrors
    it into the camera), a fill light (none in one of three) and the room's light; each
    of 2,700-6,500 K, the fill and the room near the key's temperature or not.
    """
    centre = state.mesh.xyz.mean(axis=0) * np.array([1, 1, 0])
    kelvin = float(rng.uniform(2700, 6500))
    bar = bool(rng.random() < 1 / 3)
    if bar:
        # the mirror image of the camera in the table, seen from a point of the napkin
        # near a corner: the lamp's reflection crosses the napkin there
        spot = centre + np.append(rng.uniform(-0.12, 0.12, 2), 0.0)
        view = pose.position - spot
        mirror = np.array([-view[0], -view[1], view[2]])
        mirror /= np.linalg.norm(mirror)
        dist = float(rng.uniform(0.8, 1.4))
        key = AreaLight(
            tuple(spot + dist * mirror), tuple(spot), (1.0, 0.08), kelvin, 0.0
        )
    else:
        dist = float(rng.uniform(0.9, 1.8))
        pos = towards(centre, rng.uniform(0, 50), rng.uniform(0, 360), dist)
        side = float(rng.uniform(0.2, 0.8))
        key = AreaLight(tuple(pos), tuple(centre), (side, side), kelvin, 0.0)
    # power so that the napkin's centre gets about the same light at any distance
    key = _with_power(key, 120.0 * dist**2 * (3.0 if bar else 1.0))
    lights = [key]
    if rng.random() < 2 / 3:
        fk = kelvin if rng.random() < 0.5 else float(rng.uniform(2700, 6500))
        fd = float(rng.uniform(1.0, 2.0))
        fpos = towards(centre, rng.uniform(20, 70), rng.uniform(0, 360), fd)
        lights.append(
            AreaLight(
                tuple(fpos), tuple(centre), (1.0, 1.0), fk,
                120.0 * fd**2 * float(rng.uniform(0.1, 0.4)),
            )
        )
    return PhotoLook(
        lights=tuple(lights),
        ambient=float(rng.uniform(0.05, 0.25)),
        ambient_kelvin=float(rng.uniform(3500, 6500)),
        napkin_rgb=lighting.napkin_rgb,
        table_rgb=lighting.table_rgb,
        thread_mm=float(rng.uniform(0.4, 0.8)),
        bump=float(rng.uniform(0.2, 0.5)),
        sheen=float(rng.uniform(0.3, 0.8)),
        laminate_roughness=float(rng.uniform(0.02, 0.12)),
        camera_body=True,
        bar_lamp=bar,
    )


def _with_power(light: AreaLight, power: float) -> AreaLight:
    return AreaLight(light.position, light.target, light.size_m, light.kelvin, power)


# --- the Blender scene -------------------------------------------------------------------


@dataclass
class _Nodes:
    """Builds a node tree with few words: ``math("MULTIPLY", a, 2.0)`` and so on."""

    tree: Any
    x: int = field(default=0)

    def new(self, kind: str, **props: Any) -> Any:
        node = self.tree.nodes.new(kind)
        for k, v in props.items():
            setattr(node, k, v)
        self.x += 1
        return node

    def link(self, out: Any, inp: Any) -> None:
        self.tree.links.new(out, inp)

    def feed(self, socket: Any, value: Any) -> None:
        if hasattr(value, "is_output"):
            self.link(value, socket)
        else:
            socket.default_value = value

    def math(self, op: str, a: Any, b: Any = 0.0) -> Any:
        node = self.new("ShaderNodeMath", operation=op)
        self.feed(node.inputs[0], a)
        self.feed(node.inputs[1], b)
        return node.outputs[0]


def _cloth_material(bpy: Any, look: PhotoLook, layout: NapkinLayout) -> Any:
    """The napkin: woven cotton (weave bump, slubs, sheen), stickers under a glossy coat."""
    tex = sticker_texture(layout)  # linear sticker colours, channel 3: the napkin's weight
    napkin = np.asarray(look.napkin_rgb, np.float32)
    albedo = tex[..., :3] + tex[..., 3:] * napkin
    mask = 1.0 - tex[..., 3]
    img_albedo = _float_image(bpy, "albedo", albedo)
    img_mask = _float_image(bpy, "laminate", np.repeat(mask[..., None], 3, axis=2))

    mat = bpy.data.materials.new("napkin")
    mat.use_nodes = True
    nt = mat.node_tree
    nodes = _Nodes(nt)
    bsdf = nt.nodes["Principled BSDF"]
    uv_tex = nodes.new("ShaderNodeUVMap", uv_map="tex")
    uv_mm = nodes.new("ShaderNodeUVMap", uv_map="mm")
    t_alb = nodes.new("ShaderNodeTexImage", image=img_albedo, interpolation="Linear",
                      extension="EXTEND")
    t_msk = nodes.new("ShaderNodeTexImage", image=img_mask, interpolation="Linear",
                      extension="EXTEND")
    nodes.link(uv_tex.outputs["UV"], t_alb.inputs["Vector"])
    nodes.link(uv_tex.outputs["UV"], t_msk.inputs["Vector"])
    lam = t_msk.outputs["Color"]
    bw = nodes.new("ShaderNodeRGBToBW")
    nodes.link(lam, bw.inputs[0])
    laminate = bw.outputs[0]
    fabric = nodes.math("SUBTRACT", 1.0, laminate)
    # a plain weave: threads along u and v, each over one and under the next
    sep = nodes.new("ShaderNodeSeparateXYZ")
    nodes.link(uv_mm.outputs["UV"], sep.inputs[0])
    k = np.pi / look.thread_mm
    a = nodes.math("SINE", nodes.math("MULTIPLY", sep.outputs[0], k))
    b = nodes.math("SINE", nodes.math("MULTIPLY", sep.outputs[1], k))
    aa, ab = nodes.math("ABSOLUTE", a), nodes.math("ABSOLUTE", b)
    over = nodes.math("SIGN", nodes.math("MULTIPLY", a, b))
    height = nodes.math(
        "ADD",
        nodes.math("MULTIPLY", nodes.math("ADD", aa, ab), 0.5),
        nodes.math("MULTIPLY", nodes.math("MULTIPLY", nodes.math("SUBTRACT", aa, ab), over), 0.25),
    )
    # slubs: the yarn's thickness varies over a few mm
    noise = nodes.new("ShaderNodeTexNoise", noise_dimensions="2D")
    noise.inputs["Scale"].default_value = 0.15  # per mm
    noise.inputs["Detail"].default_value = 3.0
    nodes.link(uv_mm.outputs["UV"], noise.inputs["Vector"])
    slub = nodes.math("ADD", nodes.math("MULTIPLY", noise.outputs["Fac"], 0.08), 0.96)
    height = nodes.math("MULTIPLY", nodes.math("ADD", height, nodes.math(
        "MULTIPLY", noise.outputs["Fac"], 0.5)), fabric)
    bump = nodes.new("ShaderNodeBump")
    bump.inputs["Strength"].default_value = look.bump
    bump.inputs["Distance"].default_value = 0.0003
    nodes.link(height, bump.inputs["Height"])
    nodes.link(bump.outputs["Normal"], bsdf.inputs["Normal"])
    # the fabric's albedo: slubs and the weave's own shading, on the fabric only
    shade = nodes.math("ADD", nodes.math("MULTIPLY", nodes.math(
        "MULTIPLY", nodes.math("SUBTRACT", slub, 1.0), fabric), 1.0), 1.0)
    mix = nodes.new("ShaderNodeMix", data_type="RGBA", blend_type="MULTIPLY")
    mix.inputs["Factor"].default_value = 1.0
    nodes.link(t_alb.outputs["Color"], mix.inputs["A"])
    comb = nodes.new("ShaderNodeCombineXYZ")
    for i in range(3):
        nodes.link(shade, comb.inputs[i])
    nodes.link(comb.outputs[0], mix.inputs["B"])
    nodes.link(mix.outputs["Result"], bsdf.inputs["Base Color"])
    nodes.feed(bsdf.inputs["Roughness"], nodes.math(
        "ADD", 0.45, nodes.math("MULTIPLY", fabric, 0.45)))
    nodes.feed(bsdf.inputs["Specular IOR Level"], nodes.math(
        "ADD", 0.2, nodes.math("MULTIPLY", laminate, 0.3)))
    nodes.feed(bsdf.inputs["Sheen Weight"], nodes.math("MULTIPLY", fabric, look.sheen))
    bsdf.inputs["Sheen Roughness"].default_value = 0.4
    nodes.feed(bsdf.inputs["Coat Weight"], laminate)
    bsdf.inputs["Coat Roughness"].default_value = look.laminate_roughness
    bsdf.inputs["Coat IOR"].default_value = 1.5
    return mat


def _wood_material(bpy: Any, wood: Any) -> Any:
    """A varnished wooden table top: growth rings across the grain (Blender's wave
    texture in bands, wandering by its distortion), the figure stretched along the
    grain, pores as fine noise, and a bump that follows the rings."""
    mat = bpy.data.materials.new("wood")
    mat.use_nodes = True
    nt = mat.node_tree
    nodes = _Nodes(nt)
    bsdf = nt.nodes["Principled BSDF"]
    coord = nodes.new("ShaderNodeTexCoord")  # object coordinates: world metres here
    turn = nodes.new("ShaderNodeMapping", vector_type="POINT")
    turn.inputs["Rotation"].default_value = (0.0, 0.0, -np.radians(wood.direction_deg))
    turn.inputs["Location"].default_value = (wood.seed, 2.0 * wood.seed, 0.5 * wood.seed)
    nodes.link(coord.outputs["Object"], turn.inputs["Vector"])
    # bands along x: one period is 2 pi / 20 in the texture's units
    per_m = (2 * np.pi / 20) / (wood.ring_mm * 1e-3)
    grain = nodes.new("ShaderNodeMapping", vector_type="POINT")
    grain.inputs["Scale"].default_value = (per_m, per_m / wood.stretch, per_m)
    nodes.link(turn.outputs["Vector"], grain.inputs["Vector"])
    wave = nodes.new("ShaderNodeTexWave", wave_type="BANDS", bands_direction="X")
    wave.inputs["Scale"].default_value = 1.0
    wave.inputs["Distortion"].default_value = wood.distortion
    wave.inputs["Detail"].default_value = 3.0
    wave.inputs["Detail Scale"].default_value = 0.05
    nodes.link(grain.outputs["Vector"], wave.inputs["Vector"])
    pores = nodes.new("ShaderNodeTexNoise", noise_dimensions="3D")
    pores.inputs["Scale"].default_value = 900.0
    nodes.link(grain.outputs["Vector"], pores.inputs["Vector"])
    late = nodes.math("POWER", wave.outputs["Fac"], 2.0)
    fac = nodes.math("ADD", nodes.math("MULTIPLY", late, 0.85),
                     nodes.math("MULTIPLY", pores.outputs["Fac"], 0.15))
    mix = nodes.new("ShaderNodeMix", data_type="RGBA", blend_type="MIX")
    mix.inputs["A"].default_value = (*wood.light_rgb, 1.0)
    mix.inputs["B"].default_value = (*wood.dark_rgb, 1.0)
    nodes.link(fac, mix.inputs["Factor"])
    nodes.link(mix.outputs["Result"], bsdf.inputs["Base Color"])
    bsdf.inputs["Roughness"].default_value = wood.roughness
    bsdf.inputs["Specular IOR Level"].default_value = 0.5
    bump = nodes.new("ShaderNodeBump")
    bump.inputs["Strength"].default_value = 0.15
    bump.inputs["Distance"].default_value = 0.0002
    nodes.link(fac, bump.inputs["Height"])
    nodes.link(bump.outputs["Normal"], bsdf.inputs["Normal"])
    return mat


def _float_image(bpy: Any, name: str, rgb: NDArray) -> Any:
    """A linear float image of ``rgb`` (h, w, 3), row 0 at v = 0 (Blender's bottom)."""
    h, w = rgb.shape[:2]
    img = bpy.data.images.new(name, width=w, height=h, alpha=False, float_buffer=True)
    img.colorspace_settings.name = "Non-Color"
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = rgb
    img.pixels.foreach_set(rgba.ravel())
    img.pack()
    return img


def _principled(bpy: Any, name: str, rgb: tuple, roughness: float, specular: float) -> Any:
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*rgb, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Specular IOR Level"].default_value = specular
    return mat


def _mesh_object(bpy: Any, name: str, verts: NDArray, tris: NDArray, mat: Any) -> Any:
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts.tolist(), [], tris.tolist())
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _cloth_object(bpy: Any, state: ClothState, mat: Any, layout: NapkinLayout) -> Any:
    tris = state.mesh.triangles()
    obj = _mesh_object(bpy, "napkin", state.mesh.xyz, tris, mat)
    mesh = obj.data
    mesh.shade_smooth() if hasattr(mesh, "shade_smooth") else None
    loops = tris.ravel()
    uv = state.mesh.uv[loops]
    s = TEXTURE_PX_PER_MM
    tex_h, tex_w = sticker_texture(layout).shape[:2]
    tex_uv = np.stack([(uv[:, 0] * s + 0.5) / tex_w, (uv[:, 1] * s + 0.5) / tex_h], axis=1)
    for name, values in (("tex", tex_uv), ("mm", uv)):
        layer = mesh.uv_layers.new(name=name)
        layer.data.foreach_set("uv", values.astype(np.float32).ravel())
    return obj


def _aim(obj: Any, position: NDArray, target: NDArray) -> None:
    """Place a light at ``position`` facing ``target`` (its -z towards it)."""
    from mathutils import Vector

    obj.location = Vector(position.tolist())
    direction = Vector((target - position).tolist())
    obj.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()


def _roll(obj: Any, roll_deg: float) -> None:
    """Turn an aimed light about its own axis by ``roll_deg``."""
    if roll_deg:
        from mathutils import Quaternion

        quat = obj.rotation_euler.to_quaternion() @ Quaternion((0, 0, 1), np.radians(roll_deg))
        obj.rotation_euler = quat.to_euler()


def _add_lights(bpy: Any, look: PhotoLook) -> None:
    scene = bpy.context.scene
    for k, li in enumerate(look.lights):
        data = bpy.data.lights.new(f"light{k}", type="AREA")
        data.shape = "RECTANGLE"
        data.size, data.size_y = li.size_m
        data.energy = li.power_w
        data.color = blackbody_rgb(li.kelvin)
        obj = bpy.data.objects.new(f"light{k}", data)
        scene.collection.objects.link(obj)
        _aim(obj, np.asarray(li.position), np.asarray(li.target))
        _roll(obj, li.roll_deg)
    world = bpy.data.worlds.new("room")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*blackbody_rgb(look.ambient_kelvin), 1.0)
    bg.inputs["Strength"].default_value = look.ambient
    scene.world = world


def _camera(bpy: Any, pose: CameraPose, intrinsics: Intrinsics) -> Any:
    """Blender's camera for the pinhole of ``intrinsics`` at ``pose``.

    Pixel ``u`` of ours is centred at ``u + 0.5`` of Blender's film, whose centre is
    ``W / 2``: the principal point moves by the shifts (in units of the larger side)."""
    from mathutils import Matrix

    if abs(intrinsics.fx - intrinsics.fy) > 1e-6 * intrinsics.fx:
        raise InvalidInputError(
            f"--engine cycles renders square pixels; fx {intrinsics.fx} != fy {intrinsics.fy}"
        )
    w, h = intrinsics.width, intrinsics.height
    data = bpy.data.cameras.new("camera")
    data.sensor_fit = "HORIZONTAL" if w >= h else "VERTICAL"
    data.sensor_width = data.sensor_height = 36.0
    side = max(w, h)
    data.lens = intrinsics.fx * 36.0 / side
    data.shift_x = (w / 2 - (intrinsics.cx + 0.5)) / side
    data.shift_y = ((intrinsics.cy + 0.5) - h / 2) / side
    data.clip_start, data.clip_end = 0.01, 50.0
    obj = bpy.data.objects.new("camera", data)
    bpy.context.scene.collection.objects.link(obj)
    rot = pose.rotation @ np.diag([1.0, -1.0, -1.0])  # Blender: y up, looking along -z
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = rot, pose.position
    obj.matrix_world = Matrix(m.tolist())
    bpy.context.scene.camera = obj
    return obj


def _camera_body(bpy: Any, pose: CameraPose, mat: Any) -> None:
    """The camera's body (a 12 x 4 x 5 cm box behind the lens) and its mount arm (a
    4 cm bar up and back 40 cm): they shade the scene and are unseen by the camera."""
    boxes = (
        (np.array([0.0, 0.0, -0.03]), np.array([0.06, 0.025, 0.03])),
        (np.array([0.0, -0.2, -0.08]), np.array([0.02, 0.2, 0.02])),
    )
    for k, (centre_cam, half) in enumerate(boxes):
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        verts = pose.camera_to_world(centre_cam + corners * half)
        faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4),
                 (1, 5, 7, 3)]
        mesh = bpy.data.meshes.new(f"mount{k}")
        mesh.from_pydata(verts.tolist(), [], faces)
        mesh.materials.append(mat)
        obj = bpy.data.objects.new(f"mount{k}", mesh)
        obj.visible_camera = False
        bpy.context.scene.collection.objects.link(obj)


def _settings(bpy: Any, intrinsics: Intrinsics, samples: int, seed: int, threads: int) -> None:
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    cy = scene.cycles
    cy.device = "CPU"
    cy.samples = samples
    cy.use_adaptive_sampling = True
    cy.adaptive_threshold = 0.02
    cy.use_denoising = True
    cy.denoiser = "OPENIMAGEDENOISE"
    cy.seed = seed
    cy.use_animated_seed = False
    cy.max_bounces = 4
    cy.diffuse_bounces = 2
    cy.glossy_bounces = 2
    cy.transmission_bounces = 0
    cy.transparent_max_bounces = 0
    cy.caustics_reflective = cy.caustics_refractive = False
    scene.render.resolution_x, scene.render.resolution_y = intrinsics.width, intrinsics.height
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0
    scene.render.threads_mode = "FIXED"
    scene.render.threads = max(1, threads)
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.exr_codec = "ZIP"
    scene.view_settings.view_transform = "Standard"


def _read_linear(bpy: Any, path: Path, shape: tuple[int, int]) -> NDArray[np.float64]:
    img = bpy.data.images.load(str(path))
    h, w = shape
    buf = np.empty(h * w * 4, np.float32)
    img.pixels.foreach_get(buf)
    bpy.data.images.remove(img)
    return buf.reshape(h, w, 4)[::-1, :, :3].astype(np.float64)  # Blender's rows bottom-up


def path_trace(
    state: ClothState,
    pose: CameraPose,
    intrinsics: Intrinsics,
    look: PhotoLook,
    *,
    layout: NapkinLayout | None = None,
    samples: int = 32,
    seed: int = 0,
    threads: int = 2,
) -> NDArray[np.float64]:
    """Cycles' linear RGB image (H, W, 3) of the scene (scene-referred, not exposed)."""
    bpy = import_bpy()
    layout = layout or default_layout()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    _settings(bpy, intrinsics, samples, seed, threads)
    _cloth_object(bpy, state, _cloth_material(bpy, look, layout), layout)
    big = 3.0
    table = np.array([[-big, -big, -2e-4], [big, -big, -2e-4], [big, big, -2e-4],
                      [-big, big, -2e-4]]) + np.append(state.mesh.xyz[:, :2].mean(axis=0), 0)
    table_mat = (_wood_material(bpy, look.wood) if look.wood is not None
                 else _principled(bpy, "table", look.table_rgb, 0.7, 0.3))
    _mesh_object(bpy, "table", table, np.array([[0, 1, 2], [0, 2, 3]]), table_mat)
    _add_lights(bpy, look)
    _camera(bpy, pose, intrinsics)
    if look.camera_body:
        _camera_body(bpy, pose, _principled(bpy, "mount", (0.05, 0.05, 0.05), 0.5, 0.5))
    with tempfile.TemporaryDirectory(prefix="dgli-cycles-") as tmp:
        out = Path(tmp) / "render.exr"
        bpy.context.scene.render.filepath = str(out)
        bpy.ops.render.render(write_still=True)
        linear = _read_linear(bpy, out, (intrinsics.height, intrinsics.width))
    bpy.ops.wm.read_factory_settings(use_empty=True)  # free the scene's memory
    return linear


def _depth_view(
    state: ClothState, pose: CameraPose, intrinsics: Intrinsics, layout: NapkinLayout
) -> tuple[NDArray, NDArray, NDArray, RaycastScene]:
    """Exact z-depth (H, W) mm, the cosine of each surface to the camera and where the
    laminate is, from one ray per pixel centre into the same geometry."""
    from .render import _pixel_rays
    from .render_scene import sample_texture

    scene = RaycastScene(state)
    origins, dirs = _pixel_rays(pose, intrinsics)
    hits = scene.cast(origins, dirs)
    shape = (intrinsics.height, intrinsics.width)
    t = hits["t_hit"].astype(np.float64)
    z_mm = np.where(np.isfinite(t), t * 1000.0, 0.0)
    normals = hits["primitive_normals"].astype(np.float64)
    views = -dirs / np.linalg.norm(dirs, axis=1)[:, None]
    cos = (normals * views).sum(axis=1)
    on_cloth = hits["geometry_ids"] == scene.cloth_id
    glossy = np.zeros(len(t), bool)
    uv = scene.material_uv(hits, on_cloth)
    glossy[on_cloth] = sample_texture(sticker_texture(layout), uv)[:, 3] < 0.5
    return z_mm.reshape(shape), cos.reshape(shape), glossy.reshape(shape), scene


def render_cycles(
    state: ClothState,
    pose: CameraPose,
    intrinsics: Intrinsics,
    look: PhotoLook,
    rng: np.random.Generator,
    *,
    layout: NapkinLayout | None = None,
    samples: int = 32,
    seed: int = 0,
    threads: int = 2,
    clean: bool = False,
    camera: CameraModel | None = None,
    tof: ToFModel | None = None,
) -> RenderResult:
    """A path-traced RGB-D pair of a cloth state, as a camera delivers it.

    Parameters
    ----------
    state, pose, intrinsics
        The cloth, the camera and its pinhole (square pixels, no distortion).
    look : PhotoLook
        Lights and materials (:func:`draw_look`).
    rng : Generator
        The camera pipeline's and the depth model's draws.
    layout : NapkinLayout, keyword-only
    samples : int, keyword-only
        Cycles' samples per pixel (adaptive, then OpenImageDenoise).
    seed : int, keyword-only
        Cycles' seed.
    threads : int, keyword-only
        CPU threads Cycles uses.
    clean : bool, keyword-only
        An ideal camera: exposure from the scene's white, exact depth to the mm.
    camera, tof : CameraModel, ToFModel, keyword-only
        The colour camera's pipeline and the depth camera (default: their defaults;
        ignored with ``clean``).

    Returns
    -------
    RenderResult
        As the rasteriser's, ``info["engine"] = "cycles"`` with the look and what the
        camera pipeline drew.
    """
    layout = layout or default_layout()
    intrinsics = Intrinsics(
        intrinsics.width, intrinsics.height, intrinsics.fx, intrinsics.fy,
        intrinsics.cx, intrinsics.cy,
    )
    import time

    cpu = time.process_time()
    linear = path_trace(
        state, pose, intrinsics, look, layout=layout, samples=samples, seed=seed,
        threads=threads,
    )
    cpu = time.process_time() - cpu  # all of Cycles' threads
    camera = CameraModel(ideal=True) if clean else (camera or CameraModel())
    tof = ToFModel(ideal=True) if clean else (tof or ToFModel())
    color, drawn = colour_camera(linear, camera, rng)
    z_mm, cos, glossy, scene = _depth_view(state, pose, intrinsics, layout)
    depth = tof_depth(z_mm, cos, glossy, tof, rng)
    from .conditions import Conditions

    cond = Conditions()
    return RenderResult(
        color=color,
        depth_mm=depth,
        sticker_points_cam=_sticker_points_cam(state, pose, intrinsics, cond),
        visible_fraction=_visible_fraction(state, pose, scene, intrinsics, layout),
        pose=pose,
        intrinsics=intrinsics,
        info={
            "engine": "cycles",
            "samples": samples,
            "cycles_cpu_s": round(cpu, 2),
            "look": look.to_json(),
            "camera": drawn,
        },
    )
