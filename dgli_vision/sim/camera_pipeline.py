"""What a real RGB-D camera makes of the light a path tracer computes: the colour camera's
pipeline (auto exposure, vignetting, a Bayer mosaic with shot and read noise, an imperfect
white balance, demosaicing, sRGB encoding to 8 bits) and a time-of-flight depth model
(noise growing with distance, flying pixels at depth edges, holes where a glossy surface
mirrors the emitter back or the surface is seen edge-on).

Used by :mod:`dgli_vision.sim.cycles_scene` on Cycles' linear output; plain numpy and
OpenCV, every random draw from the generator given.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..core.colour import linear_to_srgb

__all__ = [
    "CameraModel",
    "ToFModel",
    "bayer_mosaic",
    "blackbody_rgb",
    "colour_camera",
    "demosaic",
    "tof_depth",
]

#: OpenCV's name of the conversion that demosaics our R G / G B (RGGB) mosaic into RGB.
#: OpenCV names Bayer patterns by the second row's second and third pixels, so RGGB is
#: its "BG" pattern (checked by tests/test_cycles.py on a flat colour).
_DEMOSAIC_RGGB = "COLOR_BayerBG2RGB_EA"


@dataclass(frozen=True)
class CameraModel:
    """The colour camera's pipeline; ``CameraModel(ideal=True)`` only exposes and encodes.

    Attributes
    ----------
    ideal : bool
        Exposure from the scene's white, no vignetting, mosaic, noise or white-balance
        error (for geometry checks).
    exposure_target : tuple of float
        Range of the centre-weighted mean linear level auto exposure aims at.
    highlight_quantile : float
        Auto exposure never lets more than this share of the centre pixels clip.
    vignetting : tuple of float
        Range of the light lost in the image corners (0.25: a quarter).
    full_well_e : float
        Electrons at the sensor's white: shot noise is Poisson in them.
    read_noise_e : float
        Read noise, electrons (standard deviation).
    adc_bits : int
        The raw values' bits.
    white_balance_error : float
        Relative error of each channel's white-balance gain (uniform in +-).
    white_balance_strength : tuple of float
        How much of the estimated colour cast the camera removes (1: all of it).
    blur_sigma_px : tuple of float
        Range of the lens's blur, pixels (Gaussian, before the mosaic).
    """

    ideal: bool = False
    exposure_target: tuple[float, float] = (0.16, 0.26)
    highlight_quantile: float = 0.995
    vignetting: tuple[float, float] = (0.15, 0.40)
    full_well_e: float = 6000.0
    read_noise_e: float = 4.0
    adc_bits: int = 12
    white_balance_error: float = 0.06
    white_balance_strength: tuple[float, float] = (0.7, 1.0)
    blur_sigma_px: tuple[float, float] = (0.3, 0.7)


@dataclass(frozen=True)
class ToFModel:
    """The time-of-flight depth camera, registered to the colour camera.

    Attributes
    ----------
    ideal : bool
        Exact z-depth rounded to mm (for geometry checks).
    noise_mm : float
        Noise at 1 m, mm; grows with the square of the distance (0.5 mm floor).
    edge_jump_mm : float
        A depth jump larger than this between neighbours makes an edge.
    flying_pixel : float
        Share of edge pixels that read a mix of the near and the far depth.
    edge_dropout : float
        Share of edge pixels that read nothing.
    specular_cone_deg : float
        A glossy surface whose normal is within this angle of the direction to the camera
        mirrors the emitter into the sensor: it saturates and reads nothing.
    grazing_cos : float
        Surfaces seen more edge-on than this (cosine of the angle to their normal) return
        too little light: no reading.
    random_dropout : float
        Share of all pixels that read nothing.
    """

    ideal: bool = False
    noise_mm: float = 3.0
    edge_jump_mm: float = 12.0
    flying_pixel: float = 0.5
    edge_dropout: float = 0.3
    specular_cone_deg: float = 8.0
    grazing_cos: float = 0.12
    random_dropout: float = 0.002


# --- light colour ------------------------------------------------------------------------


def _cie_xyz(lam_nm: NDArray[np.float64]) -> NDArray[np.float64]:
    """CIE 1931 colour matching functions (n, 3), the multi-lobe Gaussian fit of Wyman,
    Sloan and Shirley (2013)."""

    def g(x: NDArray, mu: float, s1: float, s2: float) -> NDArray:
        return np.exp(-0.5 * ((x - mu) / np.where(x < mu, s1, s2)) ** 2)

    x = (
        1.056 * g(lam_nm, 599.8, 37.9, 31.0)
        + 0.362 * g(lam_nm, 442.0, 16.0, 26.7)
        - 0.065 * g(lam_nm, 501.1, 20.4, 26.2)
    )
    y = 0.821 * g(lam_nm, 568.8, 46.9, 40.5) + 0.286 * g(lam_nm, 530.9, 16.3, 31.1)
    z = 1.217 * g(lam_nm, 437.0, 11.8, 36.0) + 0.681 * g(lam_nm, 459.0, 26.0, 13.8)
    return np.stack([x, y, z], axis=1)


_XYZ_TO_LINEAR_SRGB = np.array(
    [[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.2040, 1.0570]]
)


def blackbody_rgb(kelvin: float) -> tuple[float, float, float]:
    """The linear sRGB colour of a black body at ``kelvin`` (Planck's law through the CIE
    1931 observer), scaled to luminance 1; about (1, 1, 1) at 6,500 K."""
    lam = np.arange(380.0, 781.0, 5.0)
    m = lam * 1e-9
    planck = 1.0 / (m**5 * (np.exp(1.4388e-2 / (m * kelvin)) - 1.0))
    xyz = (_cie_xyz(lam) * planck[:, None]).sum(axis=0)
    rgb = np.clip(_XYZ_TO_LINEAR_SRGB @ (xyz / xyz[1]), 1e-4, None)
    rgb = rgb / (rgb @ np.array([0.2126, 0.7152, 0.0722]))
    return float(rgb[0]), float(rgb[1]), float(rgb[2])


# --- the colour camera -------------------------------------------------------------------


def bayer_mosaic(rgb: NDArray[np.float64]) -> NDArray[np.float64]:
    """The raw image (H, W) an RGGB colour filter array leaves of an RGB image (H, W, 3):
    red at even rows and columns, blue at odd ones, green elsewhere."""
    raw = np.empty(rgb.shape[:2], rgb.dtype)
    raw[0::2, 0::2] = rgb[0::2, 0::2, 0]
    raw[0::2, 1::2] = rgb[0::2, 1::2, 1]
    raw[1::2, 0::2] = rgb[1::2, 0::2, 1]
    raw[1::2, 1::2] = rgb[1::2, 1::2, 2]
    return raw


def _mosaic_gains(gains: NDArray, shape: tuple[int, int]) -> NDArray[np.float64]:
    """Per-channel gains (3,) laid out as the RGGB mosaic (H, W)."""
    g = np.empty(shape)
    g[0::2, 0::2], g[1::2, 1::2] = gains[0], gains[2]
    g[0::2, 1::2] = g[1::2, 0::2] = gains[1]
    return g


def demosaic(raw: NDArray[np.uint16]) -> NDArray[np.uint16]:
    """RGB (H, W, 3) of an RGGB mosaic (H, W) by OpenCV's edge-aware demosaicing."""
    import cv2

    return cv2.cvtColor(raw, getattr(cv2, _DEMOSAIC_RGGB))


