"""Which way round the stickers of each corner run: which face each corner shows.

Every sticker is printed on both faces at the same place. Seen from the front face, the
stickers around a corner run one way round (as printed); seen from the back face (a
corner on a flap folded over, or the napkin lying back face up) or in a mirror, the
other way. This is napkin geometry, shared by the simulator (each reference's back-face
rate, from states seen from above) and by perception (the turn in an image:
:mod:`dgli_vision.perception.handedness`).

The camera's own handedness (:data:`MIRRORING`) says which of the two a clockwise turn
can be. A camera that does not mirror (the default: a camera not declared mirrored is
taken as not mirrored, as the RealSense, Azure Kinect and ZED drivers never mirror) leaves
one cause of a mirrored layout, the napkin lying back face up, and rules out the double
fault (back face up under a mirroring camera) that shows a front-up state's twin. A
camera declared mirrored is un-mirrored before its frames are read
(:func:`unmirrored`), and is then one that does not mirror. ``"unknown"`` keeps both
causes, and the caution of the double fault.
"""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache
from itertools import combinations
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from .camera import Intrinsics
from .errors import InvalidValueError
from .frame import RGBDFrame
from .layout import CORNER_STICKERS, NapkinLayout

__all__ = [
    "MIN_SHAPE",
    "MIRRORING",
    "Mirroring",
    "back_face_up",
    "camera_mirroring",
    "corner_turns",
    "unmirrored",
    "unmirrored_intrinsics",
]

#: The camera's handedness as a command or the API is told it (``--mirroring``,
#: ``mirroring=``): ``"no"`` the camera does not mirror its image, ``"yes"`` it mirrors
#: it left to right, ``"unknown"`` either.
Mirroring = Literal["no", "yes", "unknown"]
MIRRORING: tuple[str, ...] = ("no", "yes", "unknown")

#: Smallest twice-signed area of a corner's sticker triangle, as a share of the squared
#: longest side, that counts: below it the triangle is seen nearly edge on (a flap near
#: vertical) and its turn is left to noise.
MIN_SHAPE = 0.08


def _turns(points: NDArray[np.float64]) -> NDArray[np.float64]:
    """Twice the signed area of triangles (..., 3, 2) over their squared longest side
    (x right, y up: counter-clockwise positive); 0 for a degenerate triangle."""
    return _turns_of_edges(points[..., _EDGE_END, :] - points[..., _EDGE_START, :])


#: The edges b - a, c - a and c - b of a triangle (a, b, c): their ends and starts.
_EDGE_END = np.array([1, 2, 2])
_EDGE_START = np.array([0, 0, 1])


