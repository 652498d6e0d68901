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
outline's farthest reach: mapped back to the flat napkin, the outline's points reach the
crease and never pass it. Along the crease's middle (away from the corners where the
outline turns) the farthest point of the outline in each short stretch is a point of the
folded edge; a straight line fitted to those (a few stretches that stick out, an object
touching the cloth, left out) is the crease.

The outline is found at the pixel: the napkin's cells of the footprint
(:class:`~dgli_vision.perception.footprint.Footprint`) give the region; in a band around
its border each pixel is cloth where it is brighter than the midpoint of the cloth's and
the table's brightness around it (the colour edge); the region's border is placed to a
tenth of a pixel where the brightness crosses that midpoint along the border's normal,
and taken onto the table plane through the camera (the intrinsics, lens distortion
included) at the height of the folded cloth.

The crease's uncertainty pools the line fit's (the scatter of the stretches about it)
with the map's (the stickers' scatter about the rigid map).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
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
    "fit_part_map",
    "napkin_outline_px",
    "outline_crease",
    "outline_geometry",
    "outline_points_mm",
    "outline_view",
]


@dataclass(frozen=True)
class OutlineParams:
    """How the crease is fitted to the outline. Every field has a unit and a reason.

    Attributes
    ----------
    band_cells : int
        Half width of the band around the border of the napkin's cells searched at the
        pixel, cells. Default 2: a cell's border is within one cell of the cloth's.
    level_cells : int
        Side of the window the cloth's and the table's brightness are averaged over,
        cells. Default 9 (72 pixels): wider than twice the band, so both sides are in
        the window of every cell of the band, and narrow enough to follow an arm's
        shadow or a lamp's fall-off.
    min_contrast : float
        Least difference of the cloth's and the table's brightness (8-bit levels) for
        a border pixel to count. Default 12: sensor noise is 2-10 levels.
    stretch_mm : float
        Length of the stretches along the crease each giving one farthest point, mm.
        Default 10: 6-15 pixels of outline, and a wrinkle's wavelength is 100-250 mm.
    top_mm : float
        Points within this distance of a stretch's farthest point stand for it (their
        median), mm. Default 2: the pixel's size at the farthest camera.
    end_margin_mm : float
        Length kept free at each end of the crease, mm. Default 25: the outline turns
        the corner there, and the cloth bends round it.
    min_cover : float
        Least share of the crease's stretches that must fit the line. Default 0.5: an
        arm or an object may hide part of the edge, not most of it.
    trim_mm : float
        Least distance from the line beyond which a stretch is left out (a stretch that
        sticks out: cloth peeking from beneath, an object touching it), mm. Default 3;
        more where the stretches scatter more (3 of their robust sd).
    floor_sd_mm : float
        Floor of a stretch's scatter about the line, mm. Default 0.7: half a pixel at
        the nearest camera.
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

    band_cells: int = 2
    level_cells: int = 9
    min_contrast: float = 12.0
    stretch_mm: float = 10.0
    top_mm: float = 2.0
    end_margin_mm: float = 25.0
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
        The colour image, RGB (its brightness, OpenCV's luma, is read).
    cells : ndarray of bool, shape (H // cell_px, W // cell_px)
        The napkin's cells (the footprint's).
    cell_px : int
    intrinsics : Intrinsics
    up : ndarray, shape (3,)
        The table's normal, towards the camera.
    offset_m : float
        The table plane ``up . x = offset_m`` (camera frame, metres).
    """

    color: NDArray[np.uint8]
    cells: NDArray[np.bool_]
    cell_px: int
    intrinsics: Intrinsics
    up: NDArray[np.float64]
    offset_m: float