def _auto_exposure(
    lum: NDArray[np.float64], target: float, quantile: float
) -> float:
    """The gain auto exposure applies: the centre-weighted mean level to ``target``, but
    never so much that more than ``1 - quantile`` of the centre half clips."""
    h, w = lum.shape
    y, x = np.mgrid[0:h, 0:w]
    r2 = ((x - w / 2) / (w / 2)) ** 2 + ((y - h / 2) / (h / 2)) ** 2
    weight = np.exp(-r2 / 0.5)
    mean = float((lum * weight).sum() / weight.sum())
    centre = lum[h // 4 : 3 * h // 4, w // 4 : 3 * w // 4]
    bright = float(np.quantile(centre, quantile))
    return min(target / max(mean, 1e-9), 1.0 / max(bright, 1e-9))


def _grey_world_gains(raw_rgb: NDArray[np.float64]) -> NDArray[np.float64]:
    """White-balance gains (3,) that make the bright, unsaturated part of the image grey
    (the napkin, most often): the mean colour of its pixels between the 60th and the 99th
    percentile of brightness, green kept."""
    lum = raw_rgb.mean(axis=2)
    lo, hi = np.quantile(lum, [0.6, 0.99])
    sel = (lum >= lo) & (lum <= hi)
    mean = raw_rgb[sel].mean(axis=0) if sel.any() else raw_rgb.reshape(-1, 3).mean(axis=0)
    return mean[1] / np.maximum(mean, 1e-9)


def colour_camera(
    linear: NDArray[np.float64], model: CameraModel, rng: np.random.Generator
) -> tuple[NDArray[np.uint8], dict[str, float]]:
    """The 8-bit sRGB image (H, W, 3) a colour camera makes of linear scene light.

    Optics (blur, vignetting), auto exposure, the RGGB sensor with shot and read noise
    and a 12-bit converter, white balance on the raw values (grey-world on the bright
    part, partly applied and with an error per channel), OpenCV's demosaicing, sRGB
    encoding. Returns the image and what was drawn (``exposure``, ``vignetting``,
    ``wb_gains``).
    """
    import cv2

    img = np.asarray(linear, np.float64)
    h, w = img.shape[:2]
    lum = img @ np.array([0.2126, 0.7152, 0.0722])
    if model.ideal:  # white balanced to the scene's white, exposed to 90 % of it
        gains = _grey_world_gains(img[::4, ::4])
        exposure = 0.9 / max(float(np.quantile(lum, 0.99)), 1e-9)
        out = linear_to_srgb(img * gains * exposure) * 255.0
        return np.clip(np.rint(out), 0, 255).astype(np.uint8), {"exposure": exposure}
    blur = float(rng.uniform(*model.blur_sigma_px))
    img = cv2.GaussianBlur(img.astype(np.float32), (0, 0), blur).astype(np.float64)
    vig = float(rng.uniform(*model.vignetting))
    y, x = np.mgrid[0:h, 0:w]
    r2 = ((x - (w - 1) / 2) ** 2 + (y - (h - 1) / 2) ** 2) / ((w / 2) ** 2 + (h / 2) ** 2)
    img = img * (1.0 - vig * r2)[..., None]
    target = float(rng.uniform(*model.exposure_target))
    exposure = _auto_exposure(lum * (1.0 - vig * r2), target, model.highlight_quantile)
    img = img * exposure
    # the sensor: electrons with shot noise, read noise, a 12-bit converter
    raw = bayer_mosaic(img)
    electrons = np.clip(raw, 0, None) * model.full_well_e
    electrons = electrons + rng.normal(0.0, 1.0, raw.shape) * np.sqrt(
        electrons + model.read_noise_e**2
    )
    top = 2**model.adc_bits - 1
    counts = np.clip(np.rint(electrons / model.full_well_e * top), 0, top)
    # white balance on the raw values, as a camera does it: imperfect
    est = _grey_world_gains(img[::4, ::4])
    strength = float(rng.uniform(*model.white_balance_strength))
    err = model.white_balance_error
    gains = est**strength * (1 + rng.uniform(-err, err, 3))
    balanced = np.clip(counts * _mosaic_gains(gains, raw.shape), 0, top)
    rgb16 = demosaic((balanced * (65535 / top)).astype(np.uint16)).astype(np.float64) / 65535.0
    out = linear_to_srgb(rgb16) * 255.0
    color = np.clip(np.rint(out), 0, 255).astype(np.uint8)
    return color, {
        "exposure": round(exposure, 5),
        "vignetting": round(vig, 4),
        "wb_gains": [round(float(g), 4) for g in gains],
        "blur_px": round(blur, 3),
    }


# --- the depth camera --------------------------------------------------------------------


def _edges(depth: NDArray[np.float64], jump_mm: float) -> tuple[NDArray, NDArray]:
    """Pixels next to a depth jump (H, W) and, for each, the farther neighbour's depth."""
    pad = np.pad(depth, 1, mode="edge")
    h, w = depth.shape
    far = depth.copy()
    for dy, dx in ((0, 1), (1, 0), (1, 2), (2, 1)):
        nb = pad[dy : dy + h, dx : dx + w]
        far = np.maximum(far, np.where(nb > 0, nb, far))
    near = depth.copy()
    for dy, dx in ((0, 1), (1, 0), (1, 2), (2, 1)):
        nb = pad[dy : dy + h, dx : dx + w]
        near = np.minimum(near, np.where(nb > 0, nb, near))
    edge = ((far - depth) > jump_mm) | ((depth - near) > jump_mm)
    other = np.where((far - depth) > jump_mm, far, near)
    return edge & (depth > 0), other


def tof_depth(
    z_mm: NDArray[np.float64],
    normal_dot_view: NDArray[np.float64],
    glossy: NDArray[np.bool_],
    model: ToFModel,
    rng: np.random.Generator,
) -> NDArray[np.uint16]:
    """The depth image (H, W) in mm (0: no reading) a time-of-flight camera gives.

    Parameters
    ----------
    z_mm : ndarray, shape (H, W)
        Exact z-depth, mm (0: nothing there).
    normal_dot_view : ndarray, shape (H, W)
        Cosine between the surface normal and the direction to the camera.
    glossy : ndarray of bool, shape (H, W)
        Surfaces with a specular coat (the laminated stickers).
    model : ToFModel
    rng : Generator
    """
    depth = np.asarray(z_mm, np.float64).copy()
    valid = depth > 0
    if model.ideal:
        return np.clip(np.rint(np.where(valid, depth, 0)), 0, 65535).astype(np.uint16)
    sigma = np.maximum(0.5, model.noise_mm * (depth / 1000.0) ** 2)
    depth = depth + rng.normal(0.0, 1.0, depth.shape) * sigma
    edge, other = _edges(np.where(valid, z_mm, 0.0), model.edge_jump_mm)
    u = rng.random(depth.shape)
    flying = edge & (u < model.flying_pixel)
    mix = rng.uniform(0.1, 0.9, depth.shape)
    depth = np.where(flying, mix * depth + (1 - mix) * other, depth)
    drop = edge & (u >= model.flying_pixel) & (u < model.flying_pixel + model.edge_dropout)
    cone = np.cos(np.radians(model.specular_cone_deg))
    drop |= glossy & (np.abs(normal_dot_view) > cone)
    drop |= np.abs(normal_dot_view) < model.grazing_cos
    drop |= rng.random(depth.shape) < model.random_dropout
    depth = np.where(valid & ~drop, depth, 0.0)
    return np.clip(np.rint(depth), 0, 65535).astype(np.uint16)
