"""Pinhole intrinsics and camera poses.

Conventions, stated once:

* Camera frame: x right, y down, z forward (OpenCV). World frame: z up, table at z = 0.
* Pixel ``(u, v)`` integer indices name pixel *centres* (OpenCV): the ray of pixel
  ``(u, v)`` has direction ``((u - cx) / fx, (v - cy) / fy, 1)`` in the camera frame, so
  that SPEC's ``cx = 639.5`` is the middle of a 1280-pixel row. Rendering and
  deprojection both use this convention (the round trip is tested).
* Depth is z in the camera frame (not the distance along the ray).
* Lens distortion follows OpenCV's model (``k1, k2, p1, p2[, k3...]``). Images are used
  as recorded (distorted): :meth:`Intrinsics.project` gives the pixel where a point is
  *seen*, distortion included; :meth:`Intrinsics.deproject` and
  :meth:`Intrinsics.ray_directions` are the plain pinhole model of the pixels as they are.
  :meth:`Intrinsics.undistort_pixels` gives the ideal pinhole pixel of a seen one, so that
  ``deproject(undistort_pixels(px), z)`` is the true point.
* Open3D's intrinsics JSON stores ``intrinsic_matrix`` column by column.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import InvalidValueError

__all__ = [
    "DEFAULT_INTRINSICS",
    "DISTORTION_LENGTHS",
    "CameraPose",
    "Intrinsics",
    "look_at_table",
    "undistort_points",
]


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole camera intrinsics (pixels), with optional lens distortion.

    Attributes
    ----------
    width, height : int
        Image size in pixels.
    fx, fy : float
        Focal lengths in pixels.
    cx, cy : float
        Principal point in pixels (pixel-centre convention, see module docstring).
    distortion : tuple of float
        OpenCV's distortion coefficients ``(k1, k2, p1, p2[, k3[, k4, k5, k6]])``;
        empty (the default) or all zero for an ideal pinhole.
    mirrored : bool or None
        The camera's declared handedness (``"mirrored"`` in an intrinsics file, written
        by ``dgli calibrate``): True for a camera that mirrors its image left to right,
        False for one that does not, None when not declared (then taken as not mirrored:
        :func:`dgli_vision.core.handedness.camera_mirroring`).
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    distortion: tuple[float, ...] = ()
    mirrored: bool | None = None

    @property
    def distorted(self) -> bool:
        """True when any distortion coefficient is non-zero."""
        return any(c != 0.0 for c in self.distortion)

    def matrix(self) -> NDArray[np.float64]:
        """The 3 x 3 camera matrix K."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def to_open3d_dict(self) -> dict[str, object]:
        """Open3D ``PinholeCameraIntrinsic`` JSON (matrix stored column-major).

        A lens with distortion adds ``"distortion": [k1, k2, p1, p2, k3...]``, and a
        declared handedness ``"mirrored": true|false``: keys Open3D ignores (the file
        stays loadable there)."""
        out: dict[str, object] = {
            "width": self.width,
            "height": self.height,
            "intrinsic_matrix": [self.fx, 0.0, 0.0, 0.0, self.fy, 0.0, self.cx, self.cy, 1.0],
        }
        if self.distorted:
            out["distortion"] = [float(c) for c in self.distortion]
        if self.mirrored is not None:
            out["mirrored"] = bool(self.mirrored)
        return out

    def ray_directions(self) -> NDArray[np.float64]:
        """Camera-frame ray directions (H, W, 3) through pixel centres, z = 1."""
        u = (np.arange(self.width) - self.cx) / self.fx
        v = (np.arange(self.height) - self.cy) / self.fy
        d = np.empty((self.height, self.width, 3))
        d[..., 0] = u[None, :]
        d[..., 1] = v[:, None]
        d[..., 2] = 1.0
        return d

    def project(self, points_cam: ArrayLike) -> NDArray[np.float64]:
        """Pixel coordinates (n, 2) where camera-frame points (n, 3) are seen.

        With lens distortion, the pinhole pixel is distorted (:meth:`distort_pixels`), so
        that the pixel is where the point appears in the recorded image."""
        p = np.asarray(points_cam, dtype=np.float64)
        px = np.stack(
            [self.fx * p[:, 0] / p[:, 2] + self.cx, self.fy * p[:, 1] / p[:, 2] + self.cy], 1
        )
        return self.distort_pixels(px) if self.distorted else px

    def undistort_pixels(self, pixels: ArrayLike) -> NDArray[np.float64]:
        """Ideal pinhole pixels (n, 2) of pixels (n, 2) of the distorted image.

        OpenCV's ``undistortPoints`` with ``P = K``; iterated to a thousandth of a pixel.
        The pixels are returned unchanged (as floats) for an ideal lens.
        """
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        if not self.distorted or not len(px):
            return px.copy()

        k = self.matrix()
        out = undistort_points(px[:, None, :], k, self._coefficients(), _UNDISTORT_CRITERIA)
        return out.reshape(-1, 2).astype(np.float64)

    def distort_pixels(self, pixels: ArrayLike) -> NDArray[np.float64]:
        """Pixels (n, 2) of the distorted image where ideal pinhole pixels (n, 2) are seen
        (OpenCV's ``projectPoints``); the inverse of :meth:`undistort_pixels`."""
        px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
        if not self.distorted or not len(px):
            return px.copy()
        import cv2

        norm = np.column_stack(
            [(px[:, 0] - self.cx) / self.fx, (px[:, 1] - self.cy) / self.fy, np.ones(len(px))]
        )
        out, _ = cv2.projectPoints(
            norm, np.zeros(3), np.zeros(3), self.matrix(), self._coefficients()
        )
        return out.reshape(-1, 2).astype(np.float64)

    def _coefficients(self) -> NDArray[np.float64]:
        """The distortion coefficients as OpenCV wants them (padded to 4 or 5 numbers)."""
        d = list(self.distortion)
        n = next((k for k in DISTORTION_LENGTHS if k >= len(d)), len(d))
        return np.array(d + [0.0] * (n - len(d)), dtype=np.float64)

    def deproject(self, pixels: ArrayLike, depth_m: ArrayLike) -> NDArray[np.float64]:
        """Camera-frame points (n, 3) of pixels (n, 2) at z-depths (n,) in metres."""
        px = np.asarray(pixels, dtype=np.float64)
        z = np.asarray(depth_m, dtype=np.float64)
        return np.stack(
            [(px[:, 0] - self.cx) / self.fx * z, (px[:, 1] - self.cy) / self.fy * z, z], 1
        )


