"""A corner hidden under a gripper: bare table where a flat corner would lie says it has
moved, and only that; the references that leave it there pay for it."""

from __future__ import annotations

import numpy as np
import pytest

from dgli_vision.classifier import pipeline
from dgli_vision.classifier.classify import (
    TIP_SLACK,
    TIP_WEIGHT,
    Evidence,
    classify_coordinates,
    confidence_of,
    reference_terms,
)
from dgli_vision.classifier.references import load_references
from dgli_vision.core.camera import DEFAULT_INTRINSICS
from dgli_vision.core.classes import VARIANTS
from dgli_vision.core.fold_lines import CORNER_LEG_RANGES, nominal_folds
from dgli_vision.core.layout import default_layout
from dgli_vision.perception.tips import (
    TipParams,
    corner_tips,
    expected_tip_clear,
    settled_stickers,
)
from dgli_vision.sim.dataset import render_sample
from dgli_vision.sources.frames import RGBDFrame

LAYOUT = default_layout()
Z = 0.52  # camera straight down, the table this far away
UP = np.array([0.0, 0.0, -1.0])
CELL = 8


def _camera_points(uv_mm: np.ndarray, mirrored: bool = False) -> np.ndarray:
    """Material points (mm) of a flat napkin on the table, front face up, camera frame
    (m): its centre under the camera, u along the image's x, v up the image (x flipped
    in a mirror)."""
    x = (uv_mm[:, 0] - 200.0) * 1e-3
    y = (200.0 - uv_mm[:, 1]) * 1e-3
    return np.column_stack([-x if mirrored else x, y, np.full(len(x), Z)])


def _cloth_cells(corner_folded: bool, mirrored: bool = False) -> np.ndarray:
    """The napkin's cells: the whole square, or less the triangle of corner A's fold
    (175 mm legs)."""
    h, w = 720 // CELL, 1280 // CELL
    ys, xs = np.mgrid[0:h, 0:w]
    px = np.column_stack([xs.ravel(), ys.ravel()]) * CELL + CELL / 2
    rays = DEFAULT_INTRINSICS.deproject(px, np.full(len(px), Z))
    u = rays[:, 0] * 1e3 * (-1 if mirrored else 1) + 200.0
    v = 200.0 - rays[:, 1] * 1e3
    inside = (u >= 0) & (u <= 400) & (v >= 0) & (v <= 400)
    if corner_folded:
        inside &= u + v >= 175.0
    return inside.reshape(h, w)


def _tips(corner_folded: bool, objects: np.ndarray | None = None, mirrored: bool = False):
    pts = _camera_points(LAYOUT.sticker_uv, mirrored)
    corner_a = np.argmin(
        np.linalg.norm(LAYOUT.sticker_uv[:, None] - LAYOUT.corner_uv[None], axis=2), axis=1
    ) == 0
    pts[corner_a] = np.nan
    heights = np.where(corner_a, np.nan, 2.0)
    turns = np.array([0.0, -1.0, -1.0, -1.0]) if mirrored else np.array([0.0, 1, 1, 1])
    return corner_tips(
        pts, heights, corner_a, np.zeros(16, bool), turns, LAYOUT, DEFAULT_INTRINSICS, UP,
        _cloth_cells(corner_folded, mirrored), CELL, objects, 8,
    )


def test_a_folded_corner_shows_table_where_it_would_lie_flat():
    tips = _tips(corner_folded=True)
    assert tips[0] > 0.95
    assert np.isnan(tips[1:]).all()  # the other corners' stickers tell more


