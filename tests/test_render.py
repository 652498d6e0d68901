"""The renderer against analytic truth: depth, sticker colours, determinism, conventions."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from dgli_vision.core.camera import DEFAULT_INTRINSICS, look_at_table
from dgli_vision.core.layout import default_layout
from dgli_vision.perception.detect import hue_of
from dgli_vision.sim.cloth import sample_state
from dgli_vision.sim.render import Lighting, SensorModel, render

LAYOUT = default_layout()
CLEAN = SensorModel(enabled=False)


@pytest.fixture(scope="module")
def flat():
    return sample_state("01", rng=1, wrinkles=False, placement=False)


def test_projection_round_trip_uses_pixel_centres():
    intr = DEFAULT_INTRINSICS
    pts = np.array([[0.0, 0.0, 0.5], [0.1, -0.05, 0.7]])
    pix = intr.project(pts)
    np.testing.assert_allclose(pix[0], [639.5, 359.5])  # the optical axis: between pixels
    np.testing.assert_allclose(intr.deproject(pix, pts[:, 2]), pts)
    rays = intr.ray_directions()
    np.testing.assert_allclose(rays[0, 0], [-639.5 / 605, -359.5 / 605, 1.0])


def test_flat_napkin_depth_equals_camera_height(flat):
    pose = look_at_table(0.52)
    clean = render(flat, pose, sensor=CLEAN)
    # Pixels near the image centre see the napkin (it is centred under the camera).
    centre = clean.depth_mm[340:380, 620:660].astype(float)
    assert np.all(np.abs(centre - 520) <= 1)
    noisy = render(flat, pose, rng=3)
    patch = noisy.depth_mm[300:420, 560:720].astype(float)
    patch = patch[patch > 0]
    assert abs(np.median(patch) - 520) <= 1
    assert patch.std() < 3


def test_tilted_camera_depth_matches_geometry(flat):
    pose = look_at_table(0.6, tilt_rad=np.radians(12), tilt_direction_rad=0.5)
    clean = render(flat, pose, sensor=CLEAN)
    # The optical axis meets the table origin at distance 0.6 / cos(12 deg).
    expected = 600 / np.cos(np.radians(12))
    assert abs(float(clean.depth_mm[360, 640]) - expected) <= 1.5


def nearest_colour(rgb):
    h = cv2.cvtColor(np.uint8([[rgb]]), cv2.COLOR_RGB2HSV)[0, 0, 0]
    names = list(LAYOUT.colours_srgb)
    hues = np.array([hue_of(LAYOUT.colours_srgb[n]) for n in names])
    d = np.abs(hues - int(h))
    return names[int(np.argmin(np.minimum(d, 180 - d)))]


@pytest.mark.parametrize("class_id", ["01", "05", "11"])
def test_visible_sticker_centres_land_on_their_colours(class_id):
    state = sample_state(class_id, rng=4)
    pose = look_at_table(
        0.55,
        tilt_rad=np.radians(8),
        tilt_direction_rad=2.0,
        yaw_rad=1.0,
        target=(*state.mesh.xyz[:, :2].mean(axis=0), 0.0),
    )
    result = render(state, pose, sensor=CLEAN, lighting=Lighting.random(np.random.default_rng(5)))
    assert result.visible.sum() >= 8
    radius = 0.8 * LAYOUT.disc_diameter_mm / 2
    ring = np.array(
        [
            [radius * np.cos(a), radius * np.sin(a)]
            for a in np.linspace(0, 2 * np.pi, 6, endpoint=False)
        ]
    )
    for k in np.flatnonzero(result.visible_fraction == 1.0):
        u, v = np.rint(DEFAULT_INTRINSICS.project(result.sticker_points_cam[k : k + 1])[0]).astype(
            int
        )
        assert nearest_colour(result.color[v, u]) == LAYOUT.sticker_dot[k]
        ring_world = state.mesh.interpolate(LAYOUT.sticker_uv[k] + ring)
        ring_pix = np.rint(DEFAULT_INTRINSICS.project(pose.world_to_camera(ring_world))).astype(
            int
        )
        colours = [nearest_colour(result.color[y, x]) for x, y in ring_pix]
        assert colours.count(LAYOUT.sticker_disc[k]) >= 5


def test_hidden_stickers_are_not_seen(flat):
    state = sample_state("03", "B", rng=2, wrinkles=False)
    pose = look_at_table(0.55, target=(*state.mesh.xyz[:, :2].mean(axis=0), 0.0))
    result = render(state, pose, sensor=CLEAN)
    np.testing.assert_array_equal(result.visible, state.visible)


def test_render_is_deterministic_for_a_seed(flat):
    pose = look_at_table(0.5, yaw_rad=0.3)
    a = render(flat, pose, rng=9)
    b = render(flat, pose, rng=9)
    c = render(flat, pose, rng=10)
    np.testing.assert_array_equal(a.color, b.color)
    np.testing.assert_array_equal(a.depth_mm, b.depth_mm)
    assert not np.array_equal(a.color, c.color)


def test_sensor_model_adds_noise_dropouts_and_quantisation(flat):
    pose = look_at_table(0.5)
    clean = render(flat, pose, sensor=CLEAN)
    noisy = render(flat, pose, rng=1)
    assert clean.depth_mm.dtype == np.uint16 and (clean.depth_mm > 0).all()
    dropped = (noisy.depth_mm == 0).mean()
    assert 0.0005 < dropped < 0.05
    diff = noisy.color.astype(int) - clean.color.astype(int)
    assert diff.std() > 1.0
