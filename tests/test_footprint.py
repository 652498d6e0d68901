"""The footprint's cell averages: the same cells as OpenCV's area resize, to the bit."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from dgli_vision.perception.regions import _cell_means


def _area(color: np.ndarray, c: int) -> np.ndarray:
    h, w = color.shape[0] // c, color.shape[1] // c
    return cv2.resize(color[: h * c, : w * c], (w, h), interpolation=cv2.INTER_AREA)


@pytest.mark.parametrize("c", [2, 3, 4, 8, 16])
def test_cell_means_are_the_area_resize_of_any_frame(c):
    """Frames whose side is no multiple of the cell (the last pixels left out), noise,
    and levels that put many cells' means half-way between two integers."""
    rng = np.random.default_rng(c)
    for shape in [(97, 131, 3), (64, 48, 3), (50, 203, 3)]:
        noise = rng.integers(0, 256, shape, dtype=np.uint8)
        halves = (noise // 64 * 64 + 32).astype(np.uint8)
        binary = np.where(rng.random((*shape[:2], 1)) < 0.5, 0, 255).astype(np.uint8)
        for color in (noise, halves, np.repeat(binary, 3, axis=2)):
            np.testing.assert_array_equal(_cell_means(color, c), _area(color, c))


def test_every_cell_sum_rounds_as_opencv_rounds():
    """Each possible sum of an 8 x 8 cell once: exact halves round to even, as OpenCV."""
    c = 8
    sums = np.arange(c * c * 255 + 1)
    full, rest = np.divmod(sums, 255)
    k = np.arange(c * c)
    cells = np.where(k[None, :] < full[:, None], 255, 0)
    cells = np.where(k[None, :] == full[:, None], rest[:, None], cells).astype(np.uint8)
    # cell s occupies columns s * c to s * c + c - 1 of a c-row image, channel 0
    plane = cells.reshape(-1, c, c).transpose(1, 0, 2).reshape(c, -1)
    color = np.zeros((c, plane.shape[1], 3), np.uint8)
    color[..., 0] = plane
    np.testing.assert_array_equal(_cell_means(color, c), _area(color, c))
