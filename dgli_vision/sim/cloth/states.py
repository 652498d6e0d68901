"""The twelve cloth states of SPEC section 3, sampled with a seeded generator.

A state is built by folding the flat mesh (:mod:`.fold`) in material coordinates, then
adding smooth low-amplitude wrinkles, a rotation about the vertical and a placement on
the table. It knows its class, variant, mesh, sticker centres and which stickers a camera
straight above can see.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from ...core.classes import CLASS_IDS, CLASS_NAMES, CORNERS, VARIANTS
from ...core.dgli import cloth_coordinates
from ...core.errors import InvalidValueError
from ...core.fold_graph import unfold
from ...core.layout import NapkinLayout, default_layout
from .fold import fold
from .mesh import ClothMesh, flat_mesh

__all__ = [
    "CLASS_IDS",
    "CLASS_NAMES",
    "VARIANTS",
    "ClothState",
    "FoldStep",
    "boundary_uv",
    "corner_fold_line",
    "diagonal_fold_line",
    "disc_samples",
    "draw_fold_steps",
    "make_state",
    "normalize_rng",
    "sample_state",
    "side_fold_line",
    "sticker_visibility",
]

#: Sticker ids visible from straight above are decided on 13 points of the disc; a
#: sticker counts as visible when at least this fraction of them is uncovered.
VISIBLE_FRACTION = 0.5


def normalize_rng(rng: np.random.Generator | int | None) -> np.random.Generator:
    """A Generator from a Generator, a seed or None (a fresh, unseeded one)."""
    if isinstance(rng, np.random.Generator):
        return rng
    return np.random.default_rng(rng)


@dataclass(frozen=True)
class FoldStep:
    """One fold: a line through two material points (mm), the flap side, the direction."""

    p0: tuple[float, float]
    p1: tuple[float, float]
    flap: tuple[float, float]
    under: bool = False

    def apply(self, mesh: ClothMesh, *, angle: float = np.pi, thickness_m: float) -> ClothMesh:
        """Fold ``mesh`` by this step (``angle`` in radians, pi = laid flat)."""
        return fold(
            mesh,
            self.p0,
            self.p1,
            self.flap,
            angle=angle,
            under=self.under,
            thickness_m=thickness_m,
        )


@dataclass(frozen=True, eq=False)
class ClothState:
    """A simulated cloth state.

    Attributes
    ----------
    class_id : str
        ``"01"`` ... ``"12"``.
    variant : str or None
        SPEC's variant string.
    mesh : ClothMesh
        The cloth, world coordinates in metres (z up, table at z = 0).
    sticker_points : ndarray, shape (16, 3)
        World positions of the sticker centres, metres (SPEC order).
    visible_fraction : ndarray, shape (16,)
        Fraction of each sticker's disc seen by a camera straight above.
    corner_points : ndarray, shape (4, 3)
        World positions of corners A, B, C, D, metres.
    boundary : ndarray, shape (m, 3)
        The boundary polyline A -> B -> C -> D (open: D -> A is implied), metres.
    params : dict
        How the state was drawn (legs, fold offsets, yaw, wrinkle amplitude, ...).
    """

    class_id: str
    variant: str | None
    mesh: ClothMesh
    sticker_points: NDArray[np.float64]
    visible_fraction: NDArray[np.float64]
    corner_points: NDArray[np.float64]
    boundary: NDArray[np.float64]
    params: dict[str, Any] = field(default_factory=dict)

    @property
    def name(self) -> str:
        """The class name (``"corner-over"``...); ``"none"`` for a state outside the
        twelve (:mod:`.outside`)."""
        return CLASS_NAMES.get(self.class_id, self.class_id)

    @property
    def visible(self) -> NDArray[np.bool_]:
        """Stickers a camera straight above sees, shape (16,)."""
        return self.visible_fraction >= VISIBLE_FRACTION

    def segments(self) -> NDArray[np.float64]:
        """The 8 oriented segments (8, 2, 3) in metres: sticker 2i to sticker 2i + 1."""
        return self.sticker_points.reshape(-1, 2, 3)

    def coordinates(self) -> NDArray[np.float64]:
        """The 28 dGLI cloth coordinates (up = +z), all stickers known."""
        return cloth_coordinates(self.segments())


def _corner_index(corner: str) -> int:
    return CORNERS.index(corner)


def corner_fold_line(
    layout: NapkinLayout, corner: str, leg_out_mm: float, leg_in_mm: float, *, under: bool = False
) -> FoldStep:
    """Fold of one corner: the line crosses its leaving edge ``leg_out_mm`` from it and its
    arriving edge ``leg_in_mm`` from it (counter-clockwise walk)."""
    k = _corner_index(corner)
    c = layout.corner_uv
    here, nxt, prev = c[k], c[(k + 1) % 4], c[(k - 1) % 4]
    e_out = (nxt - here) / np.linalg.norm(nxt - here)
    e_in = (prev - here) / np.linalg.norm(prev - here)
    p0 = here + leg_out_mm * e_out
    p1 = here + leg_in_mm * e_in
    return FoldStep(tuple(p0), tuple(p1), tuple(here), under)


def side_fold_line(
    layout: NapkinLayout, side: str, inset_mm: float, *, under: bool = False
) -> FoldStep:
    """Fold of one side along the line parallel to it ``inset_mm`` inside the napkin."""
    c = layout.corner_uv
    x, y = c[_corner_index(side[0])], c[_corner_index(side[1])]
    e = (y - x) / np.linalg.norm(y - x)
    inward = np.array([-e[1], e[0]])
    return FoldStep(
        tuple(x + inset_mm * inward), tuple(y + inset_mm * inward), tuple((x + y) / 2), under
    )


def diagonal_fold_line(
    layout: NapkinLayout, corner: str, offset0_mm: float, offset1_mm: float
) -> FoldStep:
    """Fold of ``corner`` over the diagonal of its two neighbours, the line moved by the
    given offsets (mm, towards the corner when positive) at either end."""
    k = _corner_index(corner)
    c = layout.corner_uv
    prev, nxt, here = c[(k - 1) % 4], c[(k + 1) % 4], c[k]
    t = (nxt - prev) / np.linalg.norm(nxt - prev)
    n = np.array([-t[1], t[0]])
    if n @ (here - prev) < 0:
        n = -n
    # Points 15 mm inside the napkin along the line, so that both lie on the cloth.
    p0 = prev + offset0_mm * n + 15.0 * t
    p1 = nxt + offset1_mm * n - 15.0 * t
    return FoldStep(tuple(p0), tuple(p1), tuple(here), False)


class _FoldDraw:
    """Draws the folds of one state, collecting the fold lines, their words (those of
    :mod:`dgli_vision.core.fold_graph`) and the drawn parameters."""

    def __init__(self, layout: NapkinLayout, rng: np.random.Generator) -> None:
        self.layout = layout
        self.rng = rng
        self.params: dict[str, Any] = {}
        self.steps: list[FoldStep] = []
        self.words: list[str] = []

    def along(self, a: str, b: str) -> float:
        """Scale of a fold size measured from corner a towards corner b."""
        c = self.layout.corner_uv
        d = np.abs(c[_corner_index(b)] - c[_corner_index(a)])
        return float(d @ np.array(self.layout.fold_scale) / d.sum())

    def legs_scale(self, name: str) -> tuple[float, float]:
        """Scales of a corner's legs along its leaving and its arriving edge."""
        k = _corner_index(name)
        return self.along(name, CORNERS[(k + 1) % 4]), self.along(name, CORNERS[k - 1])

    def across(self, side: str) -> float:
        """Scale of a fold size measured from a side into the napkin."""
        return self.along(side[1], CORNERS[(_corner_index(side[1]) + 1) % 4])

    def corner(self, name: str, lo: float, hi: float, *, under: bool = False) -> None:
        """A corner folded with both legs drawn in [lo, hi] mm (scaled)."""
        s_out, s_in = self.legs_scale(name)
        u = self.rng.uniform
        legs = (float(u(lo, hi)) * s_out, float(u(lo, hi)) * s_in)
        self.params.setdefault("legs_mm", {})[name] = legs
        self.steps.append(corner_fold_line(self.layout, name, *legs, under=under))
        self.words.append(f"{name} {'under' if under else 'over'}")

    def two_corners_of_side(self, class_id: str, variant: str) -> None:
        """Classes 04 (a side's two corners) and 05 (two corners, one across the other)."""
        u = self.rng.uniform
        side, top = (variant, variant[1]) if class_id == "04" else variant.split("/")
        if class_id == "04":
            top = side[int(self.rng.integers(2))]
        first = side[0] if top == side[1] else side[1]
        shared, other = ((150, 160), (150, 180)) if class_id == "04" else ((170, 195), (230, 260))
        for name in (first, top):
            # The shared edge leaves the first corner of the side and arrives at the second.
            leg_shared = float(u(*shared))
            leg_other = float(u(*other))
            legs = (leg_shared, leg_other) if name == side[0] else (leg_other, leg_shared)
            legs = tuple(leg * s for leg, s in zip(legs, self.legs_scale(name)))
            self.params.setdefault("legs_mm", {})[name] = legs
            self.steps.append(corner_fold_line(self.layout, name, *legs))
            crossing = f" crossing {first}" if class_id == "05" and name == top else ""
            self.words.append(f"{name} over{crossing}")
        self.params["order"] = [first, top]

    def side(self, variant: str, lo: float, hi: float, word: str, *, under: bool = False) -> None:
        """A strip along a side folded, its inset drawn in [lo, hi] mm (scaled)."""
        inset = float(self.rng.uniform(lo, hi)) * self.across(variant)
        self.params["inset_mm"] = inset
        self.steps.append(side_fold_line(self.layout, variant, inset, under=under))
        self.words.append(f"{variant} {word}")

    def diagonal(self, variant: str) -> None:
        """The napkin folded along a diagonal, its ends offset up to 10 mm (scaled)."""
        s = min(self.layout.fold_scale)
        u = self.rng.uniform
        offsets = (float(u(-10, 10)) * s, float(u(-10, 10)) * s)
        self.params["diagonal_offsets_mm"] = offsets
        self.steps.append(diagonal_fold_line(self.layout, variant, *offsets))
        self.words.append(f"{variant} diagonal")


