"""The MuJoCo model of the napkin: a flex shell on a table, with grippers to hold it.

The napkin is a ``flexcomp`` of ``grid x grid`` vertices (a triangulated shell with
membrane and bending elasticity, MuJoCo's ``elastic2d="both"``; the cells cut along
alternating diagonals, :func:`grid_triangles`) lying in the **sim frame**: the flat
napkin's material frame, metres, corner A at the origin, u along x, v along y, z up,
the table the plane z = 0 (the frame of :func:`~dgli_vision.sim.cloth.states.make_state`
before its rotation and placement).
Each vertex is a small sphere of the flex's radius, so the cloth rests ``radius`` above
the table and two layers lie ``2 radius`` apart. Each hand is a mocap body with a
``connect`` equality to the vertex it grasps, off until the gripper closes.

The material (:class:`ClothMaterial`) is a cotton napkin's: 200 g/m^2 (32 g for
400 x 400 mm), an in-plane stiffness ``young * thickness`` of 3 kN/m (a woven cotton's
stretch under its own weight is well below 1%), friction 0.5 on the table and on
itself. The bending rigidity, 2.5e-7 N m, is below a real napkin's (about 1e-5 N m):
on a 20 mm grid a crease is one cell wide, and at the real rigidity a laid flap springs
back flat once let go (measured); MuJoCo's shell has no plasticity to keep a crease.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...core.errors import InvalidValueError
from ...core.layout import NapkinLayout
from . import require_mujoco

__all__ = ["ClothMaterial", "ClothModel", "build_model", "grid_triangles"]


@dataclass(frozen=True)
class ClothMaterial:
    """The simulated napkin's physical parameters.

    Attributes
    ----------
    grid : int
        Vertices along each side (the spacing is the napkin's side / (grid - 1)).
    mass_kg : float
        The whole napkin's mass (cotton, 200 g/m^2: 0.032 kg for 400 x 400 mm).
    young_pa : float
        Young's modulus of the shell, Pa.
    poisson : float
        Poisson's ratio.
    shell_thickness_m : float
        The elastic shell's thickness, m: with ``young_pa`` it sets the in-plane
        stiffness (``young * t``, N/m) and the bending rigidity (``young t^3 / 12 (1 -
        poisson^2)``, N m); 0.03 mm at 100 MPa gives 3 kN/m and 2.5e-7 N m.
    damping : float
        The shell's elastic damping (Rayleigh, s).
    friction : float
        Sliding friction, cloth on the table and on itself.
    radius_m : float
        The vertices' collision radius, m: the cloth rests this far above the table,
        two layers lie twice it apart.
    timestep_s : float
        The simulator's step, s (the discrete integrator; 8 ms let a settling corner
        bounce 13 mm up).
    """

    grid: int = 21
    mass_kg: float = 0.032
    young_pa: float = 1.0e8
    poisson: float = 0.3
    shell_thickness_m: float = 3.0e-5
    damping: float = 0.002
    friction: float = 0.5
    radius_m: float = 1.5e-3
    timestep_s: float = 0.004

    def __post_init__(self) -> None:
        if not 3 <= self.grid <= 81:
            raise InvalidValueError(f"grid must be 3-81 vertices a side; got {self.grid}")
        for name in ("mass_kg", "young_pa", "shell_thickness_m", "radius_m", "timestep_s"):
            if not getattr(self, name) > 0:
                raise InvalidValueError(f"{name} must be positive; got {getattr(self, name)}")

    @property
    def bending_rigidity_nm(self) -> float:
        """The shell's bending rigidity, N m."""
        t = self.shell_thickness_m
        return self.young_pa * t**3 / (12 * (1 - self.poisson**2))

    @property
    def stretch_stiffness_n_per_m(self) -> float:
        """The shell's in-plane stiffness ``young * thickness``, N/m."""
        return self.young_pa * self.shell_thickness_m


