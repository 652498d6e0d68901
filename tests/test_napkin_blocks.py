"""The nearest depth reading around each sample of the napkin's grid, to the value."""

from __future__ import annotations

import numpy as np
import pytest

from dgli_vision.perception.napkin import _BAND_ROWS, _nearest_in_blocks


def _by_definition(depth: np.ndarray, s: int) -> np.ndarray:
    """The minimum of ``depth - 1`` (0 wrapping to 65535) over the ``s`` x ``s`` window
    of rows and columns ``k s - s // 2`` to ``k s - s // 2 + s - 1`` of every sample."""
    less = depth - np.uint16(1)
    hh, ww = depth.shape
    out = np.empty((-(-hh // s), -(-ww // s)), np.uint16)
    for i in range(out.shape[0]):
        for j in range(out.shape[1]):
            y0, x0 = max(i * s - s // 2, 0), max(j * s - s // 2, 0)
            out[i, j] = less[y0 : i * s - s // 2 + s, x0 : j * s - s // 2 + s].min()
    return out


@pytest.mark.parametrize("s", [2, 3, 8])
def test_nearest_in_blocks_is_the_sampled_erosion(s):
    """Sides no multiple of the block (and shorter than one), frames taller than a band
    (the last band part full), readings missing here and there, nearly everywhere and
    everywhere, and the largest readings."""
    rng = np.random.default_rng(s)
    for hh, ww in [(1, 1), (5, 3), (2 * _BAND_ROWS + 13, 21), (_BAND_ROWS + s, 9)]:
        for missing in (0.0, 0.02, 0.9, 1.0):
            depth = rng.integers(0, 65536, (hh, ww)).astype(np.uint16)
            depth[rng.random((hh, ww)) < missing] = 0
            depth[rng.random((hh, ww)) < 0.01] = 65535
            np.testing.assert_array_equal(_nearest_in_blocks(depth, s), _by_definition(depth, s))
