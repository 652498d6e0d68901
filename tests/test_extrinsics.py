"""--extrinsics: the answer's 3D points in the robot's base frame (a known transform
moves them where expected), and a transform that is not rigid refused in one line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.cli import main
from dgli_vision.core.errors import InvalidInputError
from dgli_vision.core.extrinsics import in_frame, parse_extrinsics, read_extrinsics

SAMPLES = Path(__file__).resolve().parents[1] / "sample_images"
FLAT = [str(SAMPLES / "01_000_color.png"), str(SAMPLES / "01_000_depth.png")]
FOLDED = [str(SAMPLES / "05_000_color.png"), str(SAMPLES / "05_000_depth.png")]

#: a quarter turn about z and a translation: camera (x, y, z) -> (0.5 - y, x - 0.2, z + 0.1)
MATRIX = [[0, -1, 0, 0.5], [1, 0, 0, -0.2], [0, 0, 1, 0.1], [0, 0, 0, 1]]
TF_YAML = """\
header:
  stamp: {sec: 0, nanosec: 0}
  frame_id: base_link
child_frame_id: camera_color_optical_frame
transform:
  translation: {x: 0.5, y: -0.2, z: 0.1}
  rotation: {x: 0.0, y: 0.0, z: 0.7071067811865476, w: 0.7071067811865476}
