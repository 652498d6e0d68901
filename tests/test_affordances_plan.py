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
