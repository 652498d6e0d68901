"""Stickers cut by a gripper's edge: taken as seen where their colour shows at their
predicted place, and only there."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from dgli_vision.classifier import pipeline
from dgli_vision.classifier.references import load_references
from dgli_vision.core.camera import DEFAULT_INTRINSICS
from dgli_vision.core.layout import default_layout
from dgli_vision.perception.detections import StickerDetections
from dgli_vision.perception.evidence import HIDDEN, SEEN, UNKNOWN, StickerEvidence
from dgli_vision.perception.lift import Markers3D
from dgli_vision.perception.partial import confirm_partly_hidden
from dgli_vision.sim.dataset import render_sample
from dgli_vision.sources.frames import RGBDFrame

LAYOUT = default_layout()
UP = np.array([0.0, 0.0, -1.0])  # camera looking straight down at a table 0.55 m away
OFFSET = -0.55
RADIUS_PX = 0.5 * LAYOUT.disc_diameter_mm * 1e-3 * DEFAULT_INTRINSICS.fx / 0.55


def _scene(
    cut: str, sid: int = 10
) -> tuple[np.ndarray, StickerDetections, Markers3D, StickerEvidence]:
    """A white napkin, sticker ``sid`` predicted at (700, 300); ``cut``: ``"half"`` its
    disc half under a dark box, ``"none"`` no disc there (the box over white cloth)."""
    img = np.full((720, 1280, 3), 225, np.uint8)
    uv = np.array([700.0, 300.0])
    if cut == "half":
        rgb = LAYOUT.colours_srgb[LAYOUT.sticker_disc[sid]]
        cv2.circle(img, (700, 300), int(RADIUS_PX), tuple(int(c) for c in rgb), -1)
    img[200:400, 700:900] = 25  # the gripper's box over the right half
    found = np.zeros(16, bool)
    found[[0, 1, 2, 3]] = True
    cents = np.full((16, 2), np.nan)
    cents[found] = [[300, 300], [340, 300], [300, 500], [340, 500]]
    det = StickerDetections(cents, np.where(found, 300.0, np.nan), found * 1.0,
                            np.where(found, 550.0, np.nan))
    pts = np.full((16, 3), np.nan)
    pts[found] = DEFAULT_INTRINSICS.deproject(cents[found], np.full(4, 0.55))
    status = np.where(found, SEEN, HIDDEN).astype(np.int8)
    status[sid] = UNKNOWN
    near = np.zeros(16, bool)
    near[sid] = True
    predicted = np.full((16, 2), np.nan)
    predicted[sid] = uv
    reasons = tuple("possibly under an object above the napkin" if k == sid else None
                    for k in range(16))
    ev = StickerEvidence(status, reasons, predicted, True, near)
    return img, det, Markers3D(pts), ev


def _confirm(img, det, markers, ev):
    lut = np.repeat(np.arange(256, dtype=np.uint8)[:, None, None], 3, axis=2)
    return confirm_partly_hidden(
        img, lut, det, markers, ev, DEFAULT_INTRINSICS, (UP, OFFSET), LAYOUT
    )


def test_a_disc_half_under_a_box_is_seen_at_its_predicted_place_on_the_table():
    det, markers, ev = _confirm(*_scene("half"))
    assert ev.seen[10] and not ev.unknown[10] and ev.reasons[10] is None
    assert np.allclose(det.centroids[10], [700, 300])
    # on the table plane (the stickers around it lie on it), under the predicted pixel
    assert markers.points[10] @ UP == pytest.approx(OFFSET, abs=1e-9)
    assert np.allclose(DEFAULT_INTRINSICS.project(markers.points[10:11])[0], [700, 300])


def test_white_cloth_at_the_predicted_place_leaves_the_sticker_unknown():
    img, det, markers, ev = _scene("none")
    d2, m2, e2 = _confirm(img, det, markers, ev)
    assert e2.unknown[10] and not d2.found[10] and not m2.found[10]


def test_the_colour_of_a_neighbour_found_there_is_not_taken_for_the_sticker():
    img, det, markers, ev = _scene("half", sid=10)
    same = next(k for k in range(16) if LAYOUT.sticker_disc[k] == LAYOUT.sticker_disc[10]
            and k != 10)
    cents = det.centroids.copy()
    cents[same] = [700 - RADIUS_PX, 300]  # a sticker of that colour found right beside
    det = StickerDetections(cents, det.areas, det.scores, det.depth_mm)
    _, _, e2 = _confirm(img, det, markers, ev)
    assert e2.unknown[10]


def test_a_gripper_over_a_flat_corner_no_longer_leaves_a_folded_corner_as_likely():
    """Rendered: a gripper's box cuts a blue sticker of a flat napkin's corner; without
    it, 02 corner-over was the best guess (the corner may be folded under the arm)."""
    sample = render_sample("01", 0, 7373, conditions=("gripper",))
    r = sample.result
    result = pipeline.classify_frame(
        RGBDFrame(r.color, r.depth_mm, r.intrinsics), load_references()
    )
    cut = np.flatnonzero((r.visible_fraction > 0.2) & (r.visible_fraction < 0.8))
    obs = result.observation
    taken = [k for k in cut if obs.visible[k]]
    assert taken, "the cut sticker is taken as seen"
    err = np.linalg.norm(obs.points_m[taken] - r.sticker_points_cam[taken], axis=1)
    assert err.max() < 3e-3  # within 3 mm of where it is
    assert result.best_guess.class_id == "01"  # 02 corner-over before


# --- stickers confirmed at their place by their own (disc, dot) pair -----------------


def _washed(sid: int, keep: str):
    """A rendered flat napkin with sticker ``sid`` painted over with the napkin's
    brightest white as a lamp's streak mirrored in the laminate leaves it: ``keep``
    ``"dot"`` the streak over the disc's lower part and its sheen paling the rest to
    pastel (the dot and the upper rim left, as a bar lamp leaves a laminated disc),
    ``"crescent"`` over all but a thin crescent of the rim (the dot gone too)."""
    from dgli_vision.perception.napkin import find_napkin

    r = render_sample("01", 0, 5311).result
    color = r.color.copy()
    u, v = r.intrinsics.project(r.sticker_points_cam[sid : sid + 1])[0]
    radius = 0.5e-3 * LAYOUT.disc_diameter_mm * r.intrinsics.fx / r.sticker_points_cam[sid, 2]
    napkin = find_napkin(color, r.depth_mm, r.intrinsics)
    white = np.percentile(color[:: napkin.stride, :: napkin.stride][napkin.cloth], 95, axis=0)
    yy, xx = np.mgrid[: color.shape[0], : color.shape[1]]
    d = np.hypot(xx - u, yy - v)
    if keep == "dot":
        sheen = (d > 0.45 * radius) & (d < radius + 3)
        color[sheen] = (0.3 * color[sheen] + 0.7 * white).astype(np.uint8)
        streak = (yy > v + 0.5 * radius) & (d < radius + 3)
    else:
        streak = np.hypot(xx - u - 0.45 * radius, yy - v) < radius + 3
    color[streak] = white.astype(np.uint8)
    return r, RGBDFrame(color, r.depth_mm, r.intrinsics), np.array([u, v])


def test_a_disc_half_taken_by_a_lamps_streak_is_found_at_its_place_by_its_dot():
    from dgli_vision.perception.detect import detect_stickers, find_washed_out
    from dgli_vision.perception.napkin import find_napkin
    from dgli_vision.perception.observe import observe

    sid = 2  # yellow disc, blue dot
    r, frame, uv = _washed(sid, "dot")
    args = (frame.color, frame.depth_mm, frame.intrinsics, LAYOUT)
    napkin = find_napkin(*args[:3])
    first = detect_stickers(*args, napkin=napkin)
    again = find_washed_out(*args, first, napkin=napkin)
    assert not again.found[sid]  # both searches refuse what the streak leaves
    det, markers, obs = observe(frame, LAYOUT)
    assert det.found[sid] and obs.evidence.seen[sid]
    assert np.linalg.norm(det.centroids[sid] - uv) < 1.5  # at the dot's centre
    assert np.linalg.norm(markers.points[sid] - r.sticker_points_cam[sid]) < 4e-3
    assert det.found.sum() == 16  # and no other sticker given up for it


def test_a_crescent_without_its_dot_is_not_taken_for_the_sticker():
    from dgli_vision.perception.observe import observe

    _, frame, _ = _washed(2, "crescent")
    det, _, _ = observe(frame, LAYOUT)
    assert not det.found[2]


def _yellow_scene(other_px: tuple[float, float]):
    """White cloth; sticker 5 (yellow disc, yellow dot: its colour names no sticker
    alone) drawn whole at its predicted place (700, 300); sticker 4 (yellow, red dot)
    missing, predicted at ``other_px``; four stickers found around."""
    img = np.full((720, 1280, 3), 225, np.uint8)
    cv2.circle(img, (700, 300), int(RADIUS_PX), LAYOUT.colours_srgb["yellow"], -1)
    found = np.zeros(16, bool)
    found[[0, 1, 10, 11]] = True
    cents = np.full((16, 2), np.nan)
    cents[found] = [[300, 300], [340, 300], [300, 500], [340, 500]]
    det = StickerDetections(cents, np.where(found, 300.0, np.nan), found * 0.9,
                            np.where(found, 550.0, np.nan))
    pts = np.full((16, 3), np.nan)
    pts[found] = DEFAULT_INTRINSICS.deproject(cents[found], np.full(4, 0.55))
    predicted = np.full((16, 2), np.nan)
    predicted[5], predicted[4] = (700.0, 300.0), other_px
    status = np.where(found, SEEN, HIDDEN).astype(np.int8)
    ev = StickerEvidence(status, (None,) * 16, predicted)
    return img, det, Markers3D(pts), ev


@pytest.mark.parametrize(("other", "taken"), [((700.0 + 1.5 * RADIUS_PX, 300.0), False),
                                              ((700.0 + 6 * RADIUS_PX, 300.0), True)])
def test_a_yellow_dot_on_yellow_is_taken_only_where_no_other_yellow_sticker_may_lie(
    other, taken
):
    """Where two identities fit (another yellow sticker predicted beside it), none is
    given; alone, the disc is that sticker."""
    from dgli_vision.perception.napkin import NapkinView
    from dgli_vision.perception.partial import confirm_at_place

    img, det, markers, ev = _yellow_scene(other)
    lut = np.repeat(np.arange(256, dtype=np.uint8)[:, None, None], 3, axis=2)
    napkin = NapkinView(np.ones(3), lut, np.zeros((1, 1), bool), np.zeros((1, 1), bool), 8)
    depth = np.full(img.shape[:2], 550, np.uint16)
    d2, _, e2 = confirm_at_place(
        img, depth, napkin, (det, markers, ev), DEFAULT_INTRINSICS, LAYOUT
    )
    assert bool(d2.found[5]) is taken and not d2.found[4]
    if taken:
        assert np.allclose(d2.centroids[5], [700, 300], atol=0.5) and e2.seen[5]