def _draw_class_folds(draw: _FoldDraw, class_id: str, variant: str | None) -> None:
    """Draw the folds of class ``class_id`` (SPEC section 3's ranges) into ``draw``."""
    if class_id == "01":
        pass
    elif class_id in ("02", "03"):
        draw.corner(variant, 150, 200, under=class_id == "03")
    elif class_id in ("04", "05"):
        draw.two_corners_of_side(class_id, variant)
    elif class_id == "06":
        for name in variant:
            draw.corner(name, 150, 200)
    elif class_id == "07":
        for name in CORNERS:
            if name != variant:
                draw.corner(name, 150, 170)
    elif class_id == "08":
        for name in CORNERS:
            draw.corner(name, 170, 200)
    elif class_id in ("09", "10"):
        under = class_id == "10"
        draw.side(variant, 125, 140, f"strip {'under' if under else 'over'}", under=under)
    elif class_id == "11":
        draw.side(variant, 198, 210, "half")
    elif class_id == "12":
        draw.diagonal(variant)
    else:
        raise InvalidValueError(
            f"unknown class id {class_id!r}; expected one of {', '.join(CLASS_IDS)}"
        )


def draw_fold_steps(
    class_id: str, variant: str | None, layout: NapkinLayout, rng: np.random.Generator
) -> tuple[list[FoldStep], dict[str, Any]]:
    """The folds of one state of a class and variant, drawn from ``rng``, with the drawn
    parameters (``params["folds"]``: the fold words, in the order of the steps); what
    :func:`sample_state` makes a state of, and what the planner's closed-loop check folds
    again step by step.

    Returns
    -------
    list of FoldStep
    dict
    """
    draw = _FoldDraw(layout, rng)
    _draw_class_folds(draw, class_id, variant)
    steps, words, params = draw.steps, draw.words, draw.params
    order = list(range(len(steps)))
    if class_id in ("06", "07", "08"):
        rng.shuffle(order)  # the order of non-overlapping folds does not matter
        steps = [steps[i] for i in order]
        words = [words[i] for i in order]
    params["folds"] = words
    # each fold's true crease (two material points, mm): the truth of its sizes
    # (dgli_vision.core.fold_measure)
    params["creases_mm"] = {
        w: [[round(float(v), 4) for v in s.p0], [round(float(v), 4) for v in s.p1]]
        for w, s in zip(words, steps)
    }
    return steps, params


