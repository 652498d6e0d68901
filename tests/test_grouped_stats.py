"""The grouped order statistics the dot unmixing of small stickers reads (issue 40): for
every blob at once, each figure to the bit what numpy gives blob by blob."""

from __future__ import annotations

import numpy as np


def test_grouped_quantile_and_median_are_numpys_to_the_bit() -> None:
    from dgli_vision.core.colour import srgb_lut
    from dgli_vision.perception.blobs import _grouped_level_medians, _grouped_quantile

    rng = np.random.default_rng(40)
    sizes = np.array([0, 1, 2, 3, 4, 7, 8, 50, 51, 0, 5])
    group = np.repeat(np.arange(len(sizes)), sizes)
    values = rng.random(group.size) ** 3  # (uneven, and some values repeat below)
    values[::7] = values[1]
    shuffled = rng.permutation(group.size)
    values, group = values[shuffled], group[shuffled]
    ordered = values[np.lexsort((values, group))]
    for q in (0.75, 0.5, 0.1, 0.9):
        got = _grouped_quantile(ordered, sizes, q)
        for k, n in enumerate(sizes):
            want = np.quantile(values[group == k], q) if n else np.nan
            assert got[k] == want or (np.isnan(want) and np.isnan(got[k])), (q, k)
    levels = rng.integers(0, 256, (group.size, 3), dtype=np.uint8)
    levels[::5] = levels[2]  # (repeated levels)
    got = _grouped_level_medians(levels, group, len(sizes))
    assert got.shape == (len(sizes), 3)
    for k, n in enumerate(sizes):
        want = np.median(srgb_lut()[levels[group == k]], axis=0) if n else np.full(3, np.nan)
        assert np.array_equal(got[k], want, equal_nan=True), k
    assert np.isnan(_grouped_level_medians(levels[:0], group[:0], 2)).all()


def test_grouped_statistics_keep_each_groups_pixel_order_for_sums() -> None:
    """The centre's mean is a sum in pixel order divided by the count, as ``mean``."""
    from dgli_vision.perception.blobs import _DiscPixels

    rng = np.random.default_rng(41)
    n_blobs, per = 3, 400
    side = int(per**0.5)
    blob = np.repeat(np.arange(n_blobs), per)
    xx, yy = np.meshgrid(np.arange(side) - side / 2, np.arange(side) - side / 2)
    r = np.tile((np.hypot(xx, yy) / (side / 3)).ravel(), n_blobs)
    norm = rng.integers(0, 256, (blob.size, 3), dtype=np.uint8)
    discs = _DiscPixels(
        blob, r, np.ones(blob.size, bool), np.zeros(blob.size, bool),
        np.ones(blob.size, np.uint8), norm, n_blobs, 2,
    )
    from dgli_vision.core.colour import srgb_lut

    for k, seen in enumerate(discs.unmixing):
        mine = blob == k
        lin = srgb_lut()[norm[mine]]
        rk = r[mine]
        ring = lin[(rk > 0.6) & (rk < 0.95)]
        chroma = ring.max(axis=1) - ring.min(axis=1)
        disc = np.median(ring[chroma >= np.quantile(chroma, 0.75)], axis=0)
        added = lin[rk < 0.2].mean(axis=0) - disc
        assert seen is not None
        assert seen[0] == disc.tolist() and seen[1] == added.tolist(), k
