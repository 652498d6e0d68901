"""Lens distortion: intrinsics files that carry it, sticker centres undistorted before they
are lifted to 3D, and ``dgli calibrate --lens-out`` estimating it from the flat napkin."""

from __future__ import annotations

import dataclasses
import json
from types import SimpleNamespace

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.classifier.pipeline import classify_frame, observe
from dgli_vision.classifier.references import load_references
from dgli_vision.cli import main
from dgli_vision.core.camera import DEFAULT_INTRINSICS, Intrinsics, look_at_table
from dgli_vision.core.errors import CalibrationError
from dgli_vision.core.layout import default_layout
from dgli_vision.sim.cloth import sample_state
from dgli_vision.sim.conditions import apply_lens_distortion
from dgli_vision.sim.dataset import VGA_INTRINSICS
from dgli_vision.sim.render import Lighting, SensorModel, render
from dgli_vision.sources.frames import (
    RGBDFrame,
    read_frame,
    read_intrinsics,
    write_color,
    write_depth,
)

LENS = (0.1, -0.03, 0.001, -0.0005, 0.0)
K = np.array([[605.0, 0.0, 639.5], [0.0, 605.0, 359.5], [0.0, 0.0, 1.0]])
EXPECTED = Intrinsics(1280, 720, 605.0, 605.0, 639.5, 359.5, LENS)


def _render_off_centre(class_id: str, seed: int, k1: float, *, height_m: float = 0.40):
    """A napkin filling the view and off to one side (so that its stickers reach towards
    the image border, where the lens moves them most), seen through a lens with ``k1``."""
    rng = np.random.default_rng(seed)
    state = sample_state(class_id, rng=rng)
    centre = state.mesh.xyz[:, :2].mean(axis=0)
    edge = state.sticker_points[2, :2] - state.sticker_points[1, :2]
    yaw = float(np.arctan2(edge[1], edge[0]))  # a napkin edge along the image rows
    aside = 0.15 * np.array([np.cos(yaw), np.sin(yaw)])
    pose = look_at_table(height_m, yaw_rad=yaw, target=(*(centre - aside), 0.0))
    res = render(state, pose, sensor=SensorModel(), rng=seed, lighting=Lighting.random(rng))
    color, depth = apply_lens_distortion(res.color, res.depth_mm, DEFAULT_INTRINSICS, k1)
    return state, res, color, depth


@pytest.fixture(scope="module")
def flat_k1(tmp_path_factory):
    """The flat napkin through a lens with k1 = 0.1, written as a colour + depth pair."""
    folder = tmp_path_factory.mktemp("lens")
    state, res, color, depth = _render_off_centre("01", 5, 0.1)
    write_color(folder / "color.png", color)
    write_depth(folder / "depth.png", depth)
    return folder, res, state.sticker_points[:, 2] * 1e3


# --- calibration files ----------------------------------------------------------------


def _write_opencv(path, ext):
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    storage.write("image_width", 1280)
    storage.write("image_height", 720)
    storage.write("camera_matrix", K)
    storage.write("distortion_coefficients", np.array([LENS]))
    storage.release()


ROS_YAML = """\
image_width: 1280
image_height: 720
camera_name: color
camera_matrix:
  rows: 3
  cols: 3
  data: [605.0, 0.0, 639.5, 0.0, 605.0, 359.5, 0.0, 0.0, 1.0]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [0.1, -0.03, 0.001, -0.0005, 0.0]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
"""


@pytest.mark.parametrize("ext", ["yaml", "json", "xml"])
def test_opencv_calibration_files_give_the_lens(tmp_path, ext):
    path = tmp_path / f"calib.{ext}"
    _write_opencv(path, ext)
    assert read_intrinsics(path) == EXPECTED