def outline_view(frame: Any, obs: Any) -> OutlineView | None:
    """The :class:`OutlineView` of a frame (an
    :class:`~dgli_vision.sources.frames.RGBDFrame`) and its observation (a
    :class:`~dgli_vision.classifier.pipeline.ClothObservation`); None where no sticker
    gives the table's height or no white region holds a sticker.

    The napkin's cells are the footprint's; where the footprint was not measured (the
    napkin runs out of the image), the frame's white regions that hold stickers
    (:func:`~dgli_vision.perception.regions.cloth_regions`): the outline's part in view
    still fixes the crease."""
    if obs.points_m is None or obs.heights_mm is None:
        return None
    # the table plane: the heights were measured from it (up . x - offset, in mm)
    seen = np.asarray(obs.visible, dtype=bool) & np.isfinite(obs.heights_mm)
    if not seen.any():
        return None
    up = np.asarray(obs.up, dtype=float)
    offset = float(np.median(obs.points_m[seen] @ up - obs.heights_mm[seen] * 1e-3))
    foot = getattr(obs, "footprint", None)
    cells = None if foot is None else foot.cells
    if cells is None or not cells.any():
        cells = _white_cells(frame, obs.points_m[seen], up, offset)
        if cells is None:
            return None
    h, w = frame.color.shape[:2]
    cell = h // cells.shape[0]
    if cell < 1 or w // cell != cells.shape[1]:
        return None
    return OutlineView(frame.color, cells, cell, frame.intrinsics, up, offset)


