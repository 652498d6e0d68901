"""Detection and lifting: synthetic discs with known centres, and renders vs truth."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from dgli_vision.classifier.pipeline import observe
from dgli_vision.core.camera import DEFAULT_INTRINSICS, look_at_table
from dgli_vision.core.layout import default_layout
from dgli_vision.perception import detect_stickers, estimate_table_normal, lift_stickers
from dgli_vision.perception.detections import Rejection, RejectionKind
from dgli_vision.sim.cloth import sample_state
from dgli_vision.sim.render import Lighting, render
from dgli_vision.sources.frames import RGBDFrame

LAYOUT = default_layout()
INTR = DEFAULT_INTRINSICS


def draw_sticker(img, centre, radius_px, disc, dot):
    """Anti-aliased sticker drawn at sub-pixel centre (shift = 4 fractional bits)."""
    c = (int(round(centre[0] * 16)), int(round(centre[1] * 16)))
    cv2.circle(img, c, int(round(radius_px * 16)), LAYOUT.colours_srgb[disc], -1, cv2.LINE_AA, 4)
    cv2.circle(
        img, c, int(round(radius_px * 0.4 * 16)), LAYOUT.colours_srgb[dot], -1, cv2.LINE_AA, 4
    )


def synthetic(stickers, depth_mm=500):
    img = np.full((INTR.height, INTR.width, 3), 215, np.uint8)
    radius = LAYOUT.disc_diameter_mm / 2 * INTR.fx / depth_mm
    for sid, centre in stickers:
        draw_sticker(img, centre, radius, LAYOUT.sticker_disc[sid], LAYOUT.sticker_dot[sid])
    return img, np.full(img.shape[:2], depth_mm, np.uint16)


def test_discs_at_known_centres_are_found_with_identity_and_subpixel_centroids():
    rng = np.random.default_rng(0)
    stickers = [
        (sid, (100 + 70 * sid + rng.uniform(0, 1), 200 + rng.uniform(0, 300))) for sid in range(16)
    ]
    img, depth = synthetic(stickers)
    det = detect_stickers(img, depth, INTR, LAYOUT)
    assert det.found.all()
    for sid, centre in stickers:
        np.testing.assert_allclose(det.centroids[sid], centre, atol=0.15)


def test_only_the_stickers_asked_for_are_reported_as_a_full_search_finds_them():
    rng = np.random.default_rng(1)
    stickers = [
        (sid, (100 + 70 * sid + rng.uniform(0, 1), 200 + rng.uniform(0, 300))) for sid in range(16)
    ]
    stickers.append((3, (640.0, 620.0)))  # a second blob for sticker 3 (lower score or not)
    img, depth = synthetic(stickers)
    every = detect_stickers(img, depth, INTR, LAYOUT)
    wanted = np.zeros(16, bool)
    wanted[[2, 3, 11]] = True
    det = detect_stickers(img, depth, INTR, LAYOUT, report=wanted)
    np.testing.assert_array_equal(det.found, wanted & every.found)
    np.testing.assert_array_equal(det.centroids[wanted], every.centroids[wanted])
    np.testing.assert_array_equal(det.areas[wanted], every.areas[wanted])
    np.testing.assert_array_equal(det.scores[wanted], every.scores[wanted])
    assert not det.scores[~wanted].any() and det.rejected == ()


def test_an_identity_is_never_given_twice():
    img, depth = synthetic([(3, (300.2, 300.7)), (3, (700.0, 400.0))])
    det = detect_stickers(img, depth, INTR, LAYOUT)
    assert det.found.sum() == 1
    assert any("second blob for sticker 3" in r.reason for r in det.rejected)


def test_blobs_that_cannot_be_stickers_are_rejected_with_a_reason():
    img, depth = synthetic([(5, (300.0, 300.0))])
    cv2.circle(img, (800, 300), 120, LAYOUT.colours_srgb["blue"], -1)  # far too large
    cv2.rectangle(img, (200, 500), (290, 510), LAYOUT.colours_srgb["green"], -1)  # a strip
    det = detect_stickers(img, depth, INTR, LAYOUT)
    assert det.found.sum() == 1 and det.found[5]
    reasons = " ".join(r.reason for r in det.rejected)
    assert "too large" in reasons and "not disc-shaped" in reasons
    by_kind = {r.kind: r for r in det.rejected}
    large = by_kind[RejectionKind.TOO_LARGE]
    # the values measured, not only words: a disc of 120 px radius covers many discs
    # of the size expected at the synthetic depth (500 mm)
    assert large.size_ratio == large.values["ratio"] and large.size_ratio > 10
    assert large.values["z_mm"] == pytest.approx(500, abs=1)
    strip = by_kind[RejectionKind.NOT_DISC_SHAPED]
    assert strip.size_ratio is None and strip.values["elongation"] > 2.5


def test_a_rejection_message_is_made_from_its_kind_and_values():
    k = RejectionKind
    cases = [
        (k.OBLIQUE, {"foreshortening": 0.123}, "seen too obliquely (foreshortened 0.12)"),
        (k.TOO_SMALL, {"z_mm": 612.4, "ratio": 0.456}, "too small for a sticker at 612 mm "
         "(0.46 of a disc)"),
        (k.TOO_SMALL, {"z_mm": 612.4, "ratio": 0.456, "full_resolution": True},
         "too small for a sticker at 612 mm (0.46 of a disc at full resolution)"),
        (k.TOO_LARGE, {"z_mm": 600.0, "ratio": 31.5}, "too large for a sticker at 600 mm "
         "(31.50 discs)"),
        (k.NO_SUCH_STICKER, {"disc": "red", "dot": "red"}, "no sticker is red with a red dot"),
        (k.SECOND_BLOB, {"sticker": 3}, "second blob for sticker 3 (lower score)"),
        (k.NO_DOT_COLOUR, {}, "no dot colour inside"),
    ]
    for kind, values, words in cases:
        assert Rejection((1.0, 2.0), 30.0, kind, values).reason == words


def test_nothing_found_on_an_empty_table():
    img = np.full((INTR.height, INTR.width, 3), (120, 110, 100), np.uint8)
    det = detect_stickers(img, np.full(img.shape[:2], 600, np.uint16), INTR, LAYOUT)
    assert not det.found.any() and det.centroids.shape == (16, 2)


def scene(class_id, seed, *, height, tilt_deg):
    rng = np.random.default_rng(seed)
    state = sample_state(class_id, rng=rng)
    pose = look_at_table(
        height,
        tilt_rad=np.radians(tilt_deg),
        tilt_direction_rad=rng.uniform(0, 6.3),
        yaw_rad=rng.uniform(0, 6.3),
        target=(*state.mesh.xyz[:, :2].mean(axis=0), 0.0),
    )
    result = render(state, pose, lighting=Lighting.random(rng), rng=rng)
    return state, pose, result


@pytest.mark.parametrize(
    ("class_id", "seed", "height", "tilt"),
    [
        ("01", 1, 0.45, 0),
        ("04", 2, 0.52, 15),
        ("07", 3, 0.8, 10),
        ("10", 4, 0.6, 5),
        ("12", 5, 0.7, 14),
    ],
)
def test_render_detect_deproject_matches_truth(class_id, seed, height, tilt):
    _, pose, result = scene(class_id, seed, height=height, tilt_deg=tilt)
    frame = RGBDFrame(result.color, result.depth_mm, INTR)
    det, markers, obs = observe(frame, LAYOUT)
    fully_seen = result.visible_fraction == 1.0
    assert det.found[fully_seen].all()
    assert not det.found[result.visible_fraction < 0.3].any()
    err_mm = (
        np.linalg.norm(markers.points[det.found] - result.sticker_points_cam[det.found], axis=1)
        * 1e3
    )
    assert np.median(err_mm) <= 3.0
    # The table normal is the world's up seen from the camera.
    up_cam = pose.rotation.T @ np.array([0.0, 0.0, 1.0])
    assert np.degrees(np.arccos(np.clip(obs.up @ up_cam, -1, 1))) < 1.0


def test_sticker_depth_is_robust_to_a_missing_centre_reading():
    img, depth = synthetic([(0, (400.0, 300.0))], depth_mm=600)
    depth[295:306, 395:406] = 0  # no reading around the centroid
    det = detect_stickers(img, depth, INTR, LAYOUT)
    markers = lift_stickers(det, INTR)
    assert markers.found[0]
    assert markers.points[0, 2] == pytest.approx(0.6)


def test_table_normal_needs_depth():
    with pytest.raises(ValueError, match="valid depth"):
        estimate_table_normal(np.zeros((720, 1280), np.uint16), INTR)


LENS = (0.12, -0.25, 0.001, -0.002)


@pytest.mark.parametrize("coefficients", [LENS, list(LENS)])
def test_table_plane_through_a_lens_is_the_true_plane_for_every_camera_and_frame(coefficients):
    """The plane's sample rays are kept per camera: a tilted table seen through a lens
    (coefficients as a tuple, or as a list that cannot be a cache key) is found at its
    true tilt and offset, by a second camera as well, and again for a closer table."""
    from dgli_vision.core.camera import Intrinsics
    from dgli_vision.perception.lift import estimate_table_plane

    normal = np.array([0.0, -np.sin(np.radians(12)), -np.cos(np.radians(12))])
    for cam in (
        Intrinsics(320, 240, 300.0, 300.0, 159.5, 119.5, coefficients),
        Intrinsics(320, 240, 280.0, 285.0, 162.0, 118.0, coefficients),
    ):
        vv, uu = np.mgrid[0:240, 0:320]
        ideal = cam.undistort_pixels(np.column_stack([uu.ravel(), vv.ravel()]))
        rays = np.column_stack(
            [(ideal[:, 0] - cam.cx) / cam.fx, (ideal[:, 1] - cam.cy) / cam.fy, np.ones(len(ideal))]
        )
        for offset in (-0.6, -0.45):  # normal @ x of the table's points, metres
            depth = (offset / (rays @ normal) * 1e3).reshape(240, 320)
            up, found = estimate_table_plane(np.rint(depth).astype(np.uint16), cam, stride=8)
            assert np.degrees(np.arccos(min(1.0, abs(up @ normal)))) < 0.5
            assert abs(abs(found) - abs(offset)) < 0.002



def test_table_plane_samples_coarsely_only_where_depth_is_dense():
    """A dense frame is fitted on every 24th pixel, at the plane every 16th pixel gives
    (within noise); a frame with few readings keeps the finer sampling, plane and all."""
    from dgli_vision.perception.lift import estimate_table_plane

    rng = np.random.default_rng(3)
    normal = np.array([0.0, -np.sin(np.radians(10)), -np.cos(np.radians(10))])
    vv, uu = np.mgrid[0:720, 0:1280]
    rays = np.stack([(uu - INTR.cx) / INTR.fx, (vv - INTR.cy) / INTR.fy, np.ones(uu.shape)], -1)
    depth = -0.55 / (rays @ normal) * 1e3 + rng.normal(0.0, 1.5, uu.shape)
    depth[200:420, 500:760] -= 40.0  # a box on the table
    depth = np.rint(depth).astype(np.uint16)
    fine = estimate_table_plane(depth, INTR, coarse_stride=None)
    coarse = estimate_table_plane(depth, INTR)
    assert np.degrees(np.arccos(min(1.0, coarse[0] @ fine[0]))) < 0.05
    assert abs(coarse[1] - fine[1]) < 2e-4
    assert np.degrees(np.arccos(min(1.0, abs(coarse[0] @ normal)))) < 0.1
    sparse = depth.copy()
    sparse[rng.random(depth.shape) < 0.6] = 0  # 40% of readings: 650 every 24th pixel
    fine = estimate_table_plane(sparse, INTR, coarse_stride=None)
    kept = estimate_table_plane(sparse, INTR)
    assert np.array_equal(kept[0], fine[0]) and kept[1] == fine[1]

def test_a_sliver_of_a_covered_sticker_is_rejected_a_mostly_visible_one_kept():
    img, depth = synthetic([(7, (300.0, 300.0)), (9, (700.0, 300.0))])
    radius = LAYOUT.disc_diameter_mm / 2 * INTR.fx / 500
    # A flap (white) covers all but a sliver of sticker 7, and a quarter of sticker 9.
    cv2.rectangle(img, (int(300 - radius) + 8, 200), (400, 400), (215, 215, 215), -1)
    cv2.rectangle(img, (int(700 + radius / 2), 200), (800, 400), (215, 215, 215), -1)
    det = detect_stickers(img, depth, INTR, LAYOUT)
    assert not det.found[7]
    assert det.found[9]
