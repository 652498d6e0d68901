"""Lens distortion from one image of the flat napkin, the way a chessboard is used.

The 16 sticker centres are points of known place on a plane (the layout), so one view of
the flat napkin calibrates the lens like one view of a chessboard: the napkin's pose and
the radial distortion ``k1`` (and ``k2``, and optionally the focal length) are fitted by
least squares to the detected centres. The principal point stays as given.

Two things differ from a chessboard. A cloth napkin is never perfectly flat: a wrinkle a
few millimetres high moves an off-centre sticker by pixels, as much as the lens does.
The depth image says how far each sticker is, so each model point is moved along the
napkin's normal by how far its measured depth lies off the fitted plane before it is
projected. And 16 points from one view say little about the lens if they stay near the
image centre, where distortion is small and ``k1`` and ``k2`` look alike: the fit's own
uncertainty (from its Jacobian and residuals, with a prior on ``k2``) tells when the
estimate is poorly constrained, and then no number is given as if it were known.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from ..core.camera import Intrinsics
from ..core.errors import CalibrationError
from ..core.layout import NapkinLayout
from .detect import DetectorParams, detect_all_stickers

__all__ = ["LensEstimate", "estimate_lens", "fit_lens"]

#: Standard deviation of a detected sticker centre assumed at least (pixels): a floor
#: under the fit's own residual, so that a lucky near-perfect fit does not claim more
#: precision than detection has.
CENTRE_SIGMA_PX = 0.1

#: Standard deviation of a sticker's depth (median over its disc), mm: weighs the depths
#: against the pixels when the focal length is fitted.
DEPTH_SIGMA_MM = 1.0

#: ``k1`` is taken as known when its standard deviation is at most this (half of the
#: 0.01 within which a lens is told apart, at two standard deviations).
MAX_K1_SD = 0.005

#: ``k2`` is fitted with this prior: 0 +/- 0.03, the spread of the lenses of RGB-D colour
#: cameras. A view whose stickers stay near the centre barely tells ``k2`` from ``k1``;
#: the prior keeps ``k2`` near 0 there, and ``k1``'s standard deviation then counts what
#: the view leaves open about ``k2`` (holding ``k2`` at 0 instead would give a ``k1``
#: that fits the radii seen but claims far more precision than it has).
K2_PRIOR_SD = 0.03

#: The focal length (with ``fit_focal``) is taken as known to this fraction (sd).
MAX_FOCAL_SD = 0.005


@dataclass(frozen=True)
class LensEstimate:
    """The lens fitted to one image of the flat napkin.

    Attributes
    ----------
    intrinsics : Intrinsics
        The given intrinsics with the fitted ``k1`` (and ``k2``, focal length) in.
    k1, k1_sd : float
        The radial coefficient and its standard deviation.
    k2, k2_sd : float
        ``k2_sd`` is NaN when ``k2`` was held fixed. With a view that barely shows it,
        ``k2`` stays near its prior (0) and its ``k2_sd`` near the prior's 0.03.
    focal, focal_sd : float
        ``fx`` (``fy`` keeps its ratio to it); ``focal_sd`` is NaN when held fixed.
    rms_px : float
        Root-mean-square distance of the detected centres from the fitted model.
    reach : float
        How far the farthest sticker lies towards the image corner, from the principal
        point: 0 at the centre, 1 at the corner.
    shift_px : ndarray, shape (16,)
        How far the fitted lens moves each sticker centre (distorted to undistorted).
    problem : str or None
        Why the estimate is poorly constrained (None when it is not).
    """

    intrinsics: Intrinsics
    k1: float
    k1_sd: float
    k2: float
    k2_sd: float
    focal: float
    focal_sd: float
    rms_px: float
    reach: float
    shift_px: NDArray[np.float64]
    problem: str | None = None

    @property
    def constrained(self) -> bool:
        """True when the view determines the fitted terms well."""
        return self.problem is None


def _rotation(rvec: NDArray[np.float64]) -> NDArray[np.float64]:
    import cv2

    return cv2.Rodrigues(rvec)[0]


def _model_points(
    x: NDArray[np.float64], plane_mm: NDArray[np.float64], depth_m: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Camera-frame points of the layout under pose ``x[:6]`` (rvec, tvec).

    Each point is moved along the napkin's normal by how far its measured depth says it
    lies off the plane (a wrinkle), less the best affine fit of those offsets over the
    napkin, so that the depths correct the shape but never the pose itself."""
    rot = _rotation(x[:3])
    pts = plane_mm @ rot[:, :2].T * 1e-3 + x[3:6]
    normal = rot[:, 2]
    known = np.isfinite(depth_m)
    if abs(normal[2]) < 0.2 or known.sum() < 4:  # the napkin seen edge-on: nothing to do
        return pts
    off = (depth_m[known] - pts[known, 2]) / normal[2]
    basis = np.column_stack([np.ones(known.sum()), plane_mm[known]])
    coef, *_ = np.linalg.lstsq(basis, off, rcond=None)
    lift = np.zeros(len(pts))
    lift[known] = off - basis @ coef
    return pts + lift[:, None] * normal


