"""The physics cloth as a :class:`~dgli_vision.sim.cloth.states.ClothState`: the
project's renderer draws it (stickers and all) and ``dgli label`` reads it.

The simulator's grid (sim frame, vertices ``radius`` above the table) is brought down
onto the table, resampled onto a finer grid (bilinear, so the stickers' discs fall on
smooth cloth), turned and placed on the table as
:func:`~dgli_vision.sim.cloth.states.make_state` places a state.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...core.layout import NapkinLayout
from ..cloth.mesh import ClothMesh, flat_mesh
from ..cloth.states import ClothState, boundary_uv, sticker_visibility

__all__ = ["cloth_state", "sim_to_world", "world_to_sim"]


def _rotation(yaw: float) -> NDArray[np.float64]:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s], [s, c]])


def sim_to_world(
    xyz: NDArray[np.float64], layout: NapkinLayout, yaw: float, offset_m: tuple[float, float]
) -> NDArray[np.float64]:
    """Sim-frame points (k, 3) to the table's world frame: turned by ``yaw`` about the
    napkin's centre, which goes to ``offset_m`` (as ``make_state`` places a state)."""
    centre = np.array([layout.width_mm, layout.height_mm]) * 0.5e-3
    out = np.array(xyz, dtype=float, copy=True)
    out[:, :2] = (out[:, :2] - centre) @ _rotation(yaw).T + np.asarray(offset_m)
    return out


def world_to_sim(
    xyz: NDArray[np.float64], layout: NapkinLayout, yaw: float, offset_m: tuple[float, float]
) -> NDArray[np.float64]:
    """The inverse of :func:`sim_to_world`."""
    centre = np.array([layout.width_mm, layout.height_mm]) * 0.5e-3
    out = np.array(xyz, dtype=float, copy=True)
    out[:, :2] = (out[:, :2] - np.asarray(offset_m)) @ _rotation(yaw) + centre
    return out


def cloth_state(
    xyz_sim: NDArray[np.float64],
    shape: tuple[int, int],
    layout: NapkinLayout,
    *,
    radius_m: float,
    yaw: float = 0.0,
    offset_m: tuple[float, float] = (0.0, 0.0),
    class_id: str = "none",
    variant: str | None = None,
    spacing_mm: float = 5.0,
    params: dict[str, Any] | None = None,
) -> ClothState:
    """The simulated cloth as a state.

    Parameters
    ----------
    xyz_sim : ndarray, shape (ny * nx, 3)
        The grid's vertices, sim frame, metres (row-major, v slowest).
    shape : (int, int)
        The grid's shape (ny, nx).
    layout : NapkinLayout
    radius_m : float, keyword-only
        The vertices' collision radius: the cloth's lowest layer rests this far up.
    yaw, offset_m : keyword-only
        The placement on the table (:func:`sim_to_world`).
    class_id, variant : keyword-only
        The labels to attach (the state the cloth should be in; "none": unknown).
    spacing_mm : float, keyword-only
        The finer grid's spacing.
    params : dict, keyword-only
        Recorded in the state.

    Returns
    -------
    ClothState
    """
    ny, nx = shape
    coarse = ClothMesh(
        np.zeros((ny * nx, 2)), np.asarray(xyz_sim, dtype=float) - (0.0, 0.0, radius_m),
        shape, (layout.width_mm / (nx - 1), layout.height_mm / (ny - 1)),
    )
    fine = flat_mesh(layout, spacing_mm=spacing_mm)
    xyz = coarse.interpolate(fine.uv)
    xyz[:, 2] = np.maximum(xyz[:, 2], 0.0)
    mesh = fine.with_xyz(sim_to_world(xyz, layout, yaw, offset_m))
    info = dict(params or {})
    info.update(yaw_rad=float(yaw), offset_m=[float(v) for v in offset_m], physics=True)
    return ClothState(
        class_id=class_id,
        variant=variant,
        mesh=mesh,
        sticker_points=mesh.interpolate(layout.sticker_uv),
        visible_fraction=sticker_visibility(mesh, layout, thickness_m=2 * radius_m),
        corner_points=mesh.interpolate(layout.corner_uv),
        boundary=mesh.interpolate(boundary_uv(layout)),
        params=info,
    )