@dataclass(frozen=True, eq=False)
class ClothModel:
    """A built model and its data, with the vertex order of the project's grid.

    Attributes
    ----------
    model, data : mujoco.MjModel, mujoco.MjData
    uv : ndarray, shape (grid * grid, 2)
        Material coordinates (mm) of the grid's vertices, row-major, v slowest (the
        order of :class:`~dgli_vision.sim.cloth.mesh.ClothMesh`).
    flex_index : ndarray of int, shape (grid * grid,)
        The flex vertex of each grid vertex.
    hand_vertices : tuple of int
        The grid vertex each hand grasps.
    material : ClothMaterial
    shape : (int, int)
        The grid's shape (ny, nx).
    spacing_mm : (float, float)
    """

    model: Any
    data: Any
    uv: NDArray[np.float64]
    flex_index: NDArray[np.intp]
    hand_vertices: tuple[int, ...]
    material: ClothMaterial
    shape: tuple[int, int]
    spacing_mm: tuple[float, float]

    def positions(self) -> NDArray[np.float64]:
        """The grid's vertices now, sim frame, metres, shape (grid * grid, 3)."""
        return np.array(self.data.flexvert_xpos[self.flex_index])


def grid_triangles(grid: int) -> NDArray[np.intp]:
    """The shell's triangles (2 (grid-1)^2, 3) over the row-major grid, counter-clockwise
    seen from +z, each cell cut along one diagonal, the two diagonals in a checkerboard
    (a "union jack"): a crease at 45 degrees then finds a line of triangle edges within
    one cell whichever way it runs. (With every cell cut the same way, a fold across the
    cuts has to bend the triangles themselves: measured, it dragged the napkin 27 mm
    where the fold along them dragged it 0.5 mm.)"""
    j, i = np.meshgrid(np.arange(grid - 1), np.arange(grid - 1))  # i: row (v), j: column
    a = (i * grid + j).ravel()
    b, c, d = a + 1, a + grid + 1, a + grid
    even = ((i + j) % 2 == 0).ravel()
    t1 = np.where(even[:, None], np.stack([a, b, c], 1), np.stack([a, b, d], 1))
    t2 = np.where(even[:, None], np.stack([a, c, d], 1), np.stack([b, c, d], 1))
    return np.concatenate([t1, t2])


def _xml(layout: NapkinLayout, m: ClothMaterial, hands: int) -> str:
    """The model's MJCF text (hands' ``connect`` equalities to vertex bodies filled in
    later by name). The flex's points are the grid's, in its row-major order."""
    w, h = layout.width_mm * 1e-3, layout.height_mm * 1e-3
    u, v = np.meshgrid(np.linspace(0, w, m.grid), np.linspace(0, h, m.grid))
    points = " ".join(f"{x:.6f} {y:.6f} {m.radius_m}" for x, y in zip(u.ravel(), v.ravel()))
    elements = " ".join(str(int(k)) for k in grid_triangles(m.grid).ravel())
    bodies = "".join(f'<body name="hand{k}" mocap="true" pos="{-1 - k} 0 0.5"/>'
                     for k in range(hands))
    return f"""<mujoco model="napkin">
  <option timestep="{m.timestep_s}" integrator="discrete" solver="CG" tolerance="1e-6"
          iterations="100"/>
  <worldbody>
    <geom name="table" type="plane" size="2 2 0.1" friction="{m.friction}"/>
    {bodies}
    <flexcomp name="cloth" type="direct" point="{points}" element="{elements}"
              radius="{m.radius_m}" dim="2" mass="{m.mass_kg}">
      <contact condim="3" selfcollide="auto" friction="{m.friction}" solref="0.004 1"/>
      <elasticity young="{m.young_pa}" poisson="{m.poisson}"
                  thickness="{m.shell_thickness_m}" damping="{m.damping}" elastic2d="both"/>
    </flexcomp>
  </worldbody>
  <equality>{{equalities}}</equality>
</mujoco>"""


