"""Semi-gloss stickers under a large light (the ``sheen`` condition): the reflection of an
area light in the stickers' vinyl and the napkin's fabric, as the renderer adds it (see
:mod:`dgli_vision.sim.render`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ..core.camera import CameraPose
from ..core.colour import srgb_to_linear
from ..core.layout import NapkinLayout
from .cloth.states import ClothState
from .conditions import (
    Conditions,
    Sheen,
    area_light_lobe,
    mirror_light_direction,
    sheen_sticker,
    specular_for_saturation,
)
from .render_scene import RaycastScene

if TYPE_CHECKING:
    from .render_scene import Lighting

__all__ = ["SHEEN_EXPOSURE_PEAK", "SheenLobes", "sheen_lobes"]

#: Linear level the brightest pixel is exposed to under ``sheen`` (sRGB about 231): a
#: camera's auto-exposure keeps the large light's reflection from blowing out.
SHEEN_EXPOSURE_PEAK = 0.8
#: HSV saturations every printed colour keeps in the full lobe under ``sheen``: pastel,
#: yet never so pale and bright that it reads as a highlight (chroma below a quarter of
#: the brightness, the tool's definition).
_SHEEN_SATURATION = (0.13, 0.3)


@dataclass(frozen=True, eq=False)
class SheenLobes:
    """A large area light's reflection on the cloth hits (see :func:`sheen_lobes`)."""

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
                diffuse * gain, saturation, tint=gain, peak=SHEEN_EXPOSURE_PEAK
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


def sheen_lobes(
    cond: Conditions,
    state: ClothState,
    scene: RaycastScene,
    pose: CameraPose,
    lighting: Lighting,
    layout: NapkinLayout,
    hits: dict[str, NDArray],
    dirs: NDArray,
    tex: NDArray,
) -> SheenLobes | None:
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
    return SheenLobes(
        sheen=sheen,
        vinyl=area_light_lobe(normals, views, light, radius, sheen.shininess),
        fabric=area_light_lobe(normals, views, light, radius, sheen.cloth_shininess),
        napkin=tex[:, 3],
        sticker=sid,
        diffuse=disc * shade,
        printed=printed,
    )
