"""Spearman distance and Davies-Bouldin index against independent computations."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import rankdata, spearmanr

from dgli_vision.core.distance import (
    average_ranks,
    centred_unit_ranks,
    davies_bouldin,
    davies_bouldin_points,
    pairwise_spearman,
    spearman_distance,
    spearman_to_ranked,
)


def test_identical_and_reversed_orders():
    x = np.array([3.0, 1.0, 4.0, 1.5, 9.0])
    assert spearman_distance(x, x) == pytest.approx(0.0)
    assert spearman_distance(x, -x) == pytest.approx(2.0)
    assert spearman_distance(x, np.exp(x)) == pytest.approx(0.0)  # rank-based


def test_matches_scipy_spearman_with_ties():
    rng = np.random.default_rng(1)
    for _ in range(20):
        x = rng.integers(0, 5, size=28).astype(float)  # many ties
        y = rng.normal(size=28)
        y[:5] = y[5]
        rho = spearmanr(x, y).statistic
        assert spearman_distance(x, y) == pytest.approx(1.0 - rho, abs=1e-12)


def test_broadcasts_over_leading_dimensions():
    rng = np.random.default_rng(2)
    x = rng.normal(size=(4, 28))
    y = rng.normal(size=28)
    out = spearman_distance(x, y)
    assert out.shape == (4,)
    assert out[2] == pytest.approx(spearman_distance(x[2], y))


def test_nan_propagates_or_is_omitted():
    rng = np.random.default_rng(3)
    x, y = rng.normal(size=(2, 28))
    x[[2, 9]] = np.nan
    y[20] = np.nan
    assert np.isnan(spearman_distance(x, y))
    keep = ~(np.isnan(x) | np.isnan(y))
    expected = 1.0 - spearmanr(x[keep], y[keep]).statistic
    assert spearman_distance(x, y, omit_nan=True) == pytest.approx(expected, abs=1e-12)
    few = np.full(28, np.nan)
    few[:2] = [1.0, 2.0]
    assert np.isnan(spearman_distance(few, y, omit_nan=True))


def test_constant_vector_is_uncorrelated():
    assert spearman_distance(np.ones(28), np.arange(28.0)) == 1.0


def test_pairwise_matches_elementwise():
    rng = np.random.default_rng(4)
    x, y = rng.normal(size=(6, 28)), rng.normal(size=(3, 28))
    d = pairwise_spearman(x, y)
    assert d.shape == (6, 3)
    assert d[4, 1] == pytest.approx(spearman_distance(x[4], y[1]))
    dx = pairwise_spearman(x)
    assert np.allclose(dx, dx.T) and np.all(np.diag(dx) == 0)
    with pytest.raises(ValueError, match="NaN"):
        pairwise_spearman(np.full((2, 28), np.nan))


def test_davies_bouldin_hand_computed():
    # Two 1-D classes {0, 2} and {10, 12}: centres 1 and 11 (means) or 0 and 10 (first
    # medoid), scatter 1 each, separation 10: DB = (1 + 1) / 10.
    pts = np.array([[0.0], [2.0], [10.0], [12.0]])
    labels = ["a", "a", "b", "b"]
    dist = np.abs(pts - pts.T)
    assert davies_bouldin(dist, labels) == pytest.approx(0.2)
    assert davies_bouldin_points(pts, labels, lambda u, v: float(np.abs(u - v).sum())) == (
        pytest.approx(0.2)
    )


def test_davies_bouldin_three_classes_takes_worst_neighbour():
    # Classes at 0, 4 and 20 with scatter 1: class 0 -> (1+1)/4, class 4 -> (1+1)/4,
    # class 20 -> (1+1)/16. Mean = (0.5 + 0.5 + 0.125) / 3.
    pts = np.array([[-1.0], [1.0], [3.0], [5.0], [19.0], [21.0]])
    labels = [0, 0, 1, 1, 2, 2]
    value = davies_bouldin_points(pts, labels, lambda u, v: float(abs(u - v)[0]))
    assert value == pytest.approx((0.5 + 0.5 + 0.125) / 3)


def test_davies_bouldin_rejects_bad_input():
    with pytest.raises(ValueError, match="at least 2 classes"):
        davies_bouldin(np.zeros((3, 3)), [1, 1, 1])
    with pytest.raises(ValueError, match="square"):
        davies_bouldin(np.zeros((3, 2)), [1, 2, 2])


def test_average_ranks_match_scipy():
    rng = np.random.default_rng(5)
    x = rng.integers(0, 6, size=(7, 28)).astype(float)
    np.testing.assert_array_equal(average_ranks(x), rankdata(x, axis=-1))
    np.testing.assert_array_equal(average_ranks([3.0, 1.0, 3.0]), [2.5, 1.0, 2.5])


def test_distances_to_ranked_rows_equal_pairwise_bit_for_bit():
    # the classifier ranks its references once and compares every frame with them:
    # the verdicts must not move by a bit (ties, a constant vector, a signed zero)
    rng = np.random.default_rng(7)
    for t in range(300):
        n = int(rng.integers(3, 29))
        x = rng.integers(-3, 4, n).astype(float) if t % 2 else rng.normal(size=n)
        if t % 10 == 0:
            x[:] = 0.5
        x[int(rng.integers(0, n))] = -0.0
        y = rng.integers(0, 5, size=(40, n)).astype(float)
        got = spearman_to_ranked(x, centred_unit_ranks(y))
        assert got.tobytes() == pairwise_spearman(x[None], y)[0].tobytes()
    with pytest.raises(ValueError, match="NaN"):
        spearman_to_ranked(np.array([1.0, np.nan, 2.0]), centred_unit_ranks(np.ones((2, 3))))