def _wrinkle(xy: NDArray, amplitude_m: float, rng: np.random.Generator) -> NDArray:
    """A smooth height field in [0, amplitude] over world xy (k, 2), 3 random waves."""
    field_ = np.zeros(len(xy))
    for _ in range(3):
        wavelength = rng.uniform(0.10, 0.25)
        theta = rng.uniform(0, 2 * np.pi)
        k = 2 * np.pi / wavelength * np.array([np.cos(theta), np.sin(theta)])
        field_ += rng.uniform(0.3, 1.0) * np.cos(xy @ k + rng.uniform(0, 2 * np.pi))
    lo, hi = field_.min(), field_.max()
    return amplitude_m * (field_ - lo) / max(hi - lo, 1e-12)


def boundary_uv(layout: NapkinLayout, *, step_mm: float = 40.0) -> NDArray[np.float64]:
    """Material points (m, 2) along the boundary A -> B -> C -> D -> (A), about
    ``step_mm`` apart, starting at A; each corner is included."""
    pts = []
    c = layout.corner_uv
    for k in range(4):
        a, b = c[k], c[(k + 1) % 4]
        n = max(1, round(float(np.linalg.norm(b - a)) / step_mm))
        t = np.arange(n)[:, None] / n
        pts.append(a + t * (b - a))
    return np.concatenate(pts)


