"""The look of a photograph, for the rasteriser's ``photo`` condition.

A real camera in a real room sees what flat shading never gives: a lamp at a finite
distance whose light falls off across the napkin (inverse square and the angle of
incidence), a second light of another colour temperature (so the white balance varies
across the image), a woven fabric's broad sheen and a laminate's glossy lobe on the
stickers, vignetting, auto exposure and auto white balance that meter the whole frame,
and a sensor with a colour mosaic that the camera demosaics. Everything here works in
linear light on flat arrays of the rendered pixels (``n = H * W``) or on the image.

The parameters are drawn by :func:`draw_photo` from the condition's generator; they are
ours, chosen to cover what the path-traced renders and real cameras show, not tuned to
any held-out set.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "Photo",
    "auto_exposed",
    "draw_photo",
    "kelvin_rgb",
    "mosaic_demosaic",
    "photo_light",
    "vignetting",
]


@dataclass(frozen=True)
class Photo:
    """A room's light and a consumer camera's pipeline (the ``photo`` condition).

    Attributes
    ----------
    lamp_offset_m : tuple of float
        The key lamp's position relative to the napkin's centre (x, y, height), metres.
    lamp_kelvin, fill_kelvin : float
        Colour temperatures of the key lamp and of the room's fill light, kelvin.
    fill : float
        The fill light's share of the light at the napkin's centre (0-1).
    sheen : float
        Peak of the fabric's broad sheen (linear light, relative to the napkin's white).
    sheen_shininess : float
        Blinn-Phong exponent of the fabric's sheen.
    gloss : float
        Peak of the stickers' laminate reflection of the lamp (linear light).
    gloss_shininess : float
        Blinn-Phong exponent of the laminate.
    laminate : float
        The room's light mirrored in the stickers' clear laminate at normal incidence
        (linear light; it grows towards grazing angles as Fresnel's law has it): the
        stickers' colours are paler than printed.
    blur_px : float
        Gaussian sigma of the lens and the sensor's anti-aliasing filter, pixels.
    vignetting : float
        Fraction of the light lost at the image's corners (cos^4-like fall-off).
    exposure_level : float
        8-bit level auto exposure puts the frame's 99.5th brightness percentile at.
    white_error : tuple of float
        Residual per-channel gains after auto white balance.
    """

    lamp_offset_m: tuple[float, float, float]
    lamp_kelvin: float
    fill_kelvin: float
    fill: float
    sheen: float
    sheen_shininess: float
    gloss: float
    gloss_shininess: float
    laminate: float
    blur_px: float
    vignetting: float
    exposure_level: float
    white_error: tuple[float, float, float]


def draw_photo(rng: np.random.Generator) -> Photo:
    """Draw a room's light and a camera's pipeline.

    Parameters
    ----------
    rng : Generator

    Returns
    -------
    Photo
        The key lamp 0.25-0.8 m to the side and 0.6-1.4 m up (fall-off of 1.2-2x
        across the napkin), 2,700-6,500 K; a fill light of 4,000-6,500 K giving 15-45%
        of the light; a fabric sheen of 0.04-0.15, a laminate lobe of 0.3-1.2 and the
        room mirrored in the laminate at 0.02-0.08; a blur of 0.8-1.6 px; vignetting of
        15-40%; auto exposure to 215-245 and a white balance within 8%.
    """
    angle = rng.uniform(0, 2 * np.pi)
    side = rng.uniform(0.25, 0.8)
    offset = (side * np.cos(angle), side * np.sin(angle), rng.uniform(0.6, 1.4))
    return Photo(
        lamp_offset_m=tuple(float(v) for v in offset),
        lamp_kelvin=float(rng.uniform(2700, 6500)),
        fill_kelvin=float(rng.uniform(4000, 6500)),
        fill=float(rng.uniform(0.15, 0.45)),
        sheen=float(rng.uniform(0.04, 0.15)),
        sheen_shininess=float(rng.uniform(8, 30)),
        gloss=float(rng.uniform(0.3, 1.2)),
        gloss_shininess=float(rng.uniform(150, 600)),
        laminate=float(rng.uniform(0.02, 0.08)),
        blur_px=float(rng.uniform(0.8, 1.6)),
        vignetting=float(rng.uniform(0.15, 0.4)),
        exposure_level=float(rng.uniform(215, 245)),
        white_error=tuple(float(g) for g in 1 + rng.uniform(-0.08, 0.08, 3)),
    )


def kelvin_rgb(kelvin: float) -> NDArray[np.float64]:
    """Linear RGB (3,) of a black body at ``kelvin``, normalised to green 1.

    Tanner Helland's fit of the Planckian locus in sRGB, taken to linear light; good to a
    few percent between 1,000 and 40,000 K, which is all a light's tint needs here.
    """
    t = kelvin / 100.0
    r = 255.0 if t <= 66 else 329.698727446 * (t - 60) ** -0.1332047592
    g = (
        99.4708025861 * np.log(t) - 161.1195681661
        if t <= 66
        else 288.1221695283 * (t - 60) ** -0.0755148492
    )
    b = (
        255.0
        if t >= 66
        else (0.0 if t <= 19 else 138.5177312231 * np.log(t - 10) - 305.0447927307)
    )
    srgb = np.clip(np.array([r, g, b]) / 255.0, 1e-3, 1.0)
    lin = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
    return lin / lin[1]


def photo_light(
    photo: Photo,
    points: NDArray[np.float64],
    normals: NDArray[np.float64],
    view_dirs: NDArray[np.float64],
    centre: NDArray[np.float64],
) -> tuple[NDArray[np.float64], ...]:
    """The light on every surface point: diffuse irradiance and the two specular lobes.

    Parameters
    ----------
    photo : Photo
    points : ndarray, shape (n, 3)
        World points (metres).
    normals : ndarray, shape (n, 3)
        Unit surface normals (either side: cloth is two-sided).
    view_dirs : ndarray, shape (n, 3)
        Unit directions from the points towards the camera.
    centre : ndarray, shape (3,)
        The napkin's centre, where the key lamp's irradiance is 1.

    Returns
    -------
    diffuse : ndarray, shape (n, 3)
        Irradiance times the lights' colours (multiply by albedo).
    sheen, gloss : ndarray, shape (n,)
        Blinn-Phong lobes of the lamp (multiply by ``photo.sheen`` / ``photo.gloss`` and
        the lamp's colour).
    mirrored : ndarray, shape (n,)
        Schlick's Fresnel factor of the view angle, 1 at normal incidence (multiply by
        ``photo.laminate`` and the fill light's colour).
    """
    lamp = centre + np.asarray(photo.lamp_offset_m)
    to_lamp = lamp - points
    dist2 = np.einsum("ij,ij->i", to_lamp, to_lamp)
    to_lamp /= np.sqrt(dist2)[:, None]
    # face the normals towards the camera (two-sided cloth)
    facing = np.sign(np.einsum("ij,ij->i", normals, view_dirs))
    facing[facing == 0] = 1.0
    n = normals * facing[:, None]
    cos_in = np.clip(np.einsum("ij,ij->i", n, to_lamp), 0.0, None)
    centre_to_lamp = np.asarray(photo.lamp_offset_m)
    d0 = float(centre_to_lamp @ centre_to_lamp)
    cos0 = centre_to_lamp[2] / np.sqrt(d0)
    key = cos_in * (d0 / dist2) / cos0  # 1 at the napkin's centre
    lamp_rgb, fill_rgb = kelvin_rgb(photo.lamp_kelvin), kelvin_rgb(photo.fill_kelvin)
    diffuse = (1 - photo.fill) * key[:, None] * lamp_rgb + photo.fill * fill_rgb
    half = to_lamp + view_dirs
    half /= np.maximum(np.linalg.norm(half, axis=1), 1e-12)[:, None]
    cos_h = np.clip(np.einsum("ij,ij->i", n, half), 0.0, None) * (cos_in > 0)
    sheen = cos_h**photo.sheen_shininess * (d0 / dist2)
    gloss = cos_h**photo.gloss_shininess * (d0 / dist2)
    cos_v = np.clip(np.einsum("ij,ij->i", n, view_dirs), 0.0, 1.0)
    mirrored = 1.0 + 24.0 * (1.0 - cos_v) ** 5  # (F0 0.04: 1 at normal incidence, 25 grazing)
    return diffuse, sheen, gloss, mirrored


def vignetting(shape: tuple[int, int], strength: float) -> NDArray[np.float64]:
    """Gain (H, W) of a lens's vignetting: 1 at the centre, ``1 - strength`` at the
    corners, falling as cos^4 of an equivalent field angle."""
    h, w = shape
    y, x = np.mgrid[0:h, 0:w]
    r2 = ((x - (w - 1) / 2) ** 2 + (y - (h - 1) / 2) ** 2) / (
        ((w - 1) / 2) ** 2 + ((h - 1) / 2) ** 2
    )
    # cos^4(theta) with tan^2(theta) = r2 * k, k chosen so the corner reaches 1 - strength
    k = (1 - strength) ** -0.5 - 1
    return 1.0 / (1.0 + k * r2) ** 2


def auto_exposed(linear: NDArray[np.float64], photo: Photo) -> NDArray[np.float64]:
    """Linear RGB (H, W, 3) through auto white balance and auto exposure.

    White balance: the brightest 2% of pixels (the napkin, a white patch) are taken as
    white, then the residual error ``photo.white_error`` stays. Exposure: the 99.5th
    percentile of brightness lands at ``photo.exposure_level`` (8-bit sRGB).
    """
    flat = linear.reshape(-1, 3)
    lum = flat.mean(axis=1)
    bright = flat[lum >= np.quantile(lum, 0.98)]
    white = np.maximum(bright.mean(axis=0), 1e-6)
    balanced = flat * (white[1] / white) * np.asarray(photo.white_error)
    top = float(np.quantile(balanced.max(axis=1), 0.995))
    level = photo.exposure_level / 255.0
    target = ((level + 0.055) / 1.055) ** 2.4  # the level in linear light
    return (balanced * (target / max(top, 1e-9))).reshape(linear.shape)


def mosaic_demosaic(
    linear: NDArray[np.float64], rng: np.random.Generator, read_noise: float = 0.002
) -> NDArray[np.float64]:
    """Linear RGB (H, W, 3) sampled through an RGGB colour mosaic with shot and read
    noise at 12 bits, then demosaiced as a camera's ISP does (OpenCV's edge-aware
    Bayer interpolation)."""
    import cv2

    h, w, _ = linear.shape
    raw = np.empty((h, w))
    raw[0::2, 0::2] = linear[0::2, 0::2, 0]  # R
    raw[0::2, 1::2] = linear[0::2, 1::2, 1]  # G
    raw[1::2, 0::2] = linear[1::2, 0::2, 1]  # G
    raw[1::2, 1::2] = linear[1::2, 1::2, 2]  # B
    full = 4095.0
    electrons = np.clip(raw, 0, 1) * full
    noisy = electrons + rng.normal(0, 1, raw.shape) * np.sqrt(
        electrons * 0.5 + (read_noise * full) ** 2
    )
    codes = np.clip(np.rint(noisy), 0, full).astype(np.uint16)
    # OpenCV names the pattern by the 2x2 block starting at the second row and column
    # (its BayerBG is an RGGB sensor); the output order follows the conversion's name.
    rgb = cv2.cvtColor(codes, cv2.COLOR_BayerBG2RGB_EA)
    return rgb.astype(np.float64) / full
