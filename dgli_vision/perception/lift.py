"""Lifting detected stickers to 3D, and the table plane that gives ``up``."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ..core.camera import Intrinsics
from ..core.order_stats import median
from .detect import StickerDetections

__all__ = ["Markers3D", "estimate_table_normal", "estimate_table_plane", "lift_stickers"]


@dataclass(frozen=True, eq=False)
class Markers3D:
    """Sticker centres in the camera frame.

    Attributes
    ----------
    points : ndarray, shape (16, 3)
        Metres, camera frame (x right, y down, z forward); NaN where missing.
    """

    points: NDArray[np.float64]

    @property
    def found(self) -> NDArray[np.bool_]:
        """Which stickers have a 3D point, shape (16,)."""
        return ~np.isnan(self.points[:, 0])


def lift_stickers(detections: StickerDetections, intrinsics: Intrinsics) -> Markers3D:
    """Deproject each detected sticker's centroid at its robust (median) depth.

    The depth is the median of the valid depth pixels inside the sticker blob (see
    :func:`~dgli_vision.perception.detect.detect_stickers`), so a missing or noisy
    reading at the centroid pixel does not matter; a sticker without any valid depth
    inside stays missing.

    With lens distortion (``intrinsics.distortion``) the centroid, found in the
    distorted image, is undistorted before it is deprojected. The depth stays the one
    read around the distorted centroid: depth registered to colour holds, at each colour
    pixel, the z of the point seen there, and undistortion does not change z.
    """
    z = detections.depth_mm * 1e-3
    ok = detections.found & np.isfinite(z) & (z > 0)
    points = np.full((len(z), 3), np.nan)
    if ok.any():
        centres = intrinsics.undistort_pixels(detections.centroids[ok])
        points[ok] = intrinsics.deproject(centres, z[ok])
    return Markers3D(points)


def estimate_table_normal(
    depth_mm: NDArray[np.uint16], intrinsics: Intrinsics, *, stride: int = 10, iterations: int = 4
) -> NDArray[np.float64]:
    """Unit normal (3,) of the dominant plane of the depth image, towards the camera.

    See :func:`estimate_table_plane`.
    """
    return estimate_table_plane(
        depth_mm, intrinsics, stride=stride, iterations=iterations, coarse_stride=None
    )[0]


def _mean_in_order(pts: NDArray[np.float64]) -> NDArray[np.float64]:
    """Mean of each row of ``pts`` (3, n), summed point after point: the figures of the
    fit do not depend on how the points lie in memory (numpy sums a contiguous row
    pairwise, a strided one in order)."""
    return np.cumsum(pts, axis=1)[:, -1] / pts.shape[1]


def _fit_plane(
    pts: NDArray[np.float64], active: NDArray[np.bool_], iterations: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """Robust plane through the ``active`` points of ``pts`` (3, n): unit normal towards
    the camera, a point on it, and its inliers."""
    keep = active.copy()
    normal = np.array([0.0, 0.0, -1.0])
    centre = None
    caps = (0.10, 0.04) + (0.015,) * max(iterations - 2, 0)  # metres: narrow down slowly
    settled = False  # the inliers did not change: the fit and its residuals neither
    for cap in caps[:iterations]:
        if not settled:
            inliers = pts.compress(keep, axis=1)
            centre = _mean_in_order(inliers)
            rel = inliers - centre[:, None]
            _, vecs = np.linalg.eigh(rel @ rel.T)  # smallest eigenvector: the plane normal
            normal = vecs[:, 0]
            resid = np.abs(normal @ pts - normal @ centre)
            mad = median(resid[keep])
        new_keep = active & (resid < min(max(3.0 * 1.4826 * mad, 0.003), cap))
        if np.count_nonzero(new_keep) < 50:
            break
        settled = np.array_equal(new_keep, keep)
        keep = new_keep
    if centre is None:
        centre = _mean_in_order(pts.compress(keep, axis=1))
    if normal @ (-centre) < 0:  # point towards the camera at the origin
        normal = -normal
    return normal, centre, keep


def _sample_rays(
    intrinsics: Intrinsics, shape: tuple[int, int], stride: int
) -> NDArray[np.float64]:
    """``(u - cx) / fx`` and ``(v - cy) / fy`` (2, h, w) of the undistorted pixels of
    every ``stride``-th pixel (``shape``: the subsampled grid's), made once per camera:
    each pixel is undistorted on its own, so the rays of the valid ones are those
    :meth:`~dgli_vision.core.camera.Intrinsics.undistort_pixels` gives them."""
    try:
        return _camera_rays(intrinsics, shape, stride)
    except TypeError:  # intrinsics that cannot be a key (a list of coefficients)
        return _camera_rays.__wrapped__(intrinsics, shape, stride)


@lru_cache(maxsize=8)
def _camera_rays(
    intrinsics: Intrinsics, shape: tuple[int, int], stride: int
) -> NDArray[np.float64]:
    """:func:`_sample_rays`, kept for the last few cameras."""
    vv, uu = np.indices(shape).reshape(2, -1)
    pix = intrinsics.undistort_pixels(np.stack([uu * stride, vv * stride], axis=1))
    rays = np.stack(
        [(pix[:, 0] - intrinsics.cx) / intrinsics.fx, (pix[:, 1] - intrinsics.cy) / intrinsics.fy]
    ).reshape(2, *shape)
    rays.flags.writeable = False
    return rays


def estimate_table_plane(
    depth_mm: NDArray[np.uint16],
    intrinsics: Intrinsics,
    *,
    stride: int = 16,
    iterations: int = 4,
    max_tilt_deg: float = 35.0,
    below_mm: float = 30.0,
    below_share: float = 0.1,
    coarse_stride: int | None = 24,
    min_coarse_samples: int = 1000,
) -> tuple[NDArray[np.float64], float]:
    """The table plane of the depth image: unit normal (3,) towards the camera and
    offset ``normal @ x`` (metres) of its points.

    A robust least-squares fit: the plane through a subsample of the valid depth pixels
    is refitted on its inliers (within 3 MAD and at most 15 mm), a few times: every
    ``coarse_stride``-th pixel where that gives at least ``min_coarse_samples`` valid
    ones (24: 1,620 samples of a 1280 x 720 frame), else every ``stride``-th pixel (16:
    1,200 samples of a VGA frame); a thousand samples are plenty for three numbers (the
    two samplings' planes of the bench's frames differ by 0.01-0.03 degrees and under
    0.1 mm), and a frame with few depth readings keeps all the finer sampling gives.
    The table and the napkin lying on it are one plane at
    this tolerance. A large object near the camera (a robot arm) can make the dominant
    plane something else, so a plane is taken for the table only if it faces the camera
    within ``max_tilt_deg`` (SPEC's cameras tilt up to 15 degrees; default 35 leaves room
    for wrinkled, folded cloth) and fewer than ``below_share`` of the samples lie more
    than ``below_mm`` beyond it (the table is the lowest surface; objects stand on it).
    Otherwise its samples are set aside and the fit is tried again. Deterministic.

    With lens distortion the sampled pixels are undistorted first, so that the plane is
    the true table, in the frame of the lifted stickers (:func:`lift_stickers`).

    Raises
    ------
    ValueError
        With fewer than 50 valid depth pixels.
    """
    if coarse_stride is not None and coarse_stride > stride:
        coarse = depth_mm[::coarse_stride, ::coarse_stride]
        if np.count_nonzero(coarse) >= min_coarse_samples:
            stride = coarse_stride
    sub = depth_mm[::stride, ::stride].astype(np.float64) * 1e-3
    valid = sub > 0
    z = sub[valid]
    if len(z) < 50:
        raise ValueError(f"only {len(z)} valid depth samples; cannot fit the table plane")
    rays = _sample_rays(intrinsics, sub.shape, stride)
    # (3, n): coordinates in rows, so that every reduction runs along contiguous memory;
    # the arithmetic of ``intrinsics.deproject`` of the undistorted pixels
    pts = np.empty((3, len(z)))
    np.multiply(rays[0][valid], z, out=pts[0])
    np.multiply(rays[1][valid], z, out=pts[1])
    pts[2] = z
    active = np.ones(pts.shape[1], dtype=bool)
    cos_tilt = np.cos(np.radians(max_tilt_deg))
    normal, centre, keep = _fit_plane(pts, active, iterations)
    for _ in range(3):
        if -normal[2] < cos_tilt:  # not facing the camera: an object's side
            rest = active & ~keep
        else:
            height = normal @ pts - normal @ centre
            rest = active & (height < -below_mm * 1e-3)
            if rest.sum() < max(50, below_share * active.sum()):
                break  # nothing much beyond it: the table
        if rest.sum() < 50:
            break
        active = rest
        normal, centre, keep = _fit_plane(pts, active, iterations)
    return normal, float(normal @ centre)