---
"""


def _moved(p: list[float]) -> np.ndarray:
    m = np.array(MATRIX, dtype=float)
    return m[:3, :3] @ np.asarray(p) + m[:3, 3]


def _json(*args: str, code: int = 0) -> dict:
    res = CliRunner().invoke(main, list(args))
    assert res.exit_code == code, res.output
    assert "Traceback" not in res.output
    return json.loads(res.stdout)


@pytest.fixture(scope="module")
def files(tmp_path_factory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("extrinsics")
    out = {"matrix": d / "hand_eye.json", "tf": d / "tf.yaml"}
    out["matrix"].write_text(json.dumps(MATRIX))
    out["tf"].write_text(TF_YAML)
    return out


@pytest.mark.parametrize(("which", "frame"), [("matrix", "base"), ("tf", "base_link")])
def test_a_plans_grasp_and_place_are_the_camera_points_transformed(files, which, frame):
    plan = ["plan", *FLAT, "--goal", "02/A", "--json"]
    camera = _json(*plan)
    base = _json(*plan, "--extrinsics", str(files[which]))
    assert camera["frame"] == "camera" and base["frame"] == frame
    for cam, rob in zip(camera["steps"], base["steps"]):
        for key in ("grasp", "place"):
            assert np.allclose(rob[key]["point"], _moved(cam[key]["point"]), atol=1e-4)
        assert rob["grasp"]["pixel"] == cam["grasp"]["pixel"]  # a pixel is no 3D point
        for a, b in zip(cam["fold_line"], rob["fold_line"]):
            assert np.allclose(b, _moved(a), atol=1e-4)
        assert rob["lift_height"] == cam["lift_height"]
    # the direction of the lift, the table's normal, turned (not moved) into the frame
    assert np.allclose(base["up"], np.array(MATRIX, float)[:3, :3] @ camera["up"], atol=1e-5)


def test_a_verdicts_corners_folds_and_table_normal_are_in_the_base_frame(files):
    camera = _json("classify", *FOLDED, "--json")
    base = _json("classify", *FOLDED, "--json", "--extrinsics", str(files["matrix"]))
    assert (camera["frame"], base["frame"]) == ("camera", "base")
    for name, c in camera["corners"].items():
        if c["point"] is not None:
            assert np.allclose(base["corners"][name]["point"], _moved(c["point"]), atol=1e-4)
    assert camera["folds"] and camera["folds"][0]["line"] is not None
    assert np.allclose(base["folds"][0]["line"], [_moved(p) for p in camera["folds"][0]["line"]],
                       atol=1e-4)
    assert base["folds"][0]["legs_mm"] == camera["folds"][0]["legs_mm"]  # on the napkin
    turned = np.array(MATRIX, dtype=float)[:3, :3] @ camera["up"]
    assert np.allclose(base["up"], turned, atol=1e-5)
    assert base["coordinates"] == camera["coordinates"]  # the dGLI is the cloth's own


def test_verify_names_its_frame(files):
    data = _json("verify", *FOLDED, "--expect", "05", "--json",
                 "--extrinsics", str(files["tf"]))
    assert data["frame"] == "base_link" and data["outcome"] == "success"


@pytest.mark.parametrize(
    ("matrix", "says"),
    [
        ([[1.1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], "is not a rotation"),
        ([[-1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], "is a reflection"),
        ([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0.5, 1]], "last row"),
        ([[1, 0, 0], [0, 1, 0], [0, 0, 1]], "is a 3 x 3 matrix"),
    ],
)
def test_a_transform_that_is_not_rigid_is_refused_in_one_line(tmp_path, matrix, says):
    path = tmp_path / "hand_eye.json"
    path.write_text(json.dumps(matrix))
    res = CliRunner().invoke(main, ["classify", *FLAT, "--extrinsics", str(path)])
    assert res.exit_code == 2
    assert "Traceback" not in res.output and res.stdout == ""
    (line,) = res.stderr.strip().splitlines()
    assert line.startswith(f"error: extrinsics '{path}'") and says in line


def test_a_quaternion_of_another_length_is_refused(tmp_path):
    path = tmp_path / "tf.yaml"
    path.write_text(TF_YAML.replace("w: 0.7071067811865476", "w: 0.9"))
    res = CliRunner().invoke(main, ["plan", *FLAT, "--goal", "02/A", "--extrinsics", str(path)])
    assert res.exit_code == 2 and "Traceback" not in res.output
    assert "unit quaternion" in res.stderr and str(path) in res.stderr


def test_the_forms_agree_and_a_tf_message_of_one_transform_is_read(files, tmp_path):
    a, b = read_extrinsics(files["matrix"]), read_extrinsics(files["tf"])
    assert np.allclose(a.matrix, b.matrix, atol=1e-12)
    named = parse_extrinsics({"matrix": MATRIX, "frame": "world"}, "x")
    assert named.frame == "world" and np.allclose(named.matrix, a.matrix)
    tf_msg = tmp_path / "tf_static.json"
    tf_msg.write_text(json.dumps({"transforms": [{
        "header": {"frame_id": "/odom"}, "child_frame_id": "cam",
        "transform": {"translation": {"x": 0.5, "y": -0.2, "z": 0.1},
                      "rotation": {"x": 0, "y": 0, "z": 0.7071067811865476,
                                   "w": 0.7071067811865476}}}]}))
    c = read_extrinsics(tf_msg)
    assert c.frame == "odom" and np.allclose(c.matrix, a.matrix, atol=1e-12)
    with pytest.raises(InvalidInputError, match="holds 2 transforms"):
        parse_extrinsics({"transforms": [{}, {}]}, "two.yaml")


def test_in_frame_moves_only_3d_points_and_leaves_its_input_as_it_was():
    data = {"corners": {"A": {"point": [0.0, 0.0, 0.5], "pixel": [1.0, 2.0]}},
            "steps": [{"fold_line": [[0, 0, 0], [1, 0, 0]], "crease_mm": [[0, 1], [2, 3]]}],
            "up": [0.0, 0.0, -1.0]}
    ext = parse_extrinsics(MATRIX, "x")
    out = in_frame(data, ext)
    assert out["corners"]["A"] == {"point": [0.5, -0.2, 0.6], "pixel": [1.0, 2.0]}
    assert out["steps"][0]["fold_line"] == [[0.5, -0.2, 0.1], [0.5, 0.8, 0.1]]
    assert out["steps"][0]["crease_mm"] == [[0, 1], [2, 3]]
    assert out["up"] == [0.0, 0.0, -1.0] and out["frame"] == "base"
    assert data["corners"]["A"]["point"] == [0.0, 0.0, 0.5] and "frame" not in data


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    import shutil

    folder = tmp_path_factory.mktemp("recording")
    for name in ("01_000", "05_000"):
        for kind in ("color", "depth"):
            shutil.copy(SAMPLES / f"{name}_{kind}.png", folder / f"{name}_{kind}.png")
    shutil.copy(SAMPLES / "intrinsics.json", folder / "intrinsics.json")
    return folder


def _lines(*args: str) -> list[dict]:
    res = CliRunner().invoke(main, ["watch", *args, "--jsonl"])
    assert res.exit_code == 0, res.output
    assert "Traceback" not in res.output
    return [json.loads(t) for t in res.stdout.splitlines()][:-1]  # the summary left out


def test_watch_gives_each_frames_corners_in_the_base_frame(files, recording):
    camera = _lines("--bag", str(recording), "-j", "1", "--fast")
    base = _lines("--bag", str(recording), "-j", "1", "--fast", "--extrinsics", str(files["tf"]))
    # from worker processes, the same lines (but for their latencies)
    pool = _lines("--bag", str(recording), "-j", "2", "--fast", "--extrinsics", str(files["tf"]))
    assert len(camera) == len(base) == len(pool) == 2
    for cam, rob, far in zip(camera, base, pool):
        assert (cam["points_frame"], rob["points_frame"]) == ("camera", "base_link")
        assert cam["frame"] == rob["frame"]  # the frame's number stays
        assert {**far, "latency_ms": 0} == {**rob, "latency_ms": 0}
        placed = [n for n, c in cam["corners"].items() if c["point"] is not None]
        assert placed
        for n in placed:
            assert np.allclose(rob["corners"][n]["point"], _moved(cam["corners"][n]["point"]),
                               atol=1e-4)
        assert np.allclose(rob["up"], np.array(MATRIX, float)[:3, :3] @ cam["up"], atol=1e-5)


def test_the_api_takes_extrinsics_as_the_commands_do(files):
    import dgli_vision

    camera = dgli_vision.classify_pair(*FOLDED)
    base = dgli_vision.classify_pair(*FOLDED, extrinsics=files["tf"])
    same = dgli_vision.classify_pair(*FOLDED, extrinsics=np.array(MATRIX, float))
    assert base.class_id == same.class_id == camera.class_id == "05"
    assert np.allclose(base.corners["A"].point, same.corners["A"].point, atol=1e-12)
    for name, c in camera.corners.items():
        if c.point is not None:
            assert np.allclose(base.corners[name].point, _moved(c.point), atol=1e-9)
            assert base.corners[name].pixel == c.pixel
    assert np.allclose(base.folds[0].line, [_moved(q) for q in camera.folds[0].line])
    step = dgli_vision.plan(*FLAT, goal="02/A", extrinsics=files["matrix"]).steps[0]
    cam_step = dgli_vision.plan(*FLAT, goal="02/A").steps[0]
    assert np.allclose(step.grasp_point, _moved(cam_step.grasp_point), atol=1e-9)
    assert np.allclose(step.place_point, _moved(cam_step.place_point), atol=1e-9)
    with pytest.raises(InvalidInputError, match="is not a rotation"):
        dgli_vision.classify_pair(*FOLDED, extrinsics=np.diag([2.0, 1.0, 1.0, 1.0]))