def test_ros_camera_info_yaml_and_open3d_json_with_distortion_give_the_lens(tmp_path):
    (tmp_path / "camera_info.yaml").write_text(ROS_YAML)
    assert read_intrinsics(tmp_path / "camera_info.yaml") == EXPECTED
    o3d = {**EXPECTED.to_open3d_dict()}
    assert o3d["distortion"] == list(LENS)
    (tmp_path / "intrinsics.json").write_text(json.dumps(o3d))
    assert read_intrinsics(tmp_path / "intrinsics.json") == EXPECTED
    kd = {"width": 1280, "height": 720, "K": K.tolist(), "D": list(LENS)}
    (tmp_path / "kd.json").write_text(json.dumps(kd))
    assert read_intrinsics(tmp_path / "kd.json") == EXPECTED


@pytest.mark.parametrize(
    ("text", "words"),
    [
        (ROS_YAML.replace("plumb_bob", "equidistant"), ["'equidistant' is not supported"]),
        (ROS_YAML.replace("image_width: 1280\n", ""), ["no image size", "image_width"]),
        (ROS_YAML.replace("cols: 5", "cols: 4"), ["1x4 but holds 5"]),
        ("camera_matrix: [1, 2\n  bad: {", ["neither JSON nor YAML"]),
    ],
)
def test_a_wrong_calibration_file_is_refused_in_one_line(tmp_path, text, words):
    path = tmp_path / "camera_info.yaml"
    path.write_text(text)
    with pytest.raises(CalibrationError) as exc:
        read_intrinsics(path)
    assert str(path) in str(exc.value) and "\n" not in str(exc.value)
    for w in words:
        assert w in str(exc.value)


def test_camera_info_of_a_bag_carries_its_plumb_bob_coefficients():
    from dgli_vision.sources.ros_bags import _intrinsics

    msg = SimpleNamespace(
        width=1280, height=720, k=K.reshape(-1), d=list(LENS), distortion_model="plumb_bob"
    )
    intr, note = _intrinsics(msg)
    assert intr == EXPECTED and "undistorted" in note
    fisheye = SimpleNamespace(**{**vars(msg), "distortion_model": "equidistant"})
    intr, note = _intrinsics(fisheye)
    assert not intr.distorted and "not undistorted" in note


# --- undistorting, projecting -----------------------------------------------------------


def test_projection_distorts_as_opencv_does_and_undistorting_inverts_it():
    rng = np.random.default_rng(0)
    pts = np.column_stack([rng.uniform(-0.5, 0.5, (50, 2)), rng.uniform(0.4, 0.8, 50)])
    seen = EXPECTED.project(pts)
    cv, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), K, np.array(LENS))
    np.testing.assert_allclose(seen, cv.reshape(-1, 2), atol=1e-6)
    ideal = DEFAULT_INTRINSICS.project(pts)
    np.testing.assert_allclose(EXPECTED.undistort_pixels(seen), ideal, atol=1e-3)
    np.testing.assert_allclose(EXPECTED.deproject(ideal, pts[:, 2]), pts, atol=1e-9)


# --- lifting with the lens --------------------------------------------------------------


def test_with_the_coefficients_the_flat_napkin_is_flat_and_true_to_size(flat_k1):
    folder, res, wrinkles_mm = flat_k1
    (folder / "lens.json").write_text(
        json.dumps(
            dataclasses.replace(DEFAULT_INTRINSICS, distortion=(0.1, 0, 0, 0)).to_open3d_dict()
        )
    )
    truth = res.sticker_points_cam
    plain = read_frame(folder / "color.png", folder / "depth.png")
    _, markers, _ = observe(plain)
    err = np.linalg.norm(markers.points - truth, axis=1) * 1e3
    # the fault: stretched by the lens, stickers near the border are 10+ mm off, or so
    # far off that they no longer fit on the napkin and are dropped
    assert not markers.found.all() or np.nanmax(err) > 10.0
    frame = read_frame(folder / "color.png", folder / "depth.png", folder / "lens.json")
    assert frame.intrinsics.distortion[0] == 0.1
    _, markers, obs = observe(frame)
    assert markers.found.all()
    assert (np.linalg.norm(markers.points - truth, axis=1) * 1e3).max() < 3.0
    # flat (but for its wrinkles) on the table, and true to size: every distance between
    # two stickers as on the layout
    assert np.ptp(obs.heights_mm - wrinkles_mm) < 4.0
    uv = default_layout().sticker_uv
    layout_mm = np.linalg.norm(uv[:, None] - uv[None], axis=2)
    seen_mm = np.linalg.norm(markers.points[:, None] - markers.points[None], axis=2) * 1e3
    assert np.abs(seen_mm - layout_mm).max() < 4.0


