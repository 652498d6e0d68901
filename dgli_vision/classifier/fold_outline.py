"""A fold's crease from the napkin's outline, where the stickers seen do not fix it.

A half fold or a diagonal fold hides the napkin beneath it: only the flap's stickers are
seen, and they fix the flap's map ``T`` (material mm -> table plane, a mirror image:
the flap shows its back) but not where the crease is (any crease, with the napkin that
stays placed to match, puts the flap's stickers in the same places). A flap folded
under hides its own stickers instead: those of the napkin that stays fix its map ``S``,
and again nothing fixes the crease.

The napkin's outline does. Folded cloth lies on one side of its crease: everything seen
of a flap folded over lies, mapped back by ``T``, on the flap's side of the crease (the
napkin beneath is the flap's mirror image), and everything seen of a napkin with a flap
folded under lies, mapped back by ``S``, on the side that stays. So the crease is the
outline's farthest reach, where the cloth ends and the table begins: a step in colour
(the napkin is white, the table much darker once compared with it).

It is looked for across the nominal crease: every few millimetres along its middle (away
from the corners, where the outline turns), a profile of the image's whiteness (the
least of its three channels, each over the cloth's own: the napkin is white, a table
darker or coloured, whatever the light's colour) is read on the flat napkin's line
across it (each point placed on the table by the map, and seen through the camera, lens
distortion included), from well inside the cloth to well out on the table, its stickers
left out. Its edge is the steepest step down (in log whiteness: a shadow or a lamp's
fall-off scales cloth and table alike, a soft shadow's own edge falls slowly, a wooden
table's grain by far less than the cloth's edge), placed to a fraction of a pixel where
the whiteness crosses the midpoint of the step's two sides. A straight line fitted to
the edges, the profiles that stick out left out (an object touching the cloth, cloth
peeking from beneath), is the
crease. Its uncertainty pools the line fit's (the edges' scatter about it) with the
map's (the stickers' scatter about the rigid map) and the edge's own (where the crease
lies under the edge seen).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..core.camera import Intrinsics
from ..core.fold_lines import NominalFold
from ..core.fold_measure import Crease
from ..core.layout import NapkinLayout

__all__ = [
    "OutlineParams",
    "OutlineView",
    "PartMap",
    "crease_from_edges",
    "edge_profiles",
    "fit_part_map",
    "outline_fit",
    "outline_geometry",
    "outline_view",
]


@dataclass(frozen=True)
class OutlineParams:
    """How the crease is fitted to the outline. Every field has a unit and a reason.

    Attributes
    ----------
    reach_mm : float
        How far on either side of the nominal crease each profile reaches, mm. Default
        80: a fold made 30-60 mm off its plan is still found, and the profile holds
        both cloth and table.
    step_mm : float
        Spacing of a profile's samples, mm. Default 0.5: under a pixel at every camera
        SPEC allows.
    every_mm : float
        Spacing of the profiles along the crease, mm. Default 5: 4-8 pixels apart, so
        each reads pixels of its own.
    end_margin_mm : float
        Length kept free at each end of the crease, mm. Default 25: the outline turns
        the corner there, and the cloth bends round it.
    edge_width_mm : float
        Width over which a step's fall is measured, mm. Default 3: two pixels at the
        farthest camera, so the cloth's edge (blurred over a pixel or two) falls within
        it, and a soft shadow's (tens of mm) does not.
    min_ratio : float
        Least ratio of the brightness before and after a step. Default 1.15: the napkin
        is white, the table much less bright (SPEC); sensor noise moves a pixel by a
        few per cent.
    min_cover : float
        Least share of the profiles whose edge must fit the line. Default 0.5: an arm
        or an object may hide part of the edge, not most of it.
    trim_mm : float
        Least distance from the line beyond which an edge is left out, mm. Default 3;
        more where the edges scatter more (3 of their robust sd).
    floor_sd_mm : float
        Floor of an edge's scatter about the line, mm. Default 0.7: half a pixel at the
        nearest camera.
    height_mm : float
        Height of the folded edge above the table, in cloth thicknesses. Default 1.5:
        the edge is the turn of the cloth between a layer on the table and one on it.
    edge_mm : float
        How far the outline's farthest reach lies beyond the crease, in cloth
        thicknesses. Default 0: cloth turns round its crease within about a thickness.
    edge_sd_mm : float
        Standard deviation of where the crease lies under the edge seen, mm, added to
        the line fit's. Default 1.5: a real cloth's turn stands out by one or two
        thicknesses; the simulator's cloth, a mesh of 5 mm rows, ends at the row
        nearest its crease, 0-3.5 mm short of it (docs/folds.md).
    """

    reach_mm: float = 80.0
    step_mm: float = 0.5
    every_mm: float = 5.0
    end_margin_mm: float = 25.0
    edge_width_mm: float = 3.0
    min_ratio: float = 1.15
    min_cover: float = 0.5
    trim_mm: float = 3.0
    floor_sd_mm: float = 0.7
    height_mm: float = 1.5
    edge_mm: float = 0.0
    edge_sd_mm: float = 1.5


@dataclass(frozen=True, eq=False)
class OutlineView:
    """What the outline fit reads of a frame.

    Attributes
    ----------
    color : ndarray of uint8, shape (H, W, 3)
        The colour image, RGB (its whiteness, the least of the three channels each
        over the cloth's own, is read).
    intrinsics : Intrinsics
    up : ndarray, shape (3,)
        The table's normal, towards the camera.
    offset_m : float
        The table plane ``up . x = offset_m`` (camera frame, metres).
    basis : ndarray, shape (2, 3)
        The table plane's axes (:func:`~dgli_vision.classifier.fold_geometry.plane_basis`
        of ``up``): a table point's coordinates are its components along them, in mm.
    """

    color: NDArray[np.uint8]
    intrinsics: Intrinsics
    up: NDArray[np.float64]
    offset_m: float
    basis: NDArray[np.float64]

    def to_pixels(self, p_mm: NDArray, height_mm: float = 0.0) -> NDArray[np.float64]:
        """Where table-plane points (k, 2, mm), ``height_mm`` above the table, are seen:
        pixels (k, 2); NaN behind the camera."""
        pts = (np.asarray(p_mm, dtype=float) * 1e-3) @ self.basis
        pts += self.up * (self.offset_m + height_mm * 1e-3)
        out = np.full((len(pts), 2), np.nan)
        front = pts[:, 2] > 1e-6
        if front.any():
            out[front] = self.intrinsics.project(pts[front])
        return out


def outline_view(frame: Any, obs: Any) -> OutlineView | None:
    """The :class:`OutlineView` of a frame (an
    :class:`~dgli_vision.sources.frames.RGBDFrame`) and its observation (a
    :class:`~dgli_vision.classifier.pipeline.ClothObservation`); None where no sticker
    gives the table's height."""
    from .fold_geometry import plane_basis

    if obs.points_m is None or obs.heights_mm is None:
        return None
    # the table plane: the heights were measured from it (up . x - offset, in mm)
    seen = np.asarray(obs.visible, dtype=bool) & np.isfinite(obs.heights_mm)
    if not seen.any():
        return None
    up = np.asarray(obs.up, dtype=float)
    offset = float(np.median(obs.points_m[seen] @ up - obs.heights_mm[seen] * 1e-3))
    return OutlineView(frame.color, frame.intrinsics, up, offset, plane_basis(up))