def disc_samples(layout: NapkinLayout) -> NDArray[np.float64]:
    """13 material offsets (mm) on a sticker disc: the centre and two rings of six."""
    r = layout.disc_diameter_mm / 2
    ang = np.linspace(0, 2 * np.pi, 6, endpoint=False)
    rings = [np.stack([f * r * np.cos(ang), f * r * np.sin(ang)], 1) for f in (0.5, 0.9)]
    return np.concatenate([np.zeros((1, 2)), *rings])


def sticker_visibility(
    mesh: ClothMesh, layout: NapkinLayout, *, thickness_m: float = 1e-3
) -> NDArray[np.float64]:
    """Fraction of each sticker's disc that a camera straight above sees, shape (16,).

    A point of the disc is covered when some cloth of another layer (more than three
    grid cells away in material coordinates) lies above it, within one grid cell in
    the table plane.
    """
    offsets = disc_samples(layout)  # (13, 2)
    uv = (layout.sticker_uv[:, None, :] + offsets[None]).reshape(-1, 2)
    pts = mesh.interpolate(uv)  # (16 * 13, 3)
    tree = cKDTree(mesh.xyz[:, :2])
    radius = 1.0 * max(mesh.spacing_mm) * 1e-3
    far_mm = 3.0 * max(mesh.spacing_mm)
    # every (disc point, vertex near it) pair at once: the vertices, and whose they are
    near = tree.query_ball_point(pts[:, :2], radius)
    counts = np.fromiter(map(len, near), dtype=np.intp, count=len(near))
    vertex = np.fromiter(itertools.chain.from_iterable(near), dtype=np.intp, count=counts.sum())
    point = np.repeat(np.arange(len(pts)), counts)
    above = mesh.xyz[vertex, 2] > pts[point, 2] + 0.5 * thickness_m
    other = np.linalg.norm(mesh.uv[vertex] - uv[point], axis=1) > far_mm
    covered = np.zeros(len(pts), dtype=bool)
    covered[point[above & other]] = True
    return 1.0 - covered.reshape(len(layout.sticker_uv), -1).mean(axis=1)


