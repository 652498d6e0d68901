"""What the capture conditions do to appearance and to the images: a wood table, an arm's
shadow, a glossy highlight, a large light's sheen (lobes and the strength that washes a
sticker to a given saturation), JPEG, lens distortion and a real sensor's depth.

The condition catalogue is :mod:`dgli_vision.sim.conditions`, which re-exports these names.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ..core.camera import Intrinsics, undistort_points

if TYPE_CHECKING:
    from .condition_params import Conditions

__all__ = [
    "apply_lens_distortion",
    "area_light_lobe",
    "highlight_spot",
    "jpeg_roundtrip",
    "mirror_light_direction",
    "realistic_depth",
    "shadow_factor",
    "sheen_sticker",
    "specular_for_saturation",
    "wood_albedo",
]


def wood_albedo(xy: NDArray[np.float64], seed: int) -> NDArray[np.float64]:
    """Linear-RGB albedo (n, 3) of a light-wood table at world points (n, 2) metres.

    sRGB about (205, 172, 135): HSV saturation about 0.3, with grain stripes.
    """
    rng = np.random.default_rng([seed, 13])
    base = np.array([0.61, 0.41, 0.24]) * rng.uniform(0.85, 1.1)
    ang = rng.uniform(0, np.pi)
    t = xy @ np.array([np.cos(ang), np.sin(ang)])
    s = xy @ np.array([-np.sin(ang), np.cos(ang)])
    grain = 0.1 * np.sin(2 * np.pi * t / 0.012 + 3 * np.sin(2 * np.pi * s / 0.3))
    grain += 0.05 * np.sin(2 * np.pi * t / 0.05)
    tint = 1 + grain[:, None] * np.array([0.6, 1.0, 1.6])
    return np.clip(base * tint, 0, 1)


def shadow_factor(xy: NDArray[np.float64], conditions: Conditions, centre: NDArray) -> NDArray:
    """Light left (n,) at world points (n, 2) under a soft arm shadow across the napkin."""
    rng = np.random.default_rng([conditions.seed, 17])
    ang = rng.uniform(0, np.pi)
    normal = np.array([-np.sin(ang), np.cos(ang)])
    offset = rng.uniform(-0.08, 0.08)
    half_width = rng.uniform(0.03, 0.075)
    soft = rng.uniform(0.015, 0.035)
    d = np.abs((xy - centre[:2]) @ normal - offset)
    inside = np.clip((half_width + soft - d) / (2 * soft), 0, 1)
    inside = inside * inside * (3 - 2 * inside)  # smoothstep
    return 1.0 - conditions.shadow * inside


def highlight_spot(conditions: Conditions, sticker_uv: NDArray, visible: NDArray):
    """Material centre (2,) mm and sigma (mm) and peak of the mirror highlight, or None."""
    rng = np.random.default_rng([conditions.seed, 19])
    ids = np.flatnonzero(visible)
    if not conditions.highlight or ids.size == 0:
        return None
    sid = int(rng.choice(ids))
    r = rng.uniform(0, 10.0)
    a = rng.uniform(0, 2 * np.pi)
    centre = sticker_uv[sid] + r * np.array([np.cos(a), np.sin(a)])
    return centre, float(rng.uniform(2.0, 5.0)), float(rng.uniform(1.5, 5.0)), sid


def sheen_sticker(conditions: Conditions, visible: NDArray) -> int | None:
    """Id of the sticker the large light is mirrored in (one the camera sees), or None."""
    ids = np.flatnonzero(visible)
    if conditions.sheen is None or ids.size == 0:
        return None
    return int(np.random.default_rng([conditions.seed, 29]).choice(ids))


def mirror_light_direction(normal: NDArray, view: NDArray) -> NDArray[np.float64]:
    """Unit direction (3,) towards a light whose mirror reflection at a surface of unit
    ``normal`` reaches the viewer in unit direction ``view`` (both from the surface)."""
    n = normal if normal @ view >= 0 else -normal
    light = 2 * (n @ view) * n - view
    return light / np.linalg.norm(light)


def area_light_lobe(
    normals: NDArray,
    views: NDArray,
    light: NDArray,
    radius_rad: float,
    shininess: float,
) -> NDArray[np.float64]:
    """Blinn-Phong specular lobe (n,) in [0, 1] of a disc-shaped area light.

    The light is a disc of angular radius ``radius_rad`` around the unit direction
    ``light``. Each surface point takes the point of the disc nearest its mirror
    direction (the *representative point* of area lights): inside the disc's mirror
    image the lobe is full (1), outside it falls off as ``(n . h) ** shininess`` with the
    half-vector ``h`` between that point and the view.

    Parameters
    ----------
    normals, views : ndarray, shape (n, 3)
        Unit surface normals (either side) and unit directions from the surface to the
        camera.
    """
    n = normals * np.where((normals * views).sum(axis=1) < 0, -1.0, 1.0)[:, None]
    mirror = 2 * (n * views).sum(axis=1)[:, None] * n - views
    cos_off = np.clip(mirror @ light, -1.0, 1.0)
    across = mirror - cos_off[:, None] * light
    norm = np.linalg.norm(across, axis=1)
    across = across / np.maximum(norm, 1e-12)[:, None]
    inside = np.arccos(cos_off) <= radius_rad
    nearest = np.cos(radius_rad) * light + np.sin(radius_rad) * across
    to_light = np.where(inside[:, None], mirror, nearest)
    half = to_light + views
    half /= np.maximum(np.linalg.norm(half, axis=1), 1e-12)[:, None]
    return np.clip((n * half).sum(axis=1), 0.0, 1.0) ** shininess


def specular_for_saturation(
    diffuse: NDArray, saturation: float, *, tint: NDArray | None = None, peak: float = 0.8
) -> float:
    """Grey specular light (linear) that, added to a surface's ``diffuse`` linear RGB (3,),
    leaves it with this HSV ``saturation`` in sRGB (bisection; 0 if already paler).

    ``tint`` (3,) multiplies the added light, as a camera's channel gains do. The sum is
    judged as exposed with its brightest channel at ``peak`` (linear): an exposure that
    keeps it from clipping."""
    from ..core.colour import linear_to_srgb

    grey = np.ones(3) if tint is None else np.asarray(tint, np.float64)

    def sat(extra: float) -> float:
        lin = np.asarray(diffuse, np.float64) + extra * grey
        v = linear_to_srgb(lin * (peak / max(float(lin.max()), 1e-12)))
        return float(1 - v.min() / max(v.max(), 1e-12))

    if sat(0.0) <= saturation:
        return 0.0
    lo, hi = 0.0, 1.0
    while sat(hi) > saturation:
        hi *= 2
    for _ in range(40):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if sat(mid) > saturation else (lo, mid)
    return (lo + hi) / 2


# --- image effects ---------------------------------------------------------------------


def jpeg_roundtrip(rgb: NDArray[np.uint8], quality: int) -> NDArray[np.uint8]:
    """The RGB image as a JPEG of ``quality`` would decode."""
    import cv2

    ok, buf = cv2.imencode(".jpg", rgb[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:  # pragma: no cover - OpenCV always encodes uint8 RGB
        raise RuntimeError("JPEG encoding failed")
    return cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1].copy()


def apply_lens_distortion(
    color: NDArray[np.uint8],
    depth_mm: NDArray[np.uint16],
    intrinsics: Intrinsics,
    coefficients: float | Sequence[float],
) -> tuple[NDArray[np.uint8], NDArray[np.uint16]]:
    """Images as seen through a lens with distortion (OpenCV's model).

    Each output (distorted) pixel takes the value of the ideal pinhole image at its
    undistorted position (OpenCV's ``undistortPoints`` with ``P = K``), colour
    bilinearly, depth from the nearest pixel.

    Parameters
    ----------
    color, depth_mm : ndarray
        The ideal pinhole images.
    intrinsics : Intrinsics
        Its camera matrix is used (its own ``distortion`` is not).
    coefficients : float or sequence of float
        ``k1`` alone (radial), or OpenCV's ``(k1, k2, p1, p2[, k3...])``.
    """
    import cv2

    if np.ndim(coefficients) == 0:
        coefficients = (float(coefficients),)
    d = [float(c) for c in coefficients]
    n = next((k for k in (4, 5, 8, 12, 14) if k >= len(d)), len(d))
    dist = np.array(d + [0.0] * (n - len(d)), np.float64)
    h, w = depth_mm.shape
    vv, uu = np.mgrid[0:h, 0:w].astype(np.float32)
    pts = np.stack([uu.ravel(), vv.ravel()], 1)[:, None, :]
    k = intrinsics.matrix()
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 20, 1e-6)
    und = undistort_points(pts, k, dist, criteria)
    mx = und[:, 0, 0].reshape(h, w).astype(np.float32)
    my = und[:, 0, 1].reshape(h, w).astype(np.float32)
    color = cv2.remap(color, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    depth = cv2.remap(depth_mm, mx, my, cv2.INTER_NEAREST, borderValue=0)
    return color, depth


def realistic_depth(
    depth_mm: NDArray[np.float64],
    conditions: Conditions,
    rng: np.random.Generator,
) -> NDArray[np.float64]:
    """Flying pixels and parallax holes at depth edges, and the registration offset.

    Parameters
    ----------
    depth_mm : ndarray, shape (H, W)
        Ideal z-depth, mm (0 = none).

    Returns
    -------
    ndarray, shape (H, W)
        Depth in mm, 0 where there is no reading.
    """
    import cv2

    d = depth_mm.copy()
    valid = d > 0
    # Flying pixels: at a jump, a pixel reads a mix of the two sides.
    near = cv2.erode(np.where(valid, d, 1e9).astype(np.float32), np.ones((3, 3), np.uint8))
    far = cv2.dilate(d.astype(np.float32), np.ones((3, 3), np.uint8))
    edge = valid & ((far - near) > 15)
    mix = rng.random(d.shape)
    fly = edge & (rng.random(d.shape) < 0.6)
    d[fly] = (near * mix + far * (1 - mix))[fly]
    # Parallax holes: the projector sits to one side, so the far side of each jump
    # facing it sees no pattern for a few pixels.
    jump = np.zeros(d.shape, bool)
    jump[:, 1:] = (d[:, :-1] - d[:, 1:]) < -15  # far pixel right of a near one
    width = int(rng.integers(2, 7))
    shadow = cv2.dilate(jump.astype(np.uint8), np.ones((1, width), np.uint8), anchor=(0, 0))
    d[shadow.astype(bool)] = 0
    du, dv = conditions.registration_px
    d = np.roll(d, (dv, du), axis=(0, 1))
    if dv > 0:
        d[:dv] = 0
    elif dv < 0:
        d[dv:] = 0
    if du > 0:
        d[:, :du] = 0
    elif du < 0:
        d[:, du:] = 0
    return d
