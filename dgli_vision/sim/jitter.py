"""Tiny changes of a captured frame, of the size two readings of one scene differ by:
the depth rounded at another phase (as a 0.1 mm sensor read in mm would be), shifted by
one pixel, and the colour moved by a grey level. A verdict's confidence must not jump
under any of them (``tests/test_confidence_continuity.py``,
``benchmarks/confidence_edges.py``)."""

from __future__ import annotations

from dataclasses import replace
from typing import TypeVar

import numpy as np

__all__ = ["tiny_changes"]

F = TypeVar("F")


def tiny_changes(frame: F, rng: np.random.Generator) -> list[F]:
    """Three copies of ``frame`` (any dataclass with ``color`` (H, W, 3) uint8 and
    ``depth_mm`` (H, W) uint16, such as :class:`~dgli_vision.sources.frames.RGBDFrame`),
    each changed in one way.

    Parameters
    ----------
    frame : dataclass
    rng : numpy.random.Generator
        Draws the rounding phase and the grey levels.

    Returns
    -------
    list
        The frame with its depth rounded at another phase, with its depth shifted one
        pixel to the right, and with its colour moved by up to one grey level.
    """
    depth = frame.depth_mm  # type: ignore[attr-defined]
    color = frame.color  # type: ignore[attr-defined]
    d = depth.astype(np.float64)
    requant = np.where(d > 0, np.rint(d + rng.uniform(-0.5, 0.5, d.shape)), 0)
    shifted = np.zeros_like(depth)
    shifted[:, 1:] = depth[:, :-1]
    grey = np.clip(color.astype(np.int16) + rng.integers(-1, 2, color.shape), 0, 255)
    return [
        replace(frame, depth_mm=requant.astype(np.uint16)),  # type: ignore[type-var]
        replace(frame, depth_mm=shifted),  # type: ignore[type-var]
        replace(frame, color=grey.astype(np.uint8)),  # type: ignore[type-var]
    ]