@dataclass(frozen=True)
class _Problem:
    """What is fitted: pose (6), then k1, then k2 and the focal scale if free."""

    intrinsics: Intrinsics
    plane_mm: NDArray[np.float64]
    pixels: NDArray[np.float64]
    depth_m: NDArray[np.float64]
    fit_k2: bool
    fit_focal: bool

    def lens(self, x: NDArray[np.float64]) -> Intrinsics:
        intr = self.intrinsics
        d = [*intr.distortion, 0.0, 0.0, 0.0, 0.0][: max(4, len(intr.distortion))]
        d[0] = float(x[6])
        at = 7
        if self.fit_k2:
            d[1] = float(x[at])
            at += 1
        scale = float(x[at]) if self.fit_focal else 1.0
        return replace(intr, fx=intr.fx * scale, fy=intr.fy * scale, distortion=tuple(d))

    def residuals(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        pts = _model_points(x, self.plane_mm, self.depth_m)
        if (pts[:, 2] <= 0).any():
            return np.full(2 * len(pts), 1e3)
        lens = self.lens(x)
        norm = np.column_stack([pts[:, 0] / pts[:, 2], pts[:, 1] / pts[:, 2]])
        ideal = np.column_stack([lens.fx * norm[:, 0] + lens.cx, lens.fy * norm[:, 1] + lens.cy])
        parts = [(lens.distort_pixels(ideal) - self.pixels).reshape(-1)]
        if self.fit_k2:  # the prior, in units of the pixel residuals
            k2 = (*self.intrinsics.distortion, 0.0, 0.0)[1]
            parts.append(np.array([(x[7] - k2) / K2_PRIOR_SD * CENTRE_SIGMA_PX]))
        if self.fit_focal:  # the distance, and with it the focal length, from the depths
            known = np.isfinite(self.depth_m)
            dz = (pts[known, 2] - self.depth_m[known]) * 1e3 / DEPTH_SIGMA_MM
            parts.append(dz * CENTRE_SIGMA_PX)
        return np.concatenate(parts)


def _initial_pose(
    intrinsics: Intrinsics, plane_mm: NDArray[np.float64], pixels: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The napkin's pose from the pinhole model (OpenCV's planar PnP)."""
    import cv2

    obj = np.column_stack([plane_mm * 1e-3, np.zeros(len(plane_mm))])
    ok, rvec, tvec = cv2.solvePnP(
        obj, pixels.astype(np.float64), intrinsics.matrix(), None, flags=cv2.SOLVEPNP_IPPE
    )
    if not ok:  # pragma: no cover - IPPE solves any 4+ points in general position
        raise CalibrationError("the sticker centres do not give a pose of the napkin")
    return np.concatenate([rvec.reshape(3), tvec.reshape(3)])


def _solve(problem: _Problem, x0: NDArray[np.float64]) -> tuple[NDArray, NDArray, float]:
    """Least squares: the solution, the standard deviations of its parameters, the RMS
    residual (pixels)."""
    from scipy.optimize import least_squares

    fit = least_squares(problem.residuals, x0, method="lm", x_scale="jac")
    n = len(problem.pixels)
    rms = float(np.sqrt((fit.fun[: 2 * n].reshape(n, 2) ** 2).sum(axis=1).mean()))
    dof = max(len(fit.fun) - len(x0), 1)
    sigma = max(float(np.sqrt((fit.fun**2).sum() / dof)), CENTRE_SIGMA_PX)
    try:
        cov = np.linalg.inv(fit.jac.T @ fit.jac) * sigma**2
        sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    except np.linalg.LinAlgError:
        sd = np.full(len(x0), np.inf)
    return fit.x, sd, rms


def fit_lens(
    intrinsics: Intrinsics,
    plane_mm: NDArray[np.float64],
    pixels: NDArray[np.float64],
    depth_m: NDArray[np.float64] | None = None,
    *,
    fit_k2: bool = True,
    fit_focal: bool = False,
) -> LensEstimate:
    """Fit ``k1`` (and ``k2``, the focal length) to points of known place on a plane.

    Parameters
    ----------
    intrinsics : Intrinsics
        Focal length, principal point and any other distortion terms to keep.
    plane_mm : ndarray, shape (n, 2)
        Where the points lie on the plane (mm), e.g. the layout's sticker centres.
    pixels : ndarray, shape (n, 2)
        Where they are seen in the (distorted) image.
    depth_m : ndarray, shape (n,), optional
        Each point's measured z-depth (metres; NaN where unknown): a point that lies off
        the plane (a wrinkle) is moved along the normal to it. Needed with
        ``fit_focal`` (one view of a plane seen square-on does not tell the focal length
        from the distance).
    fit_k2 : bool, keyword-only
        Fit ``k2`` too (with the prior :data:`K2_PRIOR_SD`); otherwise it is held at the
        given value.
    fit_focal : bool, keyword-only
        Fit the focal length (``fx``, ``fy`` in the same ratio) too.

    Returns
    -------
    LensEstimate
        ``problem`` says when the fitted terms are poorly constrained.
    """
    plane = np.asarray(plane_mm, dtype=np.float64)
    pix = np.asarray(pixels, dtype=np.float64)
    depth = np.full(len(pix), np.nan) if depth_m is None else np.asarray(depth_m, np.float64)
    if fit_focal and not np.isfinite(depth).any():
        raise ValueError("fitting the focal length needs the points' depths")
    pose = _initial_pose(intrinsics, plane, pix)
    k1, k2 = (*intrinsics.distortion, 0.0, 0.0)[:2]
    fitted = _Problem(intrinsics, plane, pix, depth, fit_k2, fit_focal)
    start = [*pose, k1, *([k2] if fit_k2 else []), *([1.0] if fit_focal else [])]
    x, sd, rms = _solve(fitted, np.array(start))
    k2_sd = float(sd[7]) if fit_k2 else float("nan")
    lens = fitted.lens(x)
    focal_sd = float(sd[-1] * intrinsics.fx) if fit_focal else float("nan")
    k1_sd = float(sd[6])
    reach = _reach(intrinsics, pix)
    problem = _poorly_constrained(k1_sd, focal_sd, reach, intrinsics.fx if fit_focal else None)
    shift = np.linalg.norm(lens.undistort_pixels(pix) - pix, axis=1)
    return LensEstimate(
        intrinsics=lens,
        k1=lens.distortion[0],
        k1_sd=k1_sd,
        k2=lens.distortion[1],
        k2_sd=k2_sd,
        focal=lens.fx,
        focal_sd=focal_sd,
        rms_px=rms,
        reach=reach,
        shift_px=shift,
        problem=problem,
    )


def _poorly_constrained(
    k1_sd: float, focal_sd: float, reach: float, fx: float | None
) -> str | None:
    """Why a fit is poorly constrained, with what to do about it (None when it is not):
    ``k1``'s standard deviation above :data:`MAX_K1_SD`, or the focal length's (when
    fitted: ``fx`` given) above :data:`MAX_FOCAL_SD` of ``fx``."""
    problems = []
    if not (k1_sd <= MAX_K1_SD):
        problems.append(
            f"k1 is known only to +/- {k1_sd:.3f}: the stickers reach {reach:.0%} of the way "
            "to the image corner; place the napkin off to one side so that its stickers "
            "reach towards a corner, or fill more of the view"
        )
    if fx is not None and not (focal_sd <= MAX_FOCAL_SD * fx):
        problems.append(
            f"the focal length is known only to +/- {focal_sd:.1f} px; tilt the camera or "
            "fill more of the view"
        )
    return "; ".join(problems) or None


def _reach(intrinsics: Intrinsics, pixels: NDArray[np.float64]) -> float:
    """How far the farthest pixel lies from the principal point, as a fraction of the
    distance to the farthest image corner."""
    centre = np.array([intrinsics.cx, intrinsics.cy])
    corners = np.array(
        [
            [0, 0],
            [intrinsics.width - 1, 0],
            [0, intrinsics.height - 1],
            [intrinsics.width - 1, intrinsics.height - 1],
        ],
        dtype=np.float64,
    )
    corner = np.linalg.norm(corners - centre, axis=1).max()
    return float(np.linalg.norm(pixels - centre, axis=1).max() / corner)


def estimate_lens(
    color: NDArray[np.uint8],
    depth_mm: NDArray[np.uint16],
    intrinsics: Intrinsics,
    layout: NapkinLayout,
    *,
    fit_focal: bool = False,
    fit_k2: bool = True,
    params: DetectorParams | None = None,
    source: str = "image",
) -> LensEstimate:
    """Estimate the lens distortion from one image of the flat napkin.

    Parameters
    ----------
    color : ndarray of uint8, shape (H, W, 3)
        RGB image of the flat napkin, all 16 stickers in view; the larger the part of
        the view the napkin fills, the better ``k1`` is determined.
    depth_mm : ndarray of uint16, shape (H, W)
        Depth registered to colour (mm, 0 = none).
    intrinsics : Intrinsics
        The focal length and principal point (kept unless ``fit_focal``); their own
        distortion, if any, is the starting point and its other terms are kept.
    layout : NapkinLayout
    fit_focal, fit_k2 : bool, keyword-only
        See :func:`fit_lens`.
    params : DetectorParams, keyword-only, optional
    source : str, keyword-only
        Name of the image, for messages.

    Returns
    -------
    LensEstimate

    Raises
    ------
    CalibrationError
        Fewer than 16 stickers found.
    """
    pinhole = replace(intrinsics, distortion=())
    det, _ = detect_all_stickers(
        color, depth_mm, pinhole, layout, params, source=source, purpose="lens calibration"
    )
    radii = np.sqrt(det.areas / np.pi)
    z = _sticker_depths(depth_mm, det.centroids, radii) * 1e-3
    return fit_lens(
        intrinsics, layout.sticker_uv, det.centroids, z, fit_k2=fit_k2, fit_focal=fit_focal
    )


def _sticker_depths(
    depth_mm: NDArray[np.uint16],
    centres: NDArray[np.float64],
    radii_px: NDArray[np.float64],
    *,
    min_pixels: int = 20,
) -> NDArray[np.float64]:
    """Depth (mm) at each centre, to a fraction of a millimetre: a plane fitted to the
    valid depth pixels within ``radii_px`` of it, refitted once without the pixels more
    than 3 standard deviations off. Depth comes in whole millimetres, so the median of a
    sticker's pixels is off by up to half of one; averaging the sensor's noise over a
    disc gives the centre's depth much finer, and the wrinkles' slope is fitted away.
    NaN where fewer than ``min_pixels`` have a reading.
    """
    h, w = depth_mm.shape
    out = np.full(len(centres), np.nan)
    for i, ((cu, cv), r) in enumerate(zip(centres, radii_px)):
        if not (np.isfinite(cu) and np.isfinite(r) and r > 0):
            continue
        x0, x1 = max(int(cu - r), 0), min(int(cu + r) + 2, w)
        y0, y1 = max(int(cv - r), 0), min(int(cv + r) + 2, h)
        yy, xx = np.mgrid[y0:y1, x0:x1]
        z = depth_mm[y0:y1, x0:x1].astype(np.float64)
        keep = (z > 0) & ((xx - cu) ** 2 + (yy - cv) ** 2 <= r * r)
        if keep.sum() < min_pixels:
            continue
        basis = np.column_stack([np.ones(keep.sum()), xx[keep] - cu, yy[keep] - cv])
        values = z[keep]
        for _ in range(2):
            coef, *_ = np.linalg.lstsq(basis, values, rcond=None)
            resid = values - basis @ coef
            near = np.abs(resid) <= 3 * max(resid.std(), 0.5)
            if near.all() or near.sum() < min_pixels:
                break
            basis, values = basis[near], values[near]
        out[i] = coef[0]
    return out
