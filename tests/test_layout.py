"""The napkin layout reproduces SPEC section 2's table."""

from __future__ import annotations

import numpy as np
import pytest

from dgli_vision.core.dgli import pair_indices
from dgli_vision.core.layout import default_layout, load_layout

S = 400.0
SPEC_SEGMENTS = [  # SPEC section 2, "from" and "to" for S = 400
    ((50, 20), (100, 20)),
    ((S - 100, 20), (S - 50, 20)),
    ((S - 20, 50), (S - 20, 100)),
    ((S - 20, S - 100), (S - 20, S - 50)),
    ((S - 50, S - 20), (S - 100, S - 20)),
    ((100, S - 20), (50, S - 20)),
    ((20, S - 50), (20, S - 100)),
    ((20, 100), (20, 50)),
]


def test_segments_match_spec_table():
    layout = default_layout()
    np.testing.assert_array_equal(layout.segments_uv, np.array(SPEC_SEGMENTS))
    assert layout.segment_edges == ("AB", "AB", "BC", "BC", "CD", "CD", "DA", "DA")
    assert layout.segment_corners == ("A", "B", "B", "C", "C", "D", "D", "A")


def test_stickers_have_unique_colour_pairs_and_spec_examples():
    layout = default_layout()
    pairs = list(zip(layout.sticker_disc, layout.sticker_dot))
    assert len(set(pairs)) == 16
    assert pairs[0] == ("red", "red")
    assert pairs[15] == ("red", "green")
    np.testing.assert_array_equal(layout.sticker_uv[0], [50, 20])
    np.testing.assert_array_equal(layout.sticker_uv[15], [20, 50])
    assert layout.sticker_id("red", "green") == 15
    assert layout.sticker_id("white", "red") is None
    # Around each corner: near/far on the leaving edge red/yellow, arriving green/blue.
    assert [pairs[k][1] for k in (0, 1, 14, 15)] == ["red", "yellow", "blue", "green"]


def test_rectangular_napkin_keeps_corner_distances():
    layout = load_layout(width_mm=500, height_mm=300)
    np.testing.assert_array_equal(layout.segments_uv[1], [[400, 20], [450, 20]])
    np.testing.assert_array_equal(layout.segments_uv[3], [[480, 200], [480, 250]])
    with pytest.raises(ValueError, match="too small"):
        load_layout(width_mm=200)


def test_flat_napkin_coordinates_in_one_call():
    layout = default_layout()
    coords = layout.flat_coordinates()
    assert coords.shape == (28,)
    assert np.isfinite(coords).all()
    i, j = pair_indices(8)
    # Collinear pairs (the two segments of one edge) have dGLI 0.
    for a, b in [(0, 1), (2, 3), (4, 5), (6, 7)]:
        assert coords[(i == a) & (j == b)][0] == pytest.approx(0.0, abs=1e-12)
    # The square's quarter-turn symmetry maps segment k to k + 2: coordinates agree.
    shifted = {(a, b): v for a, b, v in zip(i, j, coords)}
    for (a, b), v in shifted.items():
        a2, b2 = sorted(((a + 2) % 8, (b + 2) % 8))
        assert shifted[(a2, b2)] == pytest.approx(v, rel=1e-9, abs=1e-12)