def _frame_of(fold: NominalFold) -> tuple[NDArray, NDArray, NDArray]:
    """The nominal crease's point, its direction and the normal pointing past the crease
    from the part seen (from the flap for a fold over, from the napkin that stays for a
    fold under)."""
    a0, b0 = np.asarray(fold.p0, dtype=float), np.asarray(fold.p1, dtype=float)
    t = (b0 - a0) / np.linalg.norm(b0 - a0)
    n = np.array([-t[1], t[0]])
    flap_side = (np.asarray(fold.flap, dtype=float) - a0) @ n > 0
    return a0, t, (-n if flap_side != fold.under else n)


def _sample(view: OutlineView, px: NDArray) -> NDArray[np.float32]:
    """The colour (RGB, bilinear) at pixels (..., 2), shape (..., 3); NaN outside the
    image (the crop of the image the pixels span is read, not all of it)."""
    import cv2

    h, w = view.color.shape[:2]
    flat = px.reshape(-1, 2)
    ok = np.isfinite(flat).all(axis=1)
    out = np.full((len(flat), 3), np.nan, dtype=np.float32)
    if not ok.any():
        return out.reshape(*px.shape[:-1], 3)
    x0 = int(max(math.floor(np.min(flat[ok, 0])) - 1, 0))
    x1 = int(min(math.ceil(np.max(flat[ok, 0])) + 2, w))
    y0 = int(max(math.floor(np.min(flat[ok, 1])) - 1, 0))
    y1 = int(min(math.ceil(np.max(flat[ok, 1])) + 2, h))
    inside = ok & (flat[:, 0] >= 0) & (flat[:, 1] >= 0) & (flat[:, 0] <= w - 1) & (
        flat[:, 1] <= h - 1)
    if x1 - x0 < 2 or y1 - y0 < 2 or not inside.any():
        return out.reshape(*px.shape[:-1], 3)
    crop = np.ascontiguousarray(view.color[y0:y1, x0:x1])
    # (OpenCV's maps are images of fewer than 32767 columns: rows of 1024 points)
    n = int(np.count_nonzero(inside))
    rows = -(-n // 1024)
    maps = np.zeros((2, rows * 1024), dtype=np.float32)
    maps[0, :n] = flat[inside, 0] - x0
    maps[1, :n] = flat[inside, 1] - y0
    got = cv2.remap(crop.astype(np.float32), maps[0].reshape(rows, 1024),
                    maps[1].reshape(rows, 1024), cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_REPLICATE)
    out[inside] = got.reshape(-1, 3)[:n]
    return out.reshape(*px.shape[:-1], 3)


def _whiteness(rgb: NDArray, cloth: NDArray[np.bool_]) -> NDArray[np.float64]:
    """The least of the three channels, each over the cloth's own (the median of the
    brighter half of the samples ``cloth``, shape (k, m)): the napkin is white, a
    table darker or coloured (a wooden one low in blue), whatever the light's colour;
    shape (k, m)."""
    inner = rgb[cloth]
    inner = inner[np.isfinite(inner).all(axis=1)]
    if len(inner) < 10:
        return np.min(rgb, axis=-1)  # (NaN where left out, without a warning)
    total = inner.sum(axis=1)
    bright = inner[total >= np.median(total)]
    white = np.maximum(np.median(bright, axis=0), 1.0)
    return np.min(rgb / white, axis=-1) * 255.0


def edge_profiles(
    view: OutlineView,
    part: PartMap,
    fold: NominalFold,
    layout: NapkinLayout,
    params: OutlineParams | None = None,
    *,
    stickers_uv: NDArray | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Where the cloth ends across the nominal crease of ``fold``, profile by profile
    (see the module's description). The samples on the part's stickers
    (``stickers_uv``, material mm (k, 2), a disc's radius and 3 mm round each) are left
    out: a sticker's edge is a step too.

    Returns
    -------
    along, past : ndarray, shape (k,)
        Each profile's place along the nominal crease and its edge's distance past it
        (mm on the flat napkin, positive away from the part seen); NaN past where no
        edge was found (too little contrast, no table beyond, out of the image).
    """
    p = params or OutlineParams()
    a0, t, n = _frame_of(fold)
    ends = Crease.through(a0, a0 + t).ends_in(layout)
    if ends is None:
        return np.zeros(0), np.zeros(0)
    s_ends = sorted(float((np.asarray(e) - a0) @ t) for e in ends)
    lo, hi = s_ends[0] + p.end_margin_mm, s_ends[1] - p.end_margin_mm
    if hi - lo < 4 * p.every_mm:
        return np.zeros(0), np.zeros(0)
    along = np.arange(lo, hi + 1e-9, p.every_mm)  # (k,)
    past = np.arange(-p.reach_mm, p.reach_mm + 1e-9, p.step_mm)  # (m,)
    m = a0 + along[:, None, None] * t + past[None, :, None] * n  # (k, m, 2) material
    table = _to_table(part, m.reshape(-1, 2))
    px = view.to_pixels(table, p.height_mm * layout.thickness_mm)
    rgb = _sample(view, px.reshape(len(along), len(past), 2))  # (k, m, 3)
    if stickers_uv is not None and len(stickers_uv):
        flat = m.reshape(-1, 2)
        near = np.zeros(len(flat), dtype=bool)
        r2 = (0.5 * layout.disc_diameter_mm + 3.0) ** 2
        for uv in np.asarray(stickers_uv, dtype=float):
            near |= np.sum((flat - uv) ** 2, axis=1) < r2
        rgb[near.reshape(len(along), len(past))] = np.nan
    # the cloth's colour from well inside it (beyond any crease made 30 mm off)
    cloth = np.broadcast_to(past[None, :] < -0.5 * p.reach_mm, rgb.shape[:2])
    return along, _edges(_whiteness(rgb, cloth), past, p)


def _edges(g: NDArray, past: NDArray, p: OutlineParams) -> NDArray[np.float64]:
    """Each profile's (rows of ``g``, sampled at ``past``, NaN where left out) steepest
    step down from cloth to table; NaN where none.

    The steps are read in log whiteness, so that a shadow or a lamp's fall-off, which
    scale cloth and table alike, leave a step's size as it is: the cloth's edge falls by
    the cloth's ratio to the table within a pixel or two, a soft shadow's edge over tens
    of millimetres, a wooden table's grain by a fraction of that ratio. A step counts
    where the whiteness falls over ``edge_width_mm`` by at least ``min_ratio``; it is
    placed to a fraction of a sample where the whiteness crosses the midpoint of its two
    sides' levels (2-4 half widths in and out)."""
    k, m = g.shape
    out = np.full(k, np.nan)
    step = float(past[1] - past[0])
    w = max(int(round(0.5 * p.edge_width_mm / step)), 1)
    if m < 8 * w + 2:
        return out
    lg = np.log(g + 4.0)  # (k, m), NaN where left out
    fall = np.full((k, m), np.inf)
    with np.errstate(invalid="ignore"):
        fall[:, w : m - w] = lg[:, 2 * w :] - lg[:, : m - 2 * w]  # over 2 w samples
    fall[~np.isfinite(fall)] = np.inf
    fall[:, : 4 * w] = np.inf
    fall[:, m - 4 * w :] = np.inf
    i = np.argmin(fall, axis=1)  # the steepest fall of each profile
    rows = np.flatnonzero(fall[np.arange(k), i] <= -math.log(p.min_ratio))
    if not len(rows):
        return out
    i = i[rows]
    # the two sides' levels: the mean log whiteness 2-4 half widths in and out
    offs = np.arange(2 * w, 4 * w + 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # (a side all left out: NaN)
        inner = np.nanmean(lg[rows[:, None], i[:, None] - offs[None]], axis=1)
        outer = np.nanmean(lg[rows[:, None], i[:, None] + offs[None]], axis=1)
    mid = 0.5 * (inner + outer)
    # the crossing of the midpoint within a half width of the step: the last sample
    # above it
    win = np.arange(-w, w)  # (2w,)
    a = lg[rows[:, None], i[:, None] + win[None]] - mid[:, None]  # (r, 2w)
    b = lg[rows[:, None], i[:, None] + win[None] + 1] - mid[:, None]
    cross = (a >= 0) & (b < 0)
    ok = cross.any(axis=1) & np.isfinite(mid)
    j = 2 * w - 1 - np.argmax(cross[:, ::-1], axis=1)
    r = np.arange(len(rows))
    aa, bb = a[r, j], b[r, j]
    frac = np.where(aa - bb > 0, aa / np.where(aa - bb > 0, aa - bb, 1.0), 0.0)
    at = past[i + win[j]] + frac * step
    out[rows[ok]] = at[ok]
    return out


@dataclass(frozen=True)
class PartMap:
    """A rigid map of one part of the napkin, material mm -> table plane mm:
    ``p = R(theta) F m + tau`` with ``F`` the mirror ``(u, v) -> (u, -v)`` when
    ``mirror`` (a flap folded over shows its back), else the identity.

    Attributes
    ----------
    theta : float
    tau : ndarray, shape (2,)
    mirror : bool
    cov : ndarray, shape (3, 3)
        Covariance of (theta, tau_u, tau_v).
    rms_mm : float
        RMS distance of the stickers from where the map puts them.
    stickers : int
    """

    theta: float
    tau: NDArray[np.float64]
    mirror: bool
    cov: NDArray[np.float64]
    rms_mm: float
    stickers: int

    def perturbed(self, k: int, h: float) -> PartMap:
        """The map with its ``k``-th parameter (theta, tau_u, tau_v) moved by ``h``."""
        x = np.array([self.theta, *self.tau])
        x[k] += h
        return PartMap(float(x[0]), x[1:], self.mirror, self.cov, self.rms_mm, self.stickers)

    def to_material(self, p: NDArray) -> NDArray[np.float64]:
        """Table-plane points (k, 2) mapped back to the flat napkin."""
        c, s = math.cos(self.theta), math.sin(self.theta)
        q = (np.asarray(p, dtype=float) - self.tau) @ np.array([[c, -s], [s, c]])
        if self.mirror:
            q[:, 1] = -q[:, 1]
        return q


def fit_part_map(
    m: NDArray, p: NDArray, *, mirror: bool, sticker_sd_mm: float, prior_dof: float
) -> PartMap | None:
    """The rigid map (:class:`PartMap`) taking material points ``m`` (k, 2) nearest to
    ``p`` (k, 2), k >= 2, with its covariance: the residuals pooled with
    ``sticker_sd_mm`` weighted as ``prior_dof`` degrees of freedom."""
    from .fold_geometry import rigid_fit_2d

    if len(m) < 2:
        return None
    mf = np.asarray(m, dtype=float).copy()
    if mirror:
        mf[:, 1] = -mf[:, 1]
    th, tau = rigid_fit_2d(mf, p)
    c, s = math.cos(th), math.sin(th)
    rot = np.array([[c, -s], [s, c]])
    res = mf @ rot.T + tau - p
    d2 = float(np.sum(res * res))
    jac = np.zeros((len(m), 2, 3))
    jac[:, :, 0] = mf @ np.array([[-s, -c], [c, -s]]).T
    jac[:, 0, 1] = 1.0
    jac[:, 1, 2] = 1.0
    jm = jac.reshape(-1, 3)
    dof = max(2 * len(m) - 3, 0)
    var = (d2 + prior_dof * sticker_sd_mm**2) / (dof + prior_dof)
    try:
        cov = var * np.linalg.inv(jm.T @ jm)
    except np.linalg.LinAlgError:
        return None
    return PartMap(th, tau, mirror, cov, math.sqrt(d2 / len(m)), len(m))


def _line_through(s: NDArray, d: NDArray) -> tuple[float, float, NDArray]:
    """Least squares ``d = a + b s``: (a, b) and the residuals."""
    a_mat = np.column_stack([np.ones_like(s), s])
    (a, b), *_ = np.linalg.lstsq(a_mat, d, rcond=None)
    return float(a), float(b), d - (a + b * s)


def _robust_line(
    s: NDArray, d: NDArray, p: OutlineParams
) -> tuple[float, float, NDArray[np.bool_], float] | None:
    """The line ``d = a + b s`` through the stretches, those far off it left out:
    (a, b, the stretches kept, their scatter's sd in mm)."""
    keep = np.ones(len(s), dtype=bool)
    for _ in range(4):
        if np.count_nonzero(keep) < 4:
            return None
        a, b, _ = _line_through(s[keep], d[keep])
        r = d - (a + b * s)
        mad = 1.4826 * float(np.median(np.abs(r[keep])))
        new = np.abs(r) <= max(p.trim_mm, 3.0 * mad)
        if np.array_equal(new, keep):
            break
        keep = new
    if np.count_nonzero(keep) < 4:
        return None
    a, b, r = _line_through(s[keep], d[keep])
    sd = math.sqrt(max(float(np.sum(r * r)) / max(len(r) - 2, 1), p.floor_sd_mm**2))
    return a, b, keep, sd


def crease_from_edges(
    along: NDArray,
    past: NDArray,
    part: PartMap,
    fold: NominalFold,
    layout: NapkinLayout,
    params: OutlineParams | None = None,
) -> tuple[Crease, NDArray[np.float64], int, float] | str:
    """The crease of ``fold`` from the edges found across its nominal crease
    (:func:`edge_profiles`) and the map ``part`` of what is seen of the napkin.

    Returns
    -------
    (Crease, cov, edges, rms_mm) or str
        The crease on the flat napkin, the covariance (2, 2) of its normal's angle
        (radians) and offset (mm) as :meth:`Crease.from_normal` takes them, the number
        of edges fitted and their RMS distance from it (mm); or why the outline does
        not fix it.
    """
    p = params or OutlineParams()
    found = np.isfinite(past)
    if len(along) == 0:
        return "nor does the outline: the crease is too short to fit"
    s, d = np.asarray(along, dtype=float)[found], np.asarray(past, dtype=float)[found]
    fit = _robust_line(s, d, p) if len(s) >= 4 else None
    if fit is None or np.count_nonzero(fit[2]) < p.min_cover * len(along):
        return "nor does the napkin's outline (hidden, or not straight along the crease)"
    a, b, keep, sd = fit
    a0, t, n = _frame_of(fold)
    edge = p.edge_mm * layout.thickness_mm
    crease, line_cov = _crease_of(a0, t, n, a - edge, b, s[keep], sd)
    # the map's share: the same edges (as table points) mapped back by a map moved a
    # little, each parameter in turn
    table = _to_table(part, a0 + np.outer(s[keep], t) + np.outer(d[keep], n))
    base = _normal_form(crease)
    jac = np.zeros((2, 3))
    for k, h in enumerate((1e-5, 1e-3, 1e-3)):
        rel = part.perturbed(k, h).to_material(table) - a0
        aa, bb, _ = _line_through(rel @ t, rel @ n)
        other, _ = _crease_of(a0, t, n, aa - edge, bb, s[keep], sd)
        jac[:, k] = (_normal_form(other, base[0]) - base) / h
    cov = line_cov + jac @ part.cov @ jac.T
    cov[1, 1] += p.edge_sd_mm**2
    rms = float(np.sqrt(np.mean((d[keep] - (a + b * s[keep])) ** 2)))
    return crease, cov, int(np.count_nonzero(keep)), rms


def _to_table(part: PartMap, m: NDArray) -> NDArray[np.float64]:
    """Material points (k, 2) placed by the map ``part``."""
    q = np.asarray(m, dtype=float).copy()
    if part.mirror:
        q[:, 1] = -q[:, 1]
    c, s = math.cos(part.theta), math.sin(part.theta)
    return q @ np.array([[c, -s], [s, c]]).T + part.tau


def _normal_form(crease: Crease, near: float | None = None) -> NDArray[np.float64]:
    """(angle, offset) of ``n . x = offset`` with ``n`` the crease's normal (-t_v, t_u);
    the angle taken within pi of ``near``."""
    (px, py), (tx, ty) = crease.point, crease.direction
    alpha = math.atan2(tx, -ty)
    if near is not None:
        alpha += 2 * math.pi * round((near - alpha) / (2 * math.pi))
    return np.array([alpha, -ty * px + tx * py])


def _crease_of(
    origin: NDArray, t: NDArray, n: NDArray, a: float, b: float, s: NDArray, sd: float
) -> tuple[Crease, NDArray[np.float64]]:
    """The crease ``d = a + b s`` in the frame (origin, t, n) and the covariance of its
    normal form from the stretches' scatter ``sd`` at their places ``s`` (each a
    stretch of its own: the scatter is not a pixel's)."""
    p0 = origin + a * n
    direction = t + b * n
    crease = Crease.through(p0, p0 + direction)
    # the covariance of (a, b) of the least squares line, then to (angle, offset)
    a_mat = np.column_stack([np.ones_like(s), s])
    cov_ab = sd**2 * np.linalg.inv(a_mat.T @ a_mat)
    base = _normal_form(crease)
    jac = np.zeros((2, 2))
    for k, h in enumerate((1e-3, 1e-6)):
        aa, bb = (a + h, b) if k == 0 else (a, b + h)
        q0 = origin + aa * n
        other = Crease.through(q0, q0 + t + bb * n)
        jac[:, k] = (_normal_form(other, base[0]) - base) / h
    return crease, jac @ cov_ab @ jac.T


def outline_fit(frame: Any, obs: Any) -> Callable[..., Any]:
    """The outline fit of one frame, as :func:`~.fold_geometry.fit_folds` calls it:
    ``fit(obs, fold, index, sticker_part, lying, layout)`` gives
    :func:`outline_geometry`'s answer, or None where the frame cannot be read
    (:func:`outline_view`). The view is made only when a fold asks, and once."""
    view = lru_cache(maxsize=1)(lambda: outline_view(frame, obs))

    def fit(
        obs: Any, fold: NominalFold, index: int, sticker_part: NDArray,
        lying: NDArray[np.bool_], layout: NapkinLayout,
    ) -> Any:
        seen = view()
        if seen is None:
            return None
        return outline_geometry(obs, fold, index, sticker_part, lying, layout, seen)

    return fit


def outline_geometry(
    obs: Any,
    fold: NominalFold,
    index: int,
    sticker_part: NDArray,
    lying: NDArray[np.bool_],
    layout: NapkinLayout,
    view: OutlineView,
    params: OutlineParams | None = None,
) -> Any:
    """The :class:`~dgli_vision.classifier.fold_geometry.FoldGeometry` of fold
    ``index`` (``fold``) from the outline (``source`` ``"outline"``), or why not (str).

    The part seen is placed by its stickers lying on the table (``lying``, shape (16,)):
    the flap's (``sticker_part == index``) for a fold over, mirrored; those of the
    napkin that stays (``sticker_part == -1``) for a fold under.
    """
    from .fold_geometry import (
        MAX_SD_MM,
        OUTLIER_MM,
        PRIOR_DOF,
        STICKER_SD_MM,
        _edge_sd,
        geometry_from_crease,
    )

    p = params or OutlineParams()
    mine = lying & (sticker_part == (-1 if fold.under else index))
    if np.count_nonzero(mine) < 2:
        return ("nor does the outline: fewer than two of the stickers that place it lie on "
                "the table")
    p2 = (obs.points_m[mine] @ view.basis.T) * 1e3
    uv = np.asarray(layout.sticker_uv, dtype=float)[mine]
    part = _part_map(uv, p2, not fold.under, STICKER_SD_MM, PRIOR_DOF, OUTLIER_MM)
    if part is None:
        return "nor does the outline: the stickers that place it do not fit one rigid map"
    own = sticker_part == (-1 if fold.under else index)
    along, past = edge_profiles(view, part, fold, layout, p,
                                stickers_uv=np.asarray(layout.sticker_uv, dtype=float)[own])
    got = crease_from_edges(along, past, part, fold, layout, p)
    if isinstance(got, str):
        return got
    crease, cov, _, rms = got
    if not np.all(np.isfinite(cov)) or _edge_sd(crease, cov, layout) > MAX_SD_MM:
        return "nor does the napkin's outline fix it (too uncertain)"
    return geometry_from_crease(fold.word, crease, layout, cov, stickers=part.stickers,
                                rms_mm=rms, source="outline")


def _part_map(
    uv: NDArray, p2: NDArray, mirror: bool, sd_mm: float, dof: float, outlier_mm: float
) -> PartMap | None:
    """:func:`fit_part_map`, leaving out up to two stickers farther than ``outlier_mm``
    from where the map puts them (a misread sticker), as long as three are kept."""
    keep = np.ones(len(uv), dtype=bool)
    for _ in range(3):
        part = fit_part_map(uv[keep], p2[keep], mirror=mirror, sticker_sd_mm=sd_mm,
                            prior_dof=dof)
        if part is None or np.count_nonzero(keep) <= 3:
            return part
        res = np.hypot(*(_to_table(part, uv) - p2).T)
        res[~keep] = -1.0
        worst = int(np.argmax(res))
        if res[worst] <= outlier_mm:
            return part
        keep[worst] = False
    return part
