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
