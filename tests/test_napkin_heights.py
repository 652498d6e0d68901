"""Heights read around pixels: the median of the 3 x 3 height samples around each."""

from __future__ import annotations

import numpy as np

from dgli_vision.perception.napkin import NapkinMasks


def test_height_at_is_the_nanmedian_of_the_samples_around_each_pixel():
    """Pixels inside the grid, on its edges, half-way between samples (rounded to even),
    a sample beyond it, and unknown; windows with some, all or no readings; ties of heights."""
    rng = np.random.default_rng(5)
    s = 8
    for h, w in [(12, 17), (3, 3), (1, 6)]:
        heights = (np.round(rng.normal(20.0, 10.0, (h, w)) / 4) * 4).astype(np.float32)
        heights[rng.random((h, w)) < 0.4] = np.nan
        masks = NapkinMasks(s, np.zeros((h, w), bool), np.zeros((h, w), bool), height_mm=heights)
        uv = rng.uniform(-1.4 * s, (max(h, w) + 3) * s, (200, 2))
        uv[::5] = np.round(uv[::5] / 4) * 4  # exactly half-way between samples, or on one
        uv[7] = np.nan
        expected = np.full(len(uv), np.nan)
        for k, (u, v) in enumerate(uv):
            if np.isnan(u):
                continue
            i, j = round(v / s), round(u / s)
            win = heights[max(i - 1, 0) : i + 2, max(j - 1, 0) : j + 2]
            if np.isfinite(win).any():
                expected[k] = np.nanmedian(win)
        np.testing.assert_array_equal(masks.height_at(uv), expected)
