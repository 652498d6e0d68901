"""The sRGB transfer function, stated once (IEC 61966-2-1): 8-bit or [0, 1] sRGB values
to linear light and back. The renderer shades in linear light; the perception balances
images to the napkin's white in linear light."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["linear_to_srgb", "srgb_lut", "srgb_to_linear"]


def srgb_to_linear(c: ArrayLike) -> NDArray[np.float64]:
    """Linear light of sRGB values in [0, 1]."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c: ArrayLike) -> NDArray[np.float64]:
    """sRGB values in [0, 1] of linear light (clipped to [0, 1] first)."""
    c = np.clip(np.asarray(c, dtype=np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)


@lru_cache(maxsize=1)
def srgb_lut() -> NDArray[np.float64]:
    """Linear light of each 8-bit sRGB level, shape (256,), read-only."""
    lut = srgb_to_linear(np.arange(256) / 255.0)
    lut.flags.writeable = False
    return lut
