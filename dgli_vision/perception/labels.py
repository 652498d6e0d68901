"""Colour labels: every pixel named by the nearest of the four sticker hues, or none.

OpenCV's 8-bit hue runs 0-179 and red wraps around 0. A pixel is labelled when it is
saturated, bright and chromatic enough in the image balanced to the napkin's white
(:class:`~.detections.DetectorParams`), and its hue lies within ``max_hue_distance`` of
a sticker colour's.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ..core.layout import NapkinLayout
from .detections import DetectorParams

__all__ = ["colour_labels", "hue_lut", "hue_of"]

#: Up to this many dark coloured pixels, :func:`colour_labels` tests them one by one.
_FEW_DARK = 2000


def hue_of(rgb: tuple[int, int, int]) -> int:
    """OpenCV 8-bit hue (0-179) of an sRGB colour."""
    return _hue_of(tuple(int(c) for c in rgb))


@lru_cache(maxsize=64)
def _hue_of(rgb: tuple[int, ...]) -> int:
    import cv2

    return int(cv2.cvtColor(np.uint8([[rgb]]), cv2.COLOR_RGB2HSV)[0, 0, 0])


def hue_lut(
    layout: NapkinLayout, params: DetectorParams, colours: dict[str, tuple[int, int, int]] | None
) -> tuple[NDArray[np.uint8], list[str]]:
    """Lookup table hue -> colour label (0 none, k + 1 for colour k) and colour names.

    ``colours`` (calibrated sRGB of each colour name, as the balanced image shows them)
    replaces the layout's nominal colours.
    """
    names = list(layout.colours_srgb)
    source = {**layout.colours_srgb, **(colours or {})}
    lut = _nearest_hue_lut(tuple(hue_of(source[n]) for n in names), params.max_hue_distance)
    return lut.copy(), names


@lru_cache(maxsize=16)
def _nearest_hue_lut(hues: tuple[int, ...], max_distance: int) -> NDArray[np.uint8]:
    """Hue -> 1 + index of the nearest of ``hues`` within ``max_distance``, else 0."""
    h = np.arange(180)
    dist = np.abs(h[:, None] - np.array(hues)[None, :])
    dist = np.minimum(dist, 180 - dist)  # hue is circular
    lut = (np.argmin(dist, axis=1) + 1).astype(np.uint8)
    lut[dist.min(axis=1) > max_distance] = 0
    return lut


def colour_labels(
    norm: NDArray[np.uint8], lut: NDArray[np.uint8], params: DetectorParams
) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """Colour label (0 none, k + 1 colour k) of every pixel of a balanced RGB image, and
    its HSV. Shapes (h, w) and (h, w, 3). ``lut`` is :func:`hue_lut`'s table."""
    import cv2

    hsv = cv2.cvtColor(norm, cv2.COLOR_RGB2HSV)
    least = (0, params.min_saturation, params.min_value)
    coloured = cv2.inRange(hsv, least, (180, 255, 255))
    # chroma = S * V / 255 >= min_chroma: only binding where V is low (dark, noisy pixels)
    v_limit = int(np.ceil(params.min_chroma * 255 / max(params.min_saturation, 1)))
    dark_mask = cv2.inRange(hsv, least, (180, 255, max(v_limit - 1, 0)))  # (coloured too)
    n_dark = cv2.countNonZero(dark_mask)
    if n_dark:
        coloured = _without_faint(coloured, dark_mask, n_dark, hsv, params.min_chroma * 255)
    labels = cv2.LUT(hsv[..., 0], np.concatenate([lut, np.zeros(76, np.uint8)]))
    return cv2.bitwise_and(labels, coloured), hsv


def _without_faint(
    coloured: NDArray[np.uint8],
    dark_mask: NDArray[np.uint8],
    n_dark: int,
    hsv: NDArray[np.uint8],
    least: int,
) -> NDArray[np.uint8]:
    """``coloured`` without the dark pixels (``dark_mask``, ``n_dark`` of them) whose
    chroma S * V is below ``least``. Few dark pixels are looked up one by one; many
    (the second search's low saturation makes most coloured pixels dark) are tested
    with one whole-image product: the same integers either way."""
    import cv2

    if n_dark <= _FEW_DARK:
        dv, du = np.nonzero(dark_mask)
        faint = hsv[dv, du, 1].astype(np.int32) * hsv[dv, du, 2] < least
        coloured[dv[faint], du[faint]] = 0
        return coloured
    chroma = hsv[..., 1].astype(np.uint16)
    np.multiply(chroma, hsv[..., 2], out=chroma)  # at most 255 * 255: no overflow
    faint = cv2.bitwise_and(dark_mask, cv2.compare(chroma, least, cv2.CMP_LT))
    return cv2.bitwise_and(coloured, cv2.bitwise_not(faint))