def _grid_order(layout: NapkinLayout, grid: int, flat_xyz: NDArray) -> NDArray[np.intp]:
    """The flex vertex at each grid vertex (row-major, v slowest), from the flat
    positions of the flex's vertices (m, sim frame)."""
    su, sv = layout.width_mm / (grid - 1), layout.height_mm / (grid - 1)
    iu = np.rint(flat_xyz[:, 0] * 1e3 / su).astype(int)
    iv = np.rint(flat_xyz[:, 1] * 1e3 / sv).astype(int)
    order = np.full(grid * grid, -1, dtype=np.intp)
    order[iv * grid + iu] = np.arange(len(flat_xyz))
    if np.any(order < 0):
        raise RuntimeError("the flex grid's vertices do not fill the napkin's grid")
    return order


def build_model(
    layout: NapkinLayout,
    start_xyz: NDArray[np.float64] | None = None,
    *,
    material: ClothMaterial | None = None,
    hand_vertices: tuple[int, ...] = (),
) -> ClothModel:
    """The napkin's model, its vertices at ``start_xyz``.

    Parameters
    ----------
    layout : NapkinLayout
        The napkin's size.
    start_xyz : ndarray, shape (grid * grid, 3), optional
        Where each grid vertex starts (sim frame, metres, the cloth's midsurface; a
        folded state's layers at least ``2 radius`` apart); default flat.
    material : ClothMaterial, keyword-only
    hand_vertices : tuple of int, keyword-only
        The grid vertex each hand grasps (one mocap body per hand).

    Returns
    -------
    ClothModel
    """
    mujoco = require_mujoco()
    m = material or ClothMaterial()
    n = m.grid * m.grid
    if start_xyz is not None and np.shape(start_xyz) != (n, 3):
        raise InvalidValueError(f"start_xyz must have shape ({n}, 3); got {np.shape(start_xyz)}")
    if any(not 0 <= v < n for v in hand_vertices):
        raise InvalidValueError(f"hand vertices must be in 0..{n - 1}; got {hand_vertices}")
    text = _xml(layout, m, len(hand_vertices))
    flat = mujoco.MjModel.from_xml_string(text.replace("{equalities}", ""))
    probe = mujoco.MjData(flat)
    mujoco.mj_forward(flat, probe)
    order = _grid_order(layout, m.grid, np.array(probe.flexvert_xpos))
    eqs = "".join(
        f'<connect name="grip{k}" body1="hand{k}" body2="cloth_{order[v]}" anchor="0 0 0" '
        f'active="false" solref="0.005 1"/>'
        for k, v in enumerate(hand_vertices)
    )
    model = mujoco.MjModel.from_xml_string(text.replace("{equalities}", eqs)) if eqs else flat
    data = mujoco.MjData(model)
    if start_xyz is not None:
        _place(model, data, order, np.asarray(start_xyz, dtype=float), m.radius_m)
    mujoco.mj_forward(model, data)
    su, sv = layout.width_mm / (m.grid - 1), layout.height_mm / (m.grid - 1)
    uu, vv = np.meshgrid(np.arange(m.grid) * su, np.arange(m.grid) * sv)
    uv = np.stack([uu.ravel(), vv.ravel()], axis=1)
    return ClothModel(model, data, uv, order, tuple(hand_vertices), m, (m.grid, m.grid),
                      (su, sv))


def _place(model: Any, data: Any, order: NDArray, xyz: NDArray, radius: float) -> None:
    """Set each vertex body's three slide joints so that grid vertex k lies at
    ``xyz[k]`` lifted by ``radius`` (its sphere then rests on the table)."""
    for k, f in enumerate(order):
        body = model.flex_vertbodyid[model.flex_vertadr[0] + f]
        adr = model.jnt_qposadr[model.body_jntadr[body]]
        target = xyz[k] + (0.0, 0.0, radius)
        data.qpos[adr:adr + 3] = target - model.body_pos[body]
