"""The doubt factors withhold only answers in doubt (issue 51): stickers near the border
of an image whose lens is not given lower the confidence only as far as a lens the
napkin's own distances allow could move them."""

from __future__ import annotations

import numpy as np
import pytest

from dgli_vision.classifier.capture_limits import (
    LENS_STRETCH_NOISE,
    TYPICAL_K1,
    border_factor,
    lens_k1_bound,
)
from dgli_vision.core.camera import DEFAULT_INTRINSICS, look_at_table
from dgli_vision.core.layout import default_layout

INTR = DEFAULT_INTRINSICS


def _napkin_px(offset_m: tuple[float, float], k1: float = 0.0) -> np.ndarray:
    """The flat napkin's 16 sticker centres seen from 0.5 m, its centre ``offset_m`` off
    the view's axis, through a lens with ``k1`` (pixels)."""
    layout = default_layout()
    uv = np.asarray(layout.sticker_uv, float) * 1e-3
    xyz = np.c_[uv - uv.mean(axis=0) + np.asarray(offset_m), np.zeros(16)]
    pose = look_at_table(0.5)
    px = INTR.project(pose.world_to_camera(xyz))
    if k1:
        x = (px - [INTR.cx, INTR.cy]) / INTR.fx
        px = x * (1 + k1 * (x * x).sum(axis=1, keepdims=True)) * INTR.fx + [INTR.cx, INTR.cy]
    return px


def _stretch(px: np.ndarray, k1: float) -> float:
    """How far the most stretched corner's distances lie from the median corner's, lifted
    at one depth through a pinhole (what the ruler measures of a lens with ``k1``)."""
    from dgli_vision.core.layout import CORNER_STICKERS

    x = (px - [INTR.cx, INTR.cy]) / INTR.fx
    undist = x / (1 + k1 * (x * x).sum(axis=1, keepdims=True))
    ratios = []
    for ids in CORNER_STICKERS:
        ids = list(ids)
        seen = np.linalg.norm(x[ids][:, None] - x[ids][None], axis=-1)
        true = np.linalg.norm(undist[ids][:, None] - undist[ids][None], axis=-1)
        ratios.append(np.median(seen[true > 0] / true[true > 0]))
    scale = np.median(ratios)
    return float(np.max(np.abs(np.asarray(ratios) / scale - 1)))


def test_a_napkin_near_the_border_that_keeps_its_distances_keeps_its_confidence():
    px = _napkin_px((0.18, 0.10))
    typical = border_factor(px, INTR, 35.0)
    assert typical < 0.8  # a typical lens would move the outermost stickers a diameter
    assert border_factor(px, INTR, 35.0, stretch=0.002) > typical + 0.1
    assert border_factor(px, INTR, 35.0, stretch=None) == typical


@pytest.mark.parametrize("k1", [0.06, 0.09, 0.12])
def test_the_bound_from_the_stretch_never_falls_below_the_lens_that_made_it(k1):
    px = _napkin_px((0.18, 0.10), k1)
    stretch = _stretch(px, k1)
    assert lens_k1_bound(px, INTR, stretch) >= k1
    # and without the noise allowance it still holds (the weaker direction is assumed)
    assert lens_k1_bound(px, INTR, stretch - LENS_STRETCH_NOISE) >= k1


def test_the_bound_says_nothing_with_too_few_corners_or_one_radius():
    px = _napkin_px((0.18, 0.10))
    px[[2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13]] = np.nan  # corner A alone
    assert lens_k1_bound(px, INTR, 0.0) == float("inf")
    assert border_factor(px, INTR, 35.0, stretch=0.0) == border_factor(px, INTR, 35.0)
    assert TYPICAL_K1 < lens_k1_bound(_napkin_px((0.0, 0.0)), INTR, 0.05)
