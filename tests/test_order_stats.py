"""The pipeline's fast medians and quantiles give numpy's values to the bit, so that no
frame's answer depends on which one computed them."""

import numpy as np
import pytest

from dgli_vision.core.order_stats import median, nanmedian, quantile


def _samples(seed: int, dtype: type) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(300):
        n = int(rng.integers(1, 400))
        x = (rng.normal(size=n) * 10 ** rng.uniform(-3, 2)).astype(dtype)
        if rng.random() < 0.4:  # ties, as 8-bit levels through a lookup give
            x = np.round(x, 1).astype(dtype)
        out.append(x)
    return out


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_median_is_numpys_to_the_bit_for_odd_and_even_counts(dtype):
    for x in _samples(1, dtype):
        assert median(x) == float(np.median(x))


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("q", [0.97, 0.5, 0.03, 0.0, 1.0, 0.123])
def test_quantile_is_numpys_to_the_bit(dtype, q):
    for x in _samples(2, dtype):
        assert quantile(x, q) == float(np.quantile(x, q))


@pytest.mark.parametrize("n", [1023, 1024, 1025, 3600, 14400])
def test_order_statistics_of_thousands_of_values_are_numpys_to_the_bit(n):
    """From a thousand values on, one partition and the neighbour on its side (ties as
    depth in millimetres or 8-bit levels give them, and a NaN)."""
    rng = np.random.default_rng(n)
    for x in (rng.normal(size=n), rng.integers(0, 40, n) / 7.0, rng.normal(size=n) + 0.5):
        x = x.astype(np.float64)
        assert median(x) == float(np.median(x))
        for q in (0.97, 0.5, 0.03, 0.0, 1.0):
            assert quantile(x, q) == float(np.quantile(x, q))
    x[n // 3] = np.nan
    assert np.isnan(median(x)) and np.isnan(quantile(x, 0.97)) and np.isnan(quantile(x, 0.0))


def test_a_nan_gives_nan_as_numpy_does():
    x = np.array([1.0, np.nan, 3.0, 2.0])
    assert np.isnan(median(x)) and np.isnan(quantile(x, 0.97))


def test_nanmedian_is_numpys_to_the_bit():
    rng = np.random.default_rng(3)
    for x in _samples(3, np.float64):
        x[rng.random(x.size) < 0.3] = np.nan
        if np.isnan(x).all():
            continue
        assert nanmedian(x) == float(np.nanmedian(x))


@pytest.mark.parametrize("q", [0.97, 0.5, 0.0, 1.0, 0.123])
def test_the_cloth_regions_order_statistics_of_sorted_cells_are_numpys(q):
    """The white regions take the bright level and the table's median from sorted cells
    (8-bit levels through a table: many ties), image sized and tiny, NaN included."""
    from dgli_vision.core.order_stats import sorted_median, sorted_quantile

    rng = np.random.default_rng(4)
    for n in (1, 2, 7, 14400, 14401):
        x = rng.integers(0, 256, n) / 255.0 * rng.uniform(0.5, 2.0)
        s = np.sort(x)
        assert sorted_quantile(s, q) == float(np.quantile(x, q))
        assert sorted_median(s) == float(np.median(x))
    x[3] = np.nan
    assert np.isnan(sorted_quantile(np.sort(x), q)) and np.isnan(sorted_median(np.sort(x)))
