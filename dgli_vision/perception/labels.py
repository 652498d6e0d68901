"""Colour labels: every pixel named by the nearest of the four sticker hues, or none.

OpenCV's 8-bit hue runs 0-179 and red wraps around 0. A pixel is labelled when it is
saturated, bright and chromatic enough in the image balanced to the napkin's white
(:class:`~.detections.DetectorParams`), and its hue lies within ``max_hue_distance`` of
a sticker colour's.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray

from ..core.layout import NapkinLayout
from .detections import DetectorParams

__all__ = ["colour_labels", "hue_lut", "hue_of"]

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
    norm: NDArray[np.uint8], lut: NDArray[np.uint8], params: DetectorParams,
    *, out: tuple[NDArray[np.uint8], NDArray[np.uint8]] | None = None,
) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """Colour label (0 none, k + 1 colour k) of every pixel of a balanced RGB image, and
    its HSV. Shapes (h, w) and (h, w, 3). ``lut`` is :func:`hue_lut`'s table; ``out``:
    the arrays (labels, HSV) to write them in (views of larger images may be given).

    A pixel is coloured when its saturation S reaches :func:`_least_saturation` of its
    value V (which holds every threshold: saturation, value, chroma): one table lookup
    and one comparison per pixel on the HSV planes."""
    import cv2

    labels_out, hsv_out = out if out is not None else (None, None)
    hsv = cv2.cvtColor(norm, cv2.COLOR_RGB2HSV, dst=hsv_out)
    # planes of their own (each is overwritten below); three extractChannel calls cost
    # a fraction of one cv2.split of the same image
    h, s, v = (cv2.extractChannel(hsv, k) for k in range(3))
    needed, v_least = _least_saturation(
        params.min_saturation, params.min_value, params.min_chroma
    )
    coloured = cv2.compare(s, cv2.LUT(v, needed), cv2.CMP_GE, dst=s)
    if v_least > 0:  # (no saturation is enough below it)
        cv2.threshold(v, v_least - 1, 255, cv2.THRESH_BINARY, dst=v)
        cv2.bitwise_and(coloured, v, dst=coloured)
    labels = cv2.LUT(h, _hue_table(lut), dst=h)
    labels = cv2.bitwise_and(labels, coloured, dst=h if labels_out is None else labels_out)
    return labels, hsv


def _hue_table(lut: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """``lut`` (hues 0-179) as a 256-entry table for ``cv2.LUT`` (0 beyond 179)."""
    return np.concatenate([lut, np.zeros(256 - len(lut), np.uint8)])


@lru_cache(maxsize=16)
def _least_saturation(
    min_saturation: int, min_value: int, min_chroma: float
) -> tuple[NDArray[np.uint8], int]:
    """The least HSV saturation (8-bit) a pixel of each value V (0-255) needs to be
    coloured, and the least value that can be coloured at all (any saturation below it
    is too little). Shape (256,).

    A coloured pixel has S >= ``min_saturation`` and V >= ``min_value``; where V is low
    (dark, noisy pixels: V below ``min_chroma`` * 255 / ``min_saturation``) also a chroma
    S * V of at least ``min_chroma`` * 255: there S >= ceil(``min_chroma`` * 255 / V)."""
    least = min_chroma * 255
    v_limit = int(np.ceil(least / max(min_saturation, 1)))
    needed = np.full(256, max(min_saturation, 0), np.int64)
    v_least = max(min_value, 0) if min_saturation <= 255 else 256
    for v in range(min(max(v_limit - 1, 0), 255) + 1):  # (dark: the chroma binds)
        if v == 0:
            need = max(min_saturation, 0) if least <= 0 else 256
        else:
            need = max(min_saturation, math.ceil(-(-least // v)))
        needed[v] = need
        if need > 255:
            v_least = max(v_least, v + 1)
    table = np.minimum(needed, 255).astype(np.uint8)
    table.flags.writeable = False
    return table, min(v_least, 256)