def _white_cells(
    frame: Any, points_m: NDArray, up: NDArray, offset_m: float
) -> NDArray[np.bool_] | None:
    """The frame's white regions that hold the stickers ``points_m`` (k, 3), on the
    cells of :class:`~dgli_vision.perception.regions.RegionParams` (None: none)."""
    from ..perception.napkin import find_napkin
    from ..perception.regions import any_of, cloth_regions

    napkin = find_napkin(frame.color, frame.depth_mm, frame.intrinsics, up, offset_m)
    regions = cloth_regions(frame.color, napkin.white_rgb)
    if regions is None:
        return None
    labels, c = regions.labels, regions.cell_px
    px = frame.intrinsics.project(points_m)
    col = np.clip(px[:, 0] // c, 0, labels.shape[1] - 1).astype(np.intp)
    row = np.clip(px[:, 1] // c, 0, labels.shape[0] - 1).astype(np.intp)
    held = np.array(sorted(set(labels[row, col].tolist()) - {0}), dtype=labels.dtype)
    return any_of(labels, held) if held.size else None


def _levels(
    gray_cells: NDArray, inner: NDArray, outer: NDArray, k: int
) -> tuple[NDArray, NDArray]:
    """The mean brightness of the cloth cells (``inner``) and of the table's
    (``outer``) in a ``k`` x ``k`` window of cells about each cell; where a window holds
    none, the median of all of them."""
    import cv2

    def mean(sel: NDArray) -> NDArray:
        w = sel.astype(np.float32)
        num = cv2.boxFilter(gray_cells * w, -1, (k, k), normalize=False)
        den = cv2.boxFilter(w, -1, (k, k), normalize=False)
        fill = float(np.median(gray_cells[sel])) if sel.any() else float("nan")
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(den > 0.5, num / den, fill).astype(np.float32)

    return mean(inner), mean(outer)


def napkin_outline_px(view: OutlineView, params: OutlineParams | None = None) -> NDArray:
    """The napkin region's outer border, pixels (k, 2) as (x, y), placed to a fraction
    of a pixel (see the module's description); empty (0, 2) when it cannot be found."""
    import cv2

    p = params or OutlineParams()
    c, cells = view.cell_px, view.cells.astype(np.uint8)
    h, w = view.color.shape[:2]
    hc, wc = cells.shape
    # the band, the cloth inside it and the table outside it, on the cells; the
    # brightness midpoint and the contrast there too (windows of cells: a pixel's
    # brightness is compared with the midpoint interpolated between cell centres)
    kernel = np.ones((2 * p.band_cells + 1,) * 2, np.uint8)
    inner_c, near_c = cv2.erode(cells, kernel), cv2.dilate(cells, kernel)
    rows, cols = np.nonzero(near_c)
    if not len(rows):
        return np.zeros((0, 2))
    m = p.level_cells // 2  # the crop: the band and the windows about it, in cells
    r0, r1 = max(rows.min() - m, 0), min(rows.max() + 1 + m, hc)
    c0, c1 = max(cols.min() - m, 0), min(cols.max() + 1 + m, wc)
    y0, x0 = r0 * c, c0 * c
    size = ((c1 - c0) * c, (r1 - r0) * c)  # (width, height) of the crop, pixels
    crop = np.ascontiguousarray(view.color[y0 : y0 + size[1], x0 : x0 + size[0]])
    gray8 = cv2.cvtColor(crop, cv2.COLOR_RGB2GRAY)
    gray = gray8.astype(np.float32)
    gray_c = cv2.resize(gray8, (c1 - c0, r1 - r0), interpolation=cv2.INTER_AREA)
    inner_c, near_c = inner_c[r0:r1, c0:c1], near_c[r0:r1, c0:c1]
    cloth, table = _levels(gray_c.astype(np.float32), inner_c > 0, near_c == 0,
                           p.level_cells)

    def up(a: NDArray, how: int) -> NDArray:
        return cv2.resize(np.ascontiguousarray(a), size, interpolation=how)

    mid = up(0.5 * (cloth + table), cv2.INTER_LINEAR)
    contrast = up(cloth - table, cv2.INTER_LINEAR)
    inner = up(inner_c, cv2.INTER_NEAREST) > 0
    near = up(near_c, cv2.INTER_NEAREST) > 0
    fg = inner | (near & (gray > mid) & (contrast >= p.min_contrast))
    n_lab, labels = cv2.connectedComponents(fg.view(np.uint8), connectivity=8)
    keep = np.bincount(labels[inner], minlength=n_lab) > 0
    keep[0] = False
    if not keep.any():
        return np.zeros((0, 2))
    mask = keep[labels].astype(np.uint8)
    contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    pts = [ct.reshape(-1, 2).astype(np.float64) for ct in contours if len(ct) >= 20]
    if not pts:
        return np.zeros((0, 2))
    out = [_subpixel(ct, gray, mid, contrast, p) for ct in pts]
    xy = np.concatenate(out) + np.array([x0, y0], dtype=float)
    # where the region runs out of the image its border is the image's, not the cloth's
    inside = (xy[:, 0] > 2) & (xy[:, 1] > 2) & (xy[:, 0] < w - 3) & (xy[:, 1] < h - 3)
    return xy[inside]


def _subpixel(
    ct: NDArray, gray: NDArray, mid: NDArray, contrast: NDArray, p: OutlineParams
) -> NDArray:
    """The border pixels ``ct`` (k, 2) of one contour, each moved along the contour's
    normal to where the brightness crosses its midpoint (its pixel centre kept where
    no crossing is found within two pixels); those with too little contrast dropped."""
    import cv2

    k = len(ct)
    step = 3
    tangent = np.roll(ct, -step, axis=0) - np.roll(ct, step, axis=0)  # (k, 2)
    norm = np.hypot(tangent[:, 0], tangent[:, 1])
    ok = norm > 0
    normal = np.zeros_like(tangent)
    normal[ok] = np.column_stack([tangent[ok, 1], -tangent[ok, 0]]) / norm[ok, None]
    # the normal pointing out of the region: OpenCV walks an outer contour so that the
    # region is on one side; test it on the brightness
    offs = np.linspace(-2.0, 2.0, 17)  # (m,)
    sx = (ct[:, 0, None] + offs[None] * normal[:, 0, None]).astype(np.float32)
    sy = (ct[:, 1, None] + offs[None] * normal[:, 1, None]).astype(np.float32)
    g = cv2.remap(gray, sx, sy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    i, j = np.clip(ct[:, 1].astype(int), 0, gray.shape[0] - 1), np.clip(
        ct[:, 0].astype(int), 0, gray.shape[1] - 1)
    m = mid[i, j]
    f = g - m[:, None]  # (k, m): positive on cloth
    if np.nanmean(f[:, 0] - f[:, -1]) < 0:  # the normal points inwards: turn it
        f, normal = f[:, ::-1], -normal
    # the first crossing from cloth to table going out from the inside
    s = np.full(k, np.nan)
    pos = f > 0
    cross = pos[:, :-1] & ~pos[:, 1:]
    has = cross.any(axis=1)
    first = np.argmax(cross, axis=1)
    a = f[np.arange(k), first]
    b = f[np.arange(k), first + 1]
    t = np.where(has, a / np.where(a - b == 0, 1.0, a - b), 0.0)
    s[has] = (offs[first] + t * (offs[1] - offs[0]))[has]
    good = has & ok & (contrast[i, j] >= p.min_contrast) & np.isfinite(m)
    return ct[good] + s[good, None] * normal[good]


def outline_points_mm(
    view: OutlineView, px: NDArray, basis: NDArray, height_mm: float = 0.0
) -> NDArray[np.float64]:
    """Pixels (k, 2) taken onto the plane ``height_mm`` above the table, in the table
    plane's coordinates ``basis`` (2, 3) (mm: the camera-frame point's components
    along the basis, as :func:`~dgli_vision.classifier.fold_geometry.fit_folds` places
    the stickers)."""
    if not len(px):
        return np.zeros((0, 2))
    ideal = view.intrinsics.undistort_pixels(px)
    i = view.intrinsics
    rays = np.column_stack([(ideal[:, 0] - i.cx) / i.fx, (ideal[:, 1] - i.cy) / i.fy,
                            np.ones(len(ideal))])
    along = rays @ view.up
    with np.errstate(divide="ignore", invalid="ignore"):
        z = (view.offset_m + height_mm * 1e-3) / along
    pts = rays * z[:, None]
    ok = np.isfinite(z) & (z > 0)
    return (pts[ok] @ basis.T) * 1e3


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


def _stretch_points(
    q: NDArray, origin: NDArray, t: NDArray, n: NDArray, span: tuple[float, float],
    p: OutlineParams,
) -> tuple[NDArray, NDArray]:
    """The outline's farthest reach along ``n`` in each stretch of ``span`` along
    ``t``: (along, across) of one point a stretch, stretches without points left out."""
    rel = q - origin
    s, d = rel @ t, rel @ n
    lo, hi = span
    keep = (s >= lo) & (s < hi)
    s, d = s[keep], d[keep]
    n_bins = max(int((hi - lo) // p.stretch_mm), 1)
    b = np.minimum(((s - lo) / p.stretch_mm).astype(int), n_bins - 1)
    order = np.lexsort((-d, b))
    s, d, b = s[order], d[order], b[order]
    starts = np.searchsorted(b, np.arange(n_bins))
    ends = np.searchsorted(b, np.arange(n_bins), side="right")
    out_s, out_d = [], []
    for i0, i1 in zip(starts.tolist(), ends.tolist()):
        if i1 <= i0:
            continue
        top = d[i0:i1] >= d[i0] - p.top_mm
        out_s.append(float(np.median(s[i0:i1][top])))
        out_d.append(float(np.median(d[i0:i1][top])))
    return np.asarray(out_s), np.asarray(out_d)


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


def outline_crease(
    points_mm: NDArray,
    part: PartMap,
    fold: NominalFold,
    layout: NapkinLayout,
    params: OutlineParams | None = None,
) -> tuple[Crease, NDArray[np.float64], int, float] | str:
    """The crease of ``fold`` from the outline ``points_mm`` (k, 2, the table plane's
    mm) and the map ``part`` of what is seen of the napkin (the flap folded over, or the
    napkin that stays over a flap folded under).

    Returns
    -------
    (Crease, cov, stretches, rms_mm) or str
        The crease on the flat napkin, the covariance (2, 2) of its normal's angle
        (radians) and offset (mm) as :meth:`Crease.from_normal` takes them, the number
        of stretches of the outline fitted and their RMS distance from it (mm); or why
        the outline does not fix it.
    """
    p = params or OutlineParams()
    if len(points_mm) < 20:
        return "the napkin's outline is not found"
    a0, b0 = np.asarray(fold.p0, dtype=float), np.asarray(fold.p1, dtype=float)
    t = (b0 - a0) / np.linalg.norm(b0 - a0)
    n = np.array([-t[1], t[0]])
    flap_side = (np.asarray(fold.flap, dtype=float) - a0) @ n > 0
    # what is seen reaches the crease from the flap's side (a flap over, mapped back
    # by its own map) or from the side that stays (a flap under): n points past it
    if flap_side != fold.under:
        n = -n
    ends = Crease.through(a0, b0).ends_in(layout)
    if ends is None:
        return "the nominal crease misses the napkin"
    s_ends = sorted(float((np.asarray(e) - a0) @ t) for e in ends)
    span = (s_ends[0] + p.end_margin_mm, s_ends[1] - p.end_margin_mm)
    if span[1] - span[0] < 4 * p.stretch_mm:
        return "the crease is too short to fit"
    q = part.to_material(points_mm)
    s, d = _stretch_points(q, a0, t, n, span, p)
    fit = _robust_line(s, d, p)
    expected = (span[1] - span[0]) / p.stretch_mm
    if fit is None or np.count_nonzero(fit[2]) < p.min_cover * expected:
        return "the napkin's outline does not follow the crease (hidden or not straight)"
    a, b, keep, sd = fit
    kept = int(np.count_nonzero(keep))
    edge = p.edge_mm * layout.thickness_mm
    crease, line_cov = _crease_of(a0, t, n, a - edge, b, s[keep], sd)
    # the map's share: the same stretches (as table points) mapped back by a map moved
    # a little, each parameter in turn
    table = _to_table(part, a0 + np.outer(s[keep], t) + np.outer(d[keep], n))
    base = _normal_form(crease)
    jac = np.zeros((2, 3))
    for k, h in enumerate((1e-5, 1e-3, 1e-3)):
        qq = part.perturbed(k, h).to_material(table)
        rel = qq - a0
        aa, bb, _ = _line_through(rel @ t, rel @ n)
        other, _ = _crease_of(a0, t, n, aa - edge, bb, s[keep], sd)
        jac[:, k] = (_normal_form(other, base[0]) - base) / h
    cov = line_cov + jac @ part.cov @ jac.T
    cov[1, 1] += p.edge_sd_mm**2
    rms = float(np.sqrt(np.mean((d[keep] - (a + b * s[keep])) ** 2)))
    return crease, cov, kept, rms


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
        PRIOR_DOF,
        STICKER_SD_MM,
        _edge_sd,
        geometry_from_crease,
        plane_basis,
    )

    p = params or OutlineParams()
    mine = lying & (sticker_part == (-1 if fold.under else index))
    if np.count_nonzero(mine) < 2:
        return "fewer than two stickers seen place the napkin's outline"
    basis = plane_basis(obs.up)
    p2 = (obs.points_m[mine] @ basis.T) * 1e3
    uv = np.asarray(layout.sticker_uv, dtype=float)[mine]
    part = fit_part_map(uv, p2, mirror=not fold.under, sticker_sd_mm=STICKER_SD_MM,
                        prior_dof=PRIOR_DOF)
    if part is None:
        return "the stickers seen do not place the napkin's outline"
    px = napkin_outline_px(view, p)
    pts = outline_points_mm(view, px, basis, p.height_mm * layout.thickness_mm)
    got = outline_crease(pts, part, fold, layout, p)
    if isinstance(got, str):
        return got
    crease, cov, _, rms = got
    if not np.all(np.isfinite(cov)) or _edge_sd(crease, cov, layout) > MAX_SD_MM:
        return "the napkin's outline does not fix the crease"
    return geometry_from_crease(fold.word, crease, layout, cov, stickers=part.stickers,
                                rms_mm=rms, source="outline")