def make_state(
    class_id: str,
    variant: str | None,
    steps: list[FoldStep],
    *,
    layout: NapkinLayout | None = None,
    angles: list[float] | None = None,
    wrinkle_mm: float = 0.0,
    yaw: float = 0.0,
    offset_m: tuple[float, float] = (0.0, 0.0),
    rng: np.random.Generator | int | None = None,
    spacing_mm: float = 5.0,
    params: dict[str, Any] | None = None,
) -> ClothState:
    """Build a state from explicit folds (the deterministic core of :func:`sample_state`).

    Parameters
    ----------
    class_id, variant : str, str or None
        The labels to attach.
    steps : list of FoldStep
        Folds applied in order (what is folded later lies on top).
    layout : NapkinLayout, optional
        Defaults to the packaged layout.
    angles : list of float, optional
        Fold angle of each step in radians (default pi: laid flat).
    wrinkle_mm : float
        Wrinkle amplitude in mm (0: none).
    yaw : float
        Rotation about the vertical, radians, about the napkin centre.
    offset_m : tuple of float
        Where the napkin centre goes on the table, metres.
    rng : Generator or int, optional
        Draws the wrinkle pattern.
    spacing_mm : float
        Mesh spacing.
    params : dict, optional
        Recorded in the state.
    """
    layout = layout or default_layout()
    rng = normalize_rng(rng)
    thickness = layout.thickness_mm * 1e-3
    mesh = flat_mesh(layout, spacing_mm=spacing_mm)
    for step, angle in zip(steps, angles or [np.pi] * len(steps)):
        mesh = step.apply(mesh, angle=angle, thickness_m=thickness)
    xyz = mesh.xyz.copy()
    if wrinkle_mm > 0:
        xyz[:, 2] += _wrinkle(xyz[:, :2], wrinkle_mm * 1e-3, rng)
    centre = np.array([layout.width_mm, layout.height_mm]) * 0.5e-3
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.array([[c, -s], [s, c]])
    xyz[:, :2] = (xyz[:, :2] - centre) @ rot.T + np.asarray(offset_m)
    mesh = mesh.with_xyz(xyz)
    info = dict(params or {})
    info.update(
        yaw_rad=float(yaw), offset_m=[float(v) for v in offset_m], wrinkle_mm=float(wrinkle_mm)
    )
    return ClothState(
        class_id=class_id,
        variant=variant,
        mesh=mesh,
        sticker_points=mesh.interpolate(layout.sticker_uv),
        visible_fraction=sticker_visibility(mesh, layout, thickness_m=thickness),
        corner_points=mesh.interpolate(layout.corner_uv),
        boundary=mesh.interpolate(boundary_uv(layout)),
        params=info,
    )


def _made_last(
    steps: list[FoldStep], params: dict[str, Any], last_fold: str, what: str
) -> list[FoldStep]:
    """The steps with fold ``last_fold`` (a word of ``params["folds"]``, reordered in place)
    made last."""
    if last_fold not in params["folds"]:
        raise InvalidValueError(f"{what} has no fold {last_fold!r}")
    k = params["folds"].index(last_fold)
    params["folds"] = params["folds"][:k] + params["folds"][k + 1 :] + [last_fold]
    return steps[:k] + steps[k + 1 :] + [steps[k]]


