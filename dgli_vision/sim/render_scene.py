"""The renderer's scene: an Open3D ``RaycastingScene`` (CPU) of one cloth state, the table
and the solids the capture conditions add, and the stickers' texture in material
coordinates (see :mod:`dgli_vision.sim.render`)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ..core.colour import srgb_to_linear
from ..core.layout import NapkinLayout, default_layout
from .cloth.states import ClothState
from .conditions import SceneObject

__all__ = ["TEXTURE_PX_PER_MM", "Lighting", "RaycastScene", "sample_texture", "sticker_texture"]

#: Resolution of the sticker texture, pixels per mm of cloth.
TEXTURE_PX_PER_MM = 2.0


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


@lru_cache(maxsize=4)
def _texture_cached(layout: NapkinLayout) -> NDArray[np.float32]:
    import cv2

    s = TEXTURE_PX_PER_MM
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


def sample_texture(tex: NDArray, uv_mm: NDArray) -> NDArray:
    """Bilinear lookup of the texture at material points (n, 2) mm -> (n, 4)."""
    import cv2

    s = TEXTURE_PX_PER_MM
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


class RaycastScene:
    """Open3D raycasting scene of one cloth state and the table."""

    def __init__(self, state: ClothState, objects: list[SceneObject] = ()) -> None:
        from ..core.optional import open3d

        o3d = open3d("rendering")

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