def test_a_flat_corner_under_an_object_shows_cloth_or_nothing():
    # cloth there is no evidence (a flap held up stands over its own place)
    assert np.isnan(_tips(corner_folded=False)[0])
    objects = np.ones((720 // 8 + 1, 1280 // 8 + 1), bool)  # an object over everything
    assert np.isnan(_tips(corner_folded=True, objects=objects)[0])


def test_a_mirrored_napkin_tells_nothing():
    # the napkin fitted front face up would lie face down: its places are not looked at
    assert np.isnan(_tips(corner_folded=True, mirrored=True)).all()


def test_every_fold_clears_the_corners_it_moves_and_no_other():
    # the band lies inside the smallest fold of every class (independent of the
    # nominal sizes the expectation uses)
    smallest = min(lo for pair in CORNER_LEG_RANGES.values() for lo, _ in pair)
    p = TipParams()
    assert p.leg_mm < smallest  # a corner fold's line: u + v = its legs
    assert p.leg_mm - p.inset_mm < 125.0  # a strip 125-140 mm in
    for class_id, variants in VARIANTS.items():
        for variant in variants:
            clear = np.array(expected_tip_clear(class_id, variant, LAYOUT))
            moved = set()
            for fold in nominal_folds(class_id, variant, LAYOUT):
                moved |= set(fold.moved_corners)
            for k, name in enumerate("ABCD"):
                if name in moved:
                    assert clear[k] > 0.9, (class_id, variant, name)
                elif class_id == "12" and name in ("AC" if variant in "BD" else "BD"):
                    # the corners on a diagonal fold's crease: half of it
                    assert 0.3 < clear[k] < 0.7, (class_id, variant, name)
                else:
                    assert clear[k] == 0.0, (class_id, variant, name)


def test_references_that_leave_a_bare_corner_in_place_pay():
    refs = load_references(None)
    coords = np.asarray(LAYOUT.flat_coordinates())
    terms = reference_terms(coords, refs, Evidence(tips=np.array([1.0, np.nan, np.nan, np.nan])))
    by = {(r.class_id, r.variant, r.stage): t for r, t in zip(refs.references, terms.tip)}
    assert by[("01", None, "")] == pytest.approx(TIP_WEIGHT * (1.0 - TIP_SLACK))
    assert by[("02", "A", "")] == 0.0
    assert by[("02", "B", "")] > 0.0
    # a flat napkin with corner A rising leaves A's place bare too
    assert by[("01", None, "rising A over, 50-90 deg")] == 0.0
    # a mirror does not hold to the front-up fit: its reading goes without the term
    assert np.array_equal(terms.mirrored().total(), terms.mirrored().dgli
                          + terms.evidence + terms.mirrored().face)


@pytest.mark.parametrize(
    ("class_id", "k", "seed", "condition"),
    [("06", 0, 9191, "grasp"), ("10", 2, 7373, "gripper")],
)
def test_a_corner_under_the_gripper_is_read(class_id, k, seed, condition):
    # both were "cannot tell" until the table next to the gripper was looked at
    r = render_sample(class_id, k, seed, conditions=(condition,)).result
    frame = RGBDFrame(r.color, r.depth_mm, r.intrinsics)
    result = pipeline.classify_frame(frame, load_references(None))
    assert result.prediction is not None, result.reason
    assert result.prediction.class_id == class_id


def _pairs() -> list[tuple[int, int]]:
    """The two stickers along each edge of each corner (20 mm in from that edge)."""
    uv, corner_of = LAYOUT.sticker_uv, LAYOUT.sticker_corners
    gap = np.abs(uv - LAYOUT.corner_uv[corner_of])
    out = []
    for k in range(4):
        for axis in (0, 1):  # the stickers 20 mm from the edge across ``axis``
            ids = np.flatnonzero((corner_of == k) & np.isclose(gap[:, 1 - axis], 20.0))
            assert len(ids) == 2
            out.append((int(ids[0]), int(ids[1])))
    return out


def test_every_fold_moves_both_stickers_of_an_edge_pair_or_neither():
    uv = LAYOUT.sticker_uv
    for class_id, variants in VARIANTS.items():
        for variant in variants:
            for fold in nominal_folds(class_id, variant, LAYOUT):
                side = fold.on_flap(uv)
                for i, j in _pairs():
                    assert side[i] == side[j], (class_id, variant, fold.word, i, j)
    # and at every size: a corner fold's line (u / legs + v / legs = 1) with legs of
    # 150 mm or more, a strip 125 mm or more in, pass beyond every sticker of the corner
    tip_gap = np.abs(uv - LAYOUT.corner_uv[LAYOUT.sticker_corners])
    smallest = min(lo for pair in CORNER_LEG_RANGES.values() for lo, _ in pair)
    assert tip_gap.sum(axis=1).max() < smallest
    assert tip_gap.max() < 125.0


def _flat_stickers(seen: list[int], moved: dict[int, np.ndarray] | None = None):
    pts = _camera_points(LAYOUT.sticker_uv)
    for k, shift_m in (moved or {}).items():
        pts[k] = pts[k] + shift_m
    hidden = np.setdiff1d(np.arange(16), seen)
    pts[hidden] = np.nan
    heights = np.where(np.isfinite(pts[:, 0]), 2.0, np.nan)
    return settled_stickers(pts, heights, np.array([0.0, 1, 1, 0]), LAYOUT, UP)


def test_a_sticker_at_its_flat_place_settles_the_one_beside_it():
    # corner A under an object but sticker 0; the other corners' stickers seen
    seen = [0, *range(2, 14)]
    settled = _flat_stickers(seen)
    assert settled[[0, 1]].all()  # sticker 1 lies along the same edge
    assert not settled[[14, 15]].any()  # A's other edge: a diagonal crease may part them
    # a sticker displaced (on a flap laid over, say) settles nothing
    settled = _flat_stickers(seen, moved={0: np.array([0.06, 0.05, 0.0])})
    assert not settled[[0, 1, 14, 15]].any()
    # a napkin lying face down (as the front-up fit sees a mirror) settles nothing
    pts = _camera_points(LAYOUT.sticker_uv, mirrored=True)
    assert not settled_stickers(pts, np.full(16, 2.0), None, LAYOUT, UP).any()


def test_settled_stickers_do_not_count_as_unknown_for_the_confidence():
    refs = load_references(None)
    coords = np.asarray(LAYOUT.flat_coordinates())
    unknown = np.zeros(16, bool)
    unknown[[1, 14, 15]] = True
    visible = ~unknown
    loose = classify_coordinates(coords, refs, Evidence(visible=visible, unknown=unknown))
    settled = np.zeros(16, bool)
    settled[[0, 1]] = True
    firm = classify_coordinates(
        coords, refs, Evidence(visible=visible, unknown=unknown), settled=settled
    )
    # the same verdict and margin; only 14 and 15 (A's other edge) stay unknown
    assert (firm.class_id, firm.variant, firm.margin) == (loose.class_id, loose.variant,
                                                          loose.margin)
    known = 15  # coordinates of the 6 segments with both stickers seen
    assert loose.confidence == confidence_of(loose.margin, 3, 16, known)
    assert firm.confidence == confidence_of(firm.margin, 2, 16, known) > loose.confidence


def test_the_pose_that_told_the_tips_settles_the_stickers_without_a_second_fit(monkeypatch):
    """corner_tips_and_pose gives the napkin's pose it told the tips with; settled_stickers
    of the same frame given it does not fit it again, and says what its own fit says."""
    from dgli_vision.perception import tips as tips_module

    pts = _camera_points(LAYOUT.sticker_uv)
    corner_a = np.argmin(
        np.linalg.norm(LAYOUT.sticker_uv[:, None] - LAYOUT.corner_uv[None], axis=2), axis=1
    ) == 0
    pts[corner_a] = np.nan
    heights = np.where(corner_a, np.nan, 2.0)
    turns = np.array([0.0, 1, 1, 1])
    told, pose = tips_module.corner_tips_and_pose(
        pts, heights, corner_a, np.zeros(16, bool), turns, LAYOUT, DEFAULT_INTRINSICS, UP,
        _cloth_cells(True), CELL, None, 8,
    )
    assert told[0] > 0.95 and pose is not None
    alone = settled_stickers(pts, heights, turns, LAYOUT, UP)
    fits = []
    real = tips_module._stay_fit
    monkeypatch.setattr(tips_module, "_stay_fit", lambda *a: fits.append(1) or real(*a))
    assert np.array_equal(settled_stickers(pts, heights, turns, LAYOUT, UP, pose=pose), alone)
    assert fits == [] and alone.any()