def _fold_in_progress(
    steps: list[FoldStep],
    params: dict[str, Any],
    last_fold_deg: float,
    class_id: str,
    variant: str | None,
) -> tuple[list[float], tuple[str, str | None]]:
    """The fold angles (radians) with the last fold turned ``last_fold_deg``, and the
    class and variant of that state by the 90-degree rule; notes the stage in ``params``."""
    if not steps:
        raise InvalidValueError(f"class {class_id} has no fold to leave in progress")
    if not 0 < last_fold_deg < 180:
        raise InvalidValueError(f"last_fold_deg must be in (0, 180), got {last_fold_deg}")
    angles = [np.pi] * (len(steps) - 1) + [float(np.radians(last_fold_deg))]
    moving = params["folds"][-1]
    params["stage"] = f"{'settling' if last_fold_deg > 90 else 'rising'} {moving}"
    params["last_fold_deg"] = float(last_fold_deg)
    if last_fold_deg <= 90:
        class_id, variant = unfold((class_id, variant), moving)
    return angles, (class_id, variant)


def sample_state(
    class_id: str,
    variant: str | None = None,
    rng: np.random.Generator | int | None = None,
    *,
    layout: NapkinLayout | None = None,
    wrinkles: bool = True,
    placement: bool = True,
    spacing_mm: float = 5.0,
    last_fold_deg: float | None = None,
    last_fold: str | None = None,
) -> ClothState:
    """Draw one state of a class (SPEC section 3's parameter ranges).

    Parameters
    ----------
    class_id : str
        ``"01"`` ... ``"12"``.
    variant : str, optional
        One of ``VARIANTS[class_id]``; drawn at random when omitted.
    rng : Generator or int, optional
        The only source of randomness.
    layout : NapkinLayout, optional
        Defaults to the packaged layout.
    wrinkles : bool, keyword-only
        Add smooth wrinkles up to 8 mm high.
    placement : bool, keyword-only
        Random rotation about the vertical and position (centre within 50 mm of the
        origin); otherwise the napkin is centred at the origin, unrotated.
    spacing_mm : float, keyword-only
        Mesh spacing.
    last_fold_deg : float, keyword-only, optional
        A fold in progress: the state's last fold turned only this far from flat
        (degrees, in (0, 180)). By SPEC's rule the state keeps its class beyond 90
        degrees, and below it is the state before that fold
        (:func:`dgli_vision.core.fold_graph.unfold`); ``params["stage"]`` says which fold is
        in progress (``"settling B over"``, ``"rising B over"``).
    last_fold : str, keyword-only, optional
        Which of the state's folds is made last (a word of
        :func:`dgli_vision.core.fold_graph.folds_of`); default as drawn.

    Returns
    -------
    ClothState
    """
    if class_id not in CLASS_NAMES:
        raise InvalidValueError(
            f"unknown class id {class_id!r}; expected one of {', '.join(CLASS_IDS)}"
        )
    rng = normalize_rng(rng)
    options = VARIANTS[class_id]
    if variant is None:
        variant = options[int(rng.integers(len(options)))]
    elif variant not in options:
        raise InvalidValueError(f"class {class_id} has variants {options}, got {variant!r}")
    layout = layout or default_layout()
    steps, params = draw_fold_steps(class_id, variant, layout, rng)
    if last_fold is not None:
        steps = _made_last(steps, params, last_fold, f"{class_id}/{variant}")
    angles = None
    if last_fold_deg is not None:
        angles, (class_id, variant) = _fold_in_progress(
            steps, params, last_fold_deg, class_id, variant
        )
    return make_state(
        class_id,
        variant,
        steps,
        layout=layout,
        angles=angles,
        wrinkle_mm=float(rng.uniform(0, 8)) if wrinkles else 0.0,
        yaw=float(rng.uniform(0, 2 * np.pi)) if placement else 0.0,
        offset_m=tuple(rng.uniform(-0.05, 0.05, size=2)) if placement else (0.0, 0.0),
        rng=rng,
        spacing_mm=spacing_mm,
        params=params,
    )