def _turns_of_edges(edges: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`_turns` of triangles given by their edges b - a, c - a, c - b (..., 3, 2)."""
    ab, ac = edges[..., 0, :], edges[..., 1, :]
    cross = ab[..., 0] * ac[..., 1] - ab[..., 1] * ac[..., 0]
    longest = np.square(edges).sum(axis=-1).max(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(longest > 0, cross / longest, 0.0)


@lru_cache(maxsize=32)
def _triangles(layout: NapkinLayout) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """Sticker ids of every triangle of three stickers around one corner, shape
    (4, 4, 3), and the printed turn of each, shape (4, 4); read-only, once per layout."""
    ids = np.array([list(combinations(c, 3)) for c in CORNER_STICKERS])
    printed = _turns(np.asarray(layout.sticker_uv, dtype=float)[ids])
    ids.flags.writeable = False
    printed.flags.writeable = False
    return ids, printed


@lru_cache(maxsize=32)
def _triangle_edges(
    layout: NapkinLayout,
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.bool_], NDArray[np.float64]]:
    """For :func:`corner_turns`, once per layout (read-only): the sticker ids at the ends
    and at the starts of the edges of every triangle, shape (4, 4, 3) each, whether its
    printed turn counts (not edge on), and its sign, shape (4, 4)."""
    ids, printed = _triangles(layout)
    out = (ids[..., _EDGE_END], ids[..., _EDGE_START], np.abs(printed) >= MIN_SHAPE,
           np.sign(printed))
    for a in out:
        a.flags.writeable = False
    return out


def corner_turns(points_xy: NDArray[np.float64], layout: NapkinLayout) -> NDArray[np.float64]:
    """Which way round each corner's stickers run, seen from the viewer's side.

    Parameters
    ----------
    points_xy : ndarray, shape (..., 16, 2)
        Sticker positions in a plane seen by the viewer with x right and y up (NaN where
        not located): pixels with y negated, or a state's x, y seen from above.
    layout : NapkinLayout
        The printed positions (front face towards the viewer).

    Returns
    -------
    ndarray, shape (..., 4)
        Per corner A-D: +1 when its stickers run as printed (front face towards the
        viewer), -1 the other way round (back face, or a mirror), 0 when fewer than three
        of its stickers are located, the triangles are seen edge on, or they disagree
        evenly.
    """
    ends, starts, printed_counts, printed_sign = _triangle_edges(layout)
    pts = np.asarray(points_xy, dtype=float)
    turn = _turns_of_edges(pts[..., ends, :] - pts[..., starts, :])  # (..., 4, 4)
    counts = np.isfinite(turn) & (np.abs(turn) >= MIN_SHAPE) & printed_counts
    votes = np.where(counts, np.sign(turn) * printed_sign, 0.0).sum(axis=-1)
    return np.sign(votes)


def back_face_up(turns: NDArray[np.float64]) -> NDArray[np.float64]:
    """Turns as the share of a corner's stickers showing the back face: 1 for -1, 0 for
    +1, NaN where not told (0)."""
    t = np.asarray(turns, dtype=float)
    return np.where(t == 0, np.nan, (t < 0).astype(float))


def camera_mirroring(mirroring: str | None, intrinsics: Intrinsics | None = None) -> str:
    """The camera's handedness to classify with: ``mirroring`` when given, else as the
    intrinsics declare it (``"mirrored"`` in the intrinsics file, written by ``dgli
    calibrate``), else ``"no"``.

    Parameters
    ----------
    mirroring : {"no", "yes", "unknown"} or None
    intrinsics : Intrinsics, optional

    Raises
    ------
    InvalidValueError
        ``mirroring`` is none of :data:`MIRRORING`.
    """
    if mirroring is None:
        declared = None if intrinsics is None else intrinsics.mirrored
        return "yes" if declared else "no"
    if mirroring not in MIRRORING:
        raise InvalidValueError(
            f"mirroring must be one of {', '.join(MIRRORING)}, got {mirroring!r}"
        )
    return mirroring


def unmirrored_intrinsics(intrinsics: Intrinsics) -> Intrinsics:
    """The intrinsics of an image flipped left to right: the principal point mirrored
    (``cx`` to ``width - 1 - cx``, pixel centres), the tangential ``p2`` negated (the
    lens model's only term odd in x), declared not mirrored."""
    d = tuple(intrinsics.distortion)
    if len(d) >= 4:
        d = (*d[:3], -d[3], *d[4:])
    return replace(
        intrinsics, cx=intrinsics.width - 1 - intrinsics.cx, distortion=d, mirrored=False
    )


def unmirrored(frame: RGBDFrame) -> RGBDFrame:
    """A mirroring camera's frame as a camera that does not mirror sees the scene:
    colour and depth flipped left to right together, the intrinsics with them
    (:func:`unmirrored_intrinsics`). Its points lift to the scene's own places in the
    camera frame (x right, y down, z forward), and pixels are those of the flipped image.
    """
    return replace(
        frame,
        color=np.ascontiguousarray(frame.color[:, ::-1]),
        depth_mm=np.ascontiguousarray(frame.depth_mm[:, ::-1]),
        intrinsics=unmirrored_intrinsics(frame.intrinsics),
    )