def test_a_folded_napkin_through_the_lens_is_located_and_classified():
    state, res, color, depth = _render_off_centre("04", 11, 0.12, height_m=0.42)
    lens = dataclasses.replace(DEFAULT_INTRINSICS, distortion=(0.12, 0.0, 0.0, 0.0))
    result = classify_frame(RGBDFrame(color, depth, lens), load_references())
    seen = result.markers.found & res.visible
    assert seen.sum() >= 10
    err = np.linalg.norm(result.markers.points[seen] - res.sticker_points_cam[seen], axis=1)
    assert err.max() * 1e3 < 4.0
    assert result.prediction is not None and result.prediction.class_id == state.class_id


# --- dgli calibrate --lens-out ------------------------------------------------------------


def test_calibrate_recovers_k1_from_the_flat_napkin_and_writes_what_it_reads(flat_k1):
    folder = flat_k1[0]
    out = folder / "estimated.json"
    r = CliRunner().invoke(
        main,
        [
            "calibrate",
            str(folder / "color.png"),
            str(folder / "depth.png"),
            "--lens-out",
            str(out),
        ],
    )
    assert r.exit_code == 0, r.output
    assert "sticker shift by the lens: max" in r.output
    intr = read_intrinsics(out)
    assert abs(intr.distortion[0] - 0.1) < 0.01
    assert (intr.fx, intr.cx) == (DEFAULT_INTRINSICS.fx, DEFAULT_INTRINSICS.cx)
    assert not (folder / "colours.json").exists()  # no -o: no colours file


def test_calibrate_refuses_a_lens_the_view_does_not_determine(tmp_path):
    """A napkin small in the middle of the view: the stickers stay where the lens hardly
    moves them, so k1 is not told; nothing is written and the exit code is 1."""
    state = sample_state("01", rng=3, wrinkles=False, placement=False)
    res = render(state, look_at_table(0.9), intrinsics=VGA_INTRINSICS, rng=3)
    color, depth = apply_lens_distortion(res.color, res.depth_mm, VGA_INTRINSICS, 0.1)
    write_color(tmp_path / "c.png", color)
    write_depth(tmp_path / "d.png", depth)
    (tmp_path / "vga.json").write_text(json.dumps(VGA_INTRINSICS.to_open3d_dict()))
    r = CliRunner().invoke(
        main,
        [
            "calibrate",
            str(tmp_path / "c.png"),
            str(tmp_path / "d.png"),
            "--intrinsics",
            str(tmp_path / "vga.json"),
            "--lens-out",
            str(tmp_path / "lens.json"),
            "-o",
            str(tmp_path / "colours.json"),
        ],
    )
    assert r.exit_code == 1, r.output
    assert "poorly constrained" in r.output
    assert not (tmp_path / "lens.json").exists()
    assert (tmp_path / "colours.json").exists()  # the colours are measured all the same