#: Iterations of the inverse distortion: 40 or until it moves less than 1e-6 (normalised).
_UNDISTORT_CRITERIA = (3, 40, 1e-6)  # cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS


def undistort_points(
    points: NDArray, matrix: NDArray, coefficients: NDArray, criteria: tuple[int, int, float]
) -> NDArray:
    """OpenCV's ``undistortPoints`` with ``P = K``, iterated until ``criteria``.

    OpenCV 4 offers the iteration as ``undistortPointsIter``; OpenCV 5 dropped that name
    and takes ``criteria`` in ``undistortPoints``. Both give the same points.

    Parameters
    ----------
    points : ndarray, shape (n, 1, 2)
        Pixels of the distorted image.
    matrix : ndarray, shape (3, 3)
        Camera matrix.
    coefficients : ndarray
        OpenCV's distortion coefficients.
    criteria : tuple
        OpenCV's termination criteria (type, count, eps).

    Returns
    -------
    ndarray, shape (n, 1, 2)
        The ideal pinhole pixels.
    """
    import cv2

    if hasattr(cv2, "undistortPointsIter"):
        return cv2.undistortPointsIter(points, matrix, coefficients, None, matrix, criteria)
    return cv2.undistortPoints(points, matrix, coefficients, P=matrix, criteria=criteria)


#: Lengths of OpenCV's distortion vectors.
DISTORTION_LENGTHS = (4, 5, 8, 12, 14)


#: SPEC section 4's default: a nominal Azure Kinect DK colour camera at 1280 x 720.
DEFAULT_INTRINSICS = Intrinsics(1280, 720, 605.0, 605.0, 639.5, 359.5)


@dataclass(frozen=True)
class CameraPose:
    """Where the camera is: ``x_world = rotation @ x_cam + position``.

    Attributes
    ----------
    rotation : ndarray, shape (3, 3)
        World-from-camera rotation (columns: camera axes in the world).
    position : ndarray, shape (3,)
        Camera centre in the world, metres.
    """

    rotation: NDArray[np.float64]
    position: NDArray[np.float64]

    def world_to_camera(self, points: ArrayLike) -> NDArray[np.float64]:
        """Camera-frame coordinates (n, 3) of world points (n, 3)."""
        return (np.asarray(points, dtype=np.float64) - self.position) @ self.rotation

    def camera_to_world(self, points: ArrayLike) -> NDArray[np.float64]:
        """World coordinates (n, 3) of camera-frame points (n, 3)."""
        return np.asarray(points, dtype=np.float64) @ self.rotation.T + self.position

    def to_json(self) -> dict[str, list]:
        """JSON-ready form (world-from-camera rotation, rows; position in metres)."""
        return {
            "rotation": self.rotation.round(9).tolist(),
            "position_m": self.position.round(9).tolist(),
        }


def look_at_table(
    height_m: float,
    *,
    tilt_rad: float = 0.0,
    tilt_direction_rad: float = 0.0,
    yaw_rad: float = 0.0,
    target: ArrayLike = (0.0, 0.0, 0.0),
) -> CameraPose:
    """A camera ``height_m`` above the table whose optical axis hits ``target``.

    With no tilt it looks straight down, image x along world x rotated by ``yaw_rad``.
    ``tilt_rad`` tips the optical axis away from the vertical towards the azimuth
    ``tilt_direction_rad``; the camera then stands off to the side so that the axis
    still meets ``target``.
    """
    if height_m <= 0:
        raise InvalidValueError(f"height_m must be positive, got {height_m}")
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    x_axis = np.array([c, s, 0.0])
    forward = np.array([0.0, 0.0, -1.0])
    if tilt_rad:
        # Tip the forward axis: it points down and towards the target from the side.
        az = np.array([np.cos(tilt_direction_rad), np.sin(tilt_direction_rad), 0.0])
        forward = np.cos(tilt_rad) * np.array([0.0, 0.0, -1.0]) + np.sin(tilt_rad) * az
        x_axis = x_axis - (x_axis @ forward) * forward
        x_axis /= np.linalg.norm(x_axis)
    y_axis = np.cross(forward, x_axis)
    rot = np.stack([x_axis, y_axis, forward], axis=1)
    position = np.asarray(target, dtype=np.float64) - forward * (height_m / np.cos(tilt_rad))
    return CameraPose(rot, position)
