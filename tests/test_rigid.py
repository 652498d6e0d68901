"""Where a missing sticker would lie: the RANSAC rigid fit stops early only when the
answer cannot change."""

from __future__ import annotations

from itertools import combinations

import numpy as np
import pytest

from dgli_vision.perception.rigid import fit_rigid, kabsch


def _exhaustive(uv_m, pts, use, tol_m):
    """Every triple tried, the first with the most inliers kept (the plain search)."""
    ids = np.flatnonzero(use)
    triples = np.array(list(combinations(ids, 3)))
    a, b, c = (uv_m[triples[:, k]] for k in range(3))
    triples = triples[np.abs(np.cross(b - a, c - a)[:, 2]) > 1e-4]
    r, t = kabsch(uv_m[triples], pts[triples])
    pred = np.einsum("tij,nj->tni", r, uv_m[ids]) + t[:, None, :]
    inl = np.linalg.norm(pred - pts[ids][None], axis=2) < tol_m
    best = inl[int(np.argmax(inl.sum(axis=1)))]
    r1, t1 = kabsch(uv_m[ids[best]], pts[ids[best]])
    return uv_m @ r1.T + t1, ids[best], r1, t1


def test_the_rigid_fit_is_the_exhaustive_search_bit_for_bit():
    rng = np.random.default_rng(5)
    for trial in range(150):
        uv = np.column_stack([rng.uniform(0, 0.4, (16, 2)), np.zeros(16)])
        a = rng.uniform(0, 2 * np.pi)
        rot = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1.0]])
        pts = uv @ rot.T + [0.1, 0.0, 0.7] + rng.normal(0, 0.002, (16, 3))
        moved = rng.choice(16, trial % 4, replace=False)  # stickers on a flap, misreads
        pts[moved] += rng.normal(0, 0.05, (len(moved), 3))
        use = rng.random(16) < 0.4 + 0.6 * rng.random()
        use[:3] = True
        got = fit_rigid(uv, pts, use, 0.01)
        want, inliers, r, t = _exhaustive(uv, pts, use, 0.01)
        if len(inliers) < 3:
            assert got is None
            continue
        assert got.predicted.tobytes() == want.tobytes()
        np.testing.assert_array_equal(np.flatnonzero(got.inliers), inliers)
        # the map itself is kept: the pose of the inliers' least-squares fit
        assert got.rotation.tobytes() == r.tobytes() and got.translation.tobytes() == t.tobytes()


def test_a_fit_tells_the_corners_it_spans_and_the_face_it_shows():
    from dgli_vision.core.layout import default_layout
    from dgli_vision.perception.rigid import flat_points_m

    layout = default_layout()
    uv = flat_points_m(layout)
    assert not uv.flags.writeable and uv.shape == (16, 3)
    np.testing.assert_array_equal(uv[:, :2], layout.sticker_uv * 1e-3)
    pts = uv + np.array([0.0, 0.0, 0.6])  # lying flat, front face towards +z
    corner_of = layout.sticker_corners
    one_corner = corner_of == 0
    fit = fit_rigid(uv, pts, one_corner, 0.005)
    assert fit.corners_spanned(corner_of) == 1
    everything = fit_rigid(uv, pts, np.ones(16, bool), 0.005)
    assert everything.corners_spanned(corner_of) == 4
    assert everything.face_cos(np.array([0.0, 0.0, 1.0])) == pytest.approx(1.0)
    turned = fit_rigid(uv, pts * [1, -1, -1], np.ones(16, bool), 0.005)  # turned over
    assert turned.face_cos(np.array([0.0, 0.0, 1.0])) == pytest.approx(-1.0)
    assert fit_rigid(uv, pts, corner_of == 0, 0.005).inliers.sum() == one_corner.sum()