@pytest.mark.parametrize(("aside_m", "determined"), [(0.0, False), (0.15, True)])
def test_a_lens_with_k2_is_either_recovered_or_called_poorly_constrained(aside_m, determined):
    """Sticker centres seen through k1 = 0.1, k2 = -0.05 (0.1 px noise). With the napkin
    in the middle of the view, k1 and k2 look alike: no k1 is claimed. Off to one side,
    the stickers reach towards the border and both are recovered."""
    from dgli_vision.perception.lens import fit_lens

    uv = default_layout().sticker_uv
    obj = np.column_stack([uv * 1e-3, np.zeros(len(uv))])
    rvec, tvec = np.array([np.pi, 0.03, -0.02]), np.array([aside_m - 0.2, 0.2, 0.40])
    true = (0.1, -0.05, 0.0, 0.0)
    px, _ = cv2.projectPoints(obj, rvec, tvec, K, np.array(true))
    px = px.reshape(-1, 2) + np.random.default_rng(1).normal(0, 0.1, (len(uv), 2))
    z = (obj @ cv2.Rodrigues(rvec)[0].T + tvec)[:, 2]
    est = fit_lens(DEFAULT_INTRINSICS, uv, px, z)
    assert est.constrained == determined, est.problem
    if determined:
        assert abs(est.k1 - 0.1) < 0.01 and abs(est.k2 + 0.05) < 0.01
    else:
        assert "k1 is known only to" in est.problem


def test_calibrate_with_focal_corrects_a_wrong_focal_length(flat_k1, tmp_path):
    folder = flat_k1[0]
    wrong = dataclasses.replace(DEFAULT_INTRINSICS, fx=580.0, fy=580.0)
    (tmp_path / "wrong.json").write_text(json.dumps(wrong.to_open3d_dict()))
    out = tmp_path / "lens.yaml"
    args = [str(folder / "color.png"), str(folder / "depth.png"), "--lens-out", str(out)]
    r = CliRunner().invoke(
        main, ["calibrate", *args, "--intrinsics", str(tmp_path / "wrong.json"), "--focal"]
    )
    assert r.exit_code == 0, r.output
    intr = read_intrinsics(out)  # an OpenCV YAML file, by its extension
    assert abs(intr.fx - 605.0) < 3.0 and abs(intr.distortion[0] - 0.1) < 0.01


BARREL = (-0.2, 0.05, 0.001, 0.0005)


@pytest.mark.parametrize("coefficients", [BARREL, list(BARREL)])
def test_footprint_cells_through_a_lens_measure_what_their_own_corners_give(coefficients):
    """The footprint's cell corners are undistorted once per camera: any block of cells
    measures, to the bit, what undistorting that block's own corners gives (also for
    coefficients in a list, which cannot be kept), and a second camera gets its own."""
    from dgli_vision.perception import footprint

    up = np.array([0.02, -0.15, -0.988])
    up /= np.linalg.norm(up)
    for fx in (605.0, 540.0):
        cam = Intrinsics(1280, 720, fx, fx, 641.0, 358.0, coefficients)
        for shape, origin in (((90, 160), (0, 0)), ((31, 47), (12, 80)), ((1, 1), (89, 159))):
            areas = footprint._cell_areas_mm2(cam, shape, 8, up, -0.55, origin=origin)
            ys, xs = np.mgrid[
                origin[0] : origin[0] + shape[0] + 1, origin[1] : origin[1] + shape[1] + 1
            ]
            ideal = cam.undistort_pixels(np.column_stack([xs.ravel(), ys.ravel()]) * 8 - 0.5)
            d = np.stack(
                [
                    (ideal[:, 0].reshape(xs.shape) - cam.cx) / cam.fx,
                    (ideal[:, 1].reshape(xs.shape) - cam.cy) / cam.fy,
                    np.ones(xs.shape),
                ],
                axis=-1,
            )
            x = -0.55 * d / (d @ up)[..., None]
            cross = np.cross(x[:-1, 1:] - x[:-1, :-1], x[1:, :-1] - x[:-1, :-1])
            assert np.array_equal(areas, np.linalg.norm(cross, axis=-1) * 1e6)
