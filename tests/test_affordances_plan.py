"""The state's fold plan worked out once (affordances) gives every corner exactly what
the general rigid-map code gives, for every state and variant."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from dgli_vision.classifier import affordances as aff
from dgli_vision.core.classes import CORNERS, VARIANTS
from dgli_vision.core.layout import default_layout


def _observation(seed: int) -> SimpleNamespace:
    """A napkin lying flat, turned and moved, some stickers missing, one standing."""
    layout = default_layout()
    rng = np.random.default_rng(seed)
    a = rng.uniform(0, 2 * np.pi)
    rot = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1.0]])
    uv = np.column_stack([np.asarray(layout.sticker_uv) * 1e-3, np.zeros(16)])
    points = uv @ rot.T + [0.1, -0.2, 0.7] + rng.normal(0, 0.002, (16, 3))
    visible = rng.random(16) > 0.25
    heights = np.where(visible, rng.normal(0, 2, 16), np.nan)
    heights[int(rng.integers(16))] = 60.0
    return SimpleNamespace(
        points_m=points, visible=visible, heights_mm=heights, up=np.array([0, 0, 1.0]),
        turns=None, lifted=None,
    )


def test_the_plan_of_every_state_places_the_corners_as_the_general_code():
    layout = default_layout()
    for seed in range(3):
        obs = _observation(seed)
        for class_id, variants in VARIANTS.items():
            for variant in variants:
                plan = aff._plan(class_id, variant, layout)
                maps = aff.napkin_maps(obs, class_id, variant, layout)
                for k in range(len(CORNERS)):
                    fast = aff._corner_of_verdict(obs, k, maps, layout, None, plan)
                    slow = aff._corner_of_verdict(obs, k, maps, layout, None)
                    assert fast[:2] == slow[:2] and fast[3] == slow[3], (class_id, variant, k)
                    if slow[2] is None:
                        assert fast[2] is None
                    else:
                        assert fast[2].tobytes() == slow[2].tobytes()


def test_kabsch_sign_fix_gives_a_rotation_for_mirrored_points():
    rng = np.random.default_rng(4)
    src = rng.normal(size=(6, 3))
    r, _ = aff._kabsch(src, src * [1, 1, -1] + 0.1)
    assert np.linalg.det(r) > 0.99
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-12)


def test_rigid_maps_fitted_together_are_those_fitted_alone_to_the_bit():
    # one LAPACK call for a frame's fits must not move a point: fits of every size, a
    # misread sticker (refitted without it), too few points and no problem at all
    rng = np.random.default_rng(7)
    up = np.array([0.0, 0.0, 1.0])
    problems = []
    for n in (1, 2, 3, 4, 6, 8):
        uv = rng.uniform(0, 400, (n, 2))
        points = np.column_stack([uv * 1e-3, np.zeros(n)]) + np.array([0.1, 0.0, 0.7])
        points += rng.normal(0, 0.002, (n, 3))
        if n >= 4:
            points[1] += 0.05  # a misread sticker: the fit is made again without it
        if n == 6:
            points[0] = np.nan
        problems.append((uv, points, up, 1 if n % 2 else -1))
    problems.insert(2, None)
    together = aff.fit_maps(problems)
    assert together[2] is None and together[0] is None  # (one point is not enough)
    for problem, m in zip(problems, together):
        if problem is None:
            continue
        alone = _fit_alone(*problem)
        assert (m is None) == (alone is None)
        if m is not None:
            assert m.rotation.tobytes() == alone.rotation.tobytes()
            assert m.translation.tobytes() == alone.translation.tobytes()


def _fit_alone(uv_mm, points, up, face):
    """fit_map's rigid map, fitted alone with a SVD of its own (as it was before the
    frame's fits were made together)."""
    keep = np.isfinite(points).all(axis=1)
    m = None
    for _ in range(3):
        n = int(np.count_nonzero(keep))
        if n < 2:
            return None
        src = np.zeros((2 * n, 3))
        src[:n, :2] = src[n:, :2] = uv_mm[keep] * 1e-3
        src[n:, 2] = 0.05
        pts = points[keep]
        r, t = aff._kabsch(src, np.concatenate([pts, pts + face * 0.05 * up]))
        m = aff.RigidMap(r, t)
        res = np.sqrt(np.add.reduce((src[:n] @ r.T + t - pts) ** 2, axis=1))
        worst = int(np.argmax(res))
        if res[worst] <= aff.FIT_TOLERANCE_M or n <= 2:
            return m
        keep[np.flatnonzero(keep)[worst]] = False
    return m
