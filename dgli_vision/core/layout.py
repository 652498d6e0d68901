"""The napkin layout of SPEC section 2, loaded from the package's ``data/napkin.json``.

Material coordinates ``(u, v)`` are in mm on the flat napkin, front face up: corner A at
(0, 0), B at (W, 0), C at (W, H), D at (0, H), boundary walked counter-clockwise
A -> B -> C -> D. The data file is the only place where the layout's numbers live; this
module derives the segments and stickers from them.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .dgli import cloth_coordinates
from .errors import InvalidValueError

__all__ = [
    "CORNER_STICKERS",
    "NapkinLayout",
    "default_layout",
    "layout_from_dict",
    "layout_of_size",
    "load_layout",
    "parse_size",
    "sticker_pairs",
    "sticker_spreads_mm",
]

#: Ids of the four stickers around each corner (A, B, C, D): the two at the end of one
#: segment and the two at the start of the next, in SPEC's sticker order (the same for
#: every napkin size).
CORNER_STICKERS = ((14, 15, 0, 1), (2, 3, 4, 5), (6, 7, 8, 9), (10, 11, 12, 13))


def _readonly(a: NDArray) -> NDArray:
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class NapkinLayout:
    """Where the eight segments and sixteen stickers sit on the napkin.

    Attributes
    ----------
    width_mm, height_mm : float
        Napkin size W x H in mm.
    thickness_mm : float
        Cloth thickness, used only to stack layers.
    corner_names : tuple of str
        ``("A", "B", "C", "D")``.
    corner_uv : ndarray, shape (4, 2)
        Corner positions in material coordinates, mm.
    segment_edges, segment_corners : tuple of str, length 8
        Edge (``"AB"``...) and nearby corner of each segment.
    segments_uv : ndarray, shape (8, 2, 2)
        Oriented segments (start, end) along the counter-clockwise walk, mm.
    sticker_uv : ndarray, shape (16, 2)
        Sticker centres, mm: sticker ``2i`` is segment i's start, ``2i + 1`` its end.
    sticker_disc, sticker_dot : tuple of str, length 16
        Colour names of each sticker's disc (its corner) and centre dot (its role).
    colours_srgb : dict of str to tuple of int
        Nominal printed sRGB colour of each colour name.
    disc_diameter_mm, dot_diameter_mm : float
        Sticker disc and dot diameters, mm.
    nominal_mm : tuple of float
        The layout file's napkin size (W, H), mm; other sizes keep the stickers' distances
        from the corners and scale the fold sizes (:attr:`fold_scale`).
    """

    width_mm: float
    height_mm: float
    thickness_mm: float
    corner_names: tuple[str, ...]
    corner_uv: NDArray[np.float64]
    segment_edges: tuple[str, ...]
    segment_corners: tuple[str, ...]
    segments_uv: NDArray[np.float64]
    sticker_uv: NDArray[np.float64]
    sticker_disc: tuple[str, ...]
    sticker_dot: tuple[str, ...]
    colours_srgb: dict[str, tuple[int, int, int]]
    disc_diameter_mm: float
    dot_diameter_mm: float
    nominal_mm: tuple[float, float] = (400.0, 400.0)

    @property
    def fold_scale(self) -> tuple[float, float]:
        """How much longer than on the nominal napkin a length across the napkin is,
        along u (width) and along v (height): fold sizes scale with the cloth."""
        return self.width_mm / self.nominal_mm[0], self.height_mm / self.nominal_mm[1]

    @property
    def is_nominal(self) -> bool:
        """True for the napkin size of the layout file."""
        return (self.width_mm, self.height_mm) == self.nominal_mm

    @property
    def n_segments(self) -> int:
        """Number of segments (8)."""
        return len(self.segments_uv)

    @property
    def n_stickers(self) -> int:
        """Number of stickers (16)."""
        return len(self.sticker_uv)

    @property
    def sticker_corners(self) -> NDArray[np.intp]:
        """The corner (index into ``corner_names``) each sticker belongs to, shape (16,):
        that of its segment."""
        return np.array(
            [self.corner_names.index(self.segment_corners[k // 2]) for k in range(self.n_stickers)]
        )

    def sticker_id(self, disc: str, dot: str) -> int | None:
        """Sticker id with this (disc, dot) colour pair, or None if there is none."""
        for k, pair in enumerate(zip(self.sticker_disc, self.sticker_dot)):
            if pair == (disc, dot):
                return k
        return None

    def flat_segments_m(self) -> NDArray[np.float64]:
        """Segments of the flat napkin in world coordinates: shape (8, 2, 3), metres, z = 0."""
        seg = np.zeros((self.n_segments, 2, 3))
        seg[..., :2] = self.segments_uv * 1e-3
        return seg

    def flat_coordinates(self) -> NDArray[np.float64]:
        """The 28 dGLI cloth coordinates of the flat, unfolded napkin (up = +z)."""
        return cloth_coordinates(self.flat_segments_m())


def layout_from_dict(
    data: dict[str, Any], *, width_mm: float | None = None, height_mm: float | None = None
) -> NapkinLayout:
    """Build a layout from the parsed layout file (see ``data/napkin.json``).

    Parameters
    ----------
    data : dict
        The layout file's content.
    width_mm, height_mm : float, optional, keyword-only
        Override the napkin size (a W x H napkin); the segments keep their distances to
        the corners.

    Returns
    -------
    NapkinLayout
    """
    w = float(width_mm if width_mm is not None else data["width_mm"])
    h = float(height_mm if height_mm is not None else data["height_mm"])
    near = float(data["segment_near_mm"])
    far = float(data["segment_far_mm"])
    inset = float(data["segment_inset_mm"])
    if min(w, h) < 2 * far + 2 * inset:
        raise InvalidValueError(
            f"a {w:g} x {h:g} mm napkin is too small: its stickers sit {far:g} mm from the "
            f"corners and {inset:g} mm in, so each side needs at least {2 * far + 2 * inset:g} mm"
        )
    names = tuple(data["corners"])
    corner_uv = np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]])
    pos = dict(zip(names, corner_uv))
    segments, edges, corners, disc, dot = [], [], [], [], []
    for k, seg in enumerate(sorted(data["segments"], key=lambda s: s["index"])):
        if seg["index"] != k:
            raise InvalidValueError(f"segment indices must be 0..7 in order, got {seg['index']}")
        x, y, corner = seg["edge"][0], seg["edge"][1], seg["corner"]
        e = (pos[y] - pos[x]) / np.linalg.norm(pos[y] - pos[x])
        inward = np.array([-e[1], e[0]])  # interior is on the left of a ccw walk
        if corner == x:  # the edge leaves the corner: start near, end far
            ends = (pos[x] + near * e, pos[x] + far * e)
            roles = ("leaving_near", "leaving_far")
        elif corner == y:  # the edge arrives at the corner: start far, end near
            ends = (pos[y] - far * e, pos[y] - near * e)
            roles = ("arriving_far", "arriving_near")
        else:
            raise InvalidValueError(f"segment {k}: corner {corner} is not on edge {seg['edge']}")
        segments.append([ends[0] + inset * inward, ends[1] + inset * inward])
        edges.append(seg["edge"])
        corners.append(corner)
        for role in roles:
            disc.append(data["corner_colour"][corner])
            dot.append(data["role_colour"][role])
    segments_uv = np.array(segments)
    return NapkinLayout(
        width_mm=w,
        height_mm=h,
        thickness_mm=float(data["thickness_mm"]),
        corner_names=names,
        corner_uv=_readonly(corner_uv),
        segment_edges=tuple(edges),
        segment_corners=tuple(corners),
        segments_uv=_readonly(segments_uv),
        sticker_uv=_readonly(segments_uv.reshape(-1, 2).copy()),
        sticker_disc=tuple(disc),
        sticker_dot=tuple(dot),
        colours_srgb={k: tuple(int(c) for c in v) for k, v in data["colours_srgb"].items()},
        disc_diameter_mm=float(data["sticker_disc_diameter_mm"]),
        dot_diameter_mm=float(data["sticker_dot_diameter_mm"]),
        nominal_mm=(float(data["width_mm"]), float(data["height_mm"])),
    )


@lru_cache(maxsize=1)
def _packaged() -> dict[str, Any]:
    text = resources.files("dgli_vision").joinpath("core/data/napkin.json").read_text("utf-8")
    return json.loads(text)


def load_layout(*, width_mm: float | None = None, height_mm: float | None = None) -> NapkinLayout:
    """The packaged layout, optionally for a W x H napkin (see :func:`layout_from_dict`)."""
    return layout_from_dict(_packaged(), width_mm=width_mm, height_mm=height_mm)


@lru_cache(maxsize=1)
def default_layout() -> NapkinLayout:
    """The packaged layout at its nominal size (cached)."""
    return load_layout()


@lru_cache(maxsize=8)
def layout_of_size(size_mm: tuple[float, float] | None) -> NapkinLayout:
    """The packaged layout for a W x H napkin (cached); None: the nominal size."""
    if size_mm is None:
        return default_layout()
    return load_layout(width_mm=float(size_mm[0]), height_mm=float(size_mm[1]))


def smallest_side_mm() -> float:
    """The shortest napkin side the stickers fit on, mm: they sit ``segment_far_mm`` from
    each corner and ``segment_inset_mm`` in from the edge (240 mm for the packaged
    layout)."""
    data = _packaged()
    return 2 * float(data["segment_far_mm"]) + 2 * float(data["segment_inset_mm"])


def parse_size(text: str, *, largest_mm: float | None = None) -> tuple[float, float]:
    """A napkin size from ``"W"`` (square) or ``"WxH"``, in mm.

    Parameters
    ----------
    text : str
    largest_mm : float, keyword-only, optional
        The longest side taken: each side must then lie between
        :func:`smallest_side_mm` and this, and a side out of that range is refused
        with the range.

    Raises
    ------
    InvalidValueError
        Not one or two positive numbers, too small for the stickers, or out of range.
    """
    bad = f"napkin size {text!r} is not W or WxH in mm (e.g. 400 or 500x700)"
    try:
        values = [float(s) for s in text.lower().replace("mm", "").split("x")]
    except ValueError:
        raise InvalidValueError(bad) from None
    if len(values) not in (1, 2) or not all(np.isfinite(v) and v > 0 for v in values):
        raise InvalidValueError(bad)
    w, h = values[0], values[-1]
    if largest_mm is not None:
        lo = smallest_side_mm()
        if not all(lo <= v <= largest_mm for v in (w, h)):
            raise InvalidValueError(
                f"napkin size {text!r} ({w:g} x {h:g} mm) is out of range: each side must "
                f"be {lo:g} to {largest_mm:g} mm (at least {lo:g} mm for the stickers to "
                f"fit, at most {largest_mm:g} mm: the stickers and the simulated cloth are "
                "made for napkins, not tablecloths)"
            )
    load_layout(width_mm=w, height_mm=h)  # checks the stickers fit
    return w, h


@lru_cache(maxsize=8)
def sticker_pairs(n_stickers: int = 16) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Sticker ids (i, j), i < j, of every pair, in row order (120 pairs for 16);
    read-only, made once."""
    i, j = np.triu_indices(n_stickers, k=1)
    i.flags.writeable = False
    j.flags.writeable = False
    return i, j


def sticker_spreads_mm(points_mm: NDArray[np.float64]) -> NDArray[np.float64]:
    """Distances between the stickers of every pair, shape (..., 120), from their
    positions (..., 16, 3) in mm (NaN where either is not located)."""
    i, j = sticker_pairs(points_mm.shape[-2])
    return np.linalg.norm(points_mm[..., i, :] - points_mm[..., j, :], axis=-1)
