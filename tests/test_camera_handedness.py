"""The camera's handedness (issue 51): ``dgli calibrate`` records it from the flat napkin,
an intrinsics file carries it as ``"mirrored"``, and ``--mirroring`` / ``mirroring=``
say it; a camera not declared mirrored is taken as not mirrored."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.cli.main import main
from dgli_vision.core.camera import Intrinsics
from dgli_vision.core.errors import CalibrationError, InvalidValueError
from dgli_vision.core.handedness import camera_mirroring, unmirrored_intrinsics
from dgli_vision.sources.frames import parse_intrinsics, read_intrinsics
from dgli_vision.sources.intrinsics_files import intrinsics_text

SAMPLES = Path(__file__).resolve().parents[1] / "sample_images"


def _mirrored_pair(name: str, out: Path) -> tuple[str, str]:
    """Sample ``name`` as a camera that mirrors its image writes it."""
    paths = []
    for kind in ("color", "depth"):
        img = cv2.imread(str(SAMPLES / f"{name}_{kind}.png"), cv2.IMREAD_UNCHANGED)
        path = out / f"{name}_{kind}.png"
        cv2.imwrite(str(path), np.ascontiguousarray(img[:, ::-1]))
        paths.append(str(path))
    return paths[0], paths[1]


@pytest.fixture(scope="module")
def mirrored_camera(tmp_path_factory) -> dict[str, object]:
    """A mirroring camera's flat napkin calibrated, and its 02 (a state with a twin)."""
    out = tmp_path_factory.mktemp("mirrored")
    flat = _mirrored_pair("01_000", out)
    corner = _mirrored_pair("02_000", out)
    res = CliRunner().invoke(
        main, ["calibrate", *flat, "--intrinsics-out", str(out / "cam.json")]
    )
    return {"calibrate": res, "intrinsics": out / "cam.json", "corner": corner}


def _classify(pair, *options: str) -> tuple[int, dict]:
    res = CliRunner().invoke(main, ["classify", *pair, "--json", *options])
    return res.exit_code, json.loads(res.output)


def test_calibrate_says_a_plain_camera_does_not_mirror_and_writes_it(tmp_path):
    out = tmp_path / "cam.json"
    pair = [str(SAMPLES / "01_000_color.png"), str(SAMPLES / "01_000_depth.png")]
    res = CliRunner().invoke(main, ["calibrate", *pair, "--intrinsics-out", str(out)])
    assert res.exit_code == 0, res.output
    assert "does not mirror" in res.output
    assert json.loads(out.read_text())["mirrored"] is False


def test_calibrate_finds_a_mirroring_camera_and_classify_then_reads_it_unmirrored(
    mirrored_camera,
):
    res = mirrored_camera["calibrate"]
    assert res.exit_code == 0, res.output
    assert "the camera mirrors its image" in res.output
    intr = mirrored_camera["intrinsics"]
    assert json.loads(intr.read_text())["mirrored"] is True
    code, got = _classify(mirrored_camera["corner"], "--intrinsics", str(intr))
    assert code == 0 and got["class"] == "02" and got["mirroring"] == "yes"
    assert got["confidence"] >= 0.9  # the twin's cap is for a camera of unknown handedness


def test_an_undeclared_mirroring_camera_is_caught_and_unknown_handedness_is_capped(
    mirrored_camera,
):
    code, got = _classify(mirrored_camera["corner"])  # not declared: taken as not mirrored
    assert code == 1 and got["class"] is None and got["mirroring"] == "no"
    assert "stickers run clockwise" in got["reason"] and "--mirroring yes" in got["reason"]
    code, got = _classify(mirrored_camera["corner"], "--mirroring", "yes")
    assert code == 0 and got["class"] == "02"
    plain = [str(SAMPLES / "02_000_color.png"), str(SAMPLES / "02_000_depth.png")]
    code, got = _classify(plain, "--mirroring", "unknown")
    assert code == 0 and got["class"] == "02" and 0.25 <= got["confidence"] <= 0.45
    code, got = _classify(plain)
    assert code == 0 and got["confidence"] >= 0.9


def test_calibrate_refuses_a_napkin_that_is_not_flat(tmp_path):
    pair = [str(SAMPLES / "02_000_color.png"), str(SAMPLES / "02_000_depth.png")]
    out = tmp_path / "cam.json"
    res = CliRunner().invoke(main, ["calibrate", *pair, "--intrinsics-out", str(out)])
    assert res.exit_code == 2 and not out.exists()
    assert res.output.count("\n") == 1 and "02_000_color.png" in res.output, res.output


def test_the_intrinsics_readers_take_mirrored_and_name_a_bad_value(tmp_path):
    base = Intrinsics(640, 480, 500.0, 500.0, 319.5, 239.5, (0.1, 0.0, 0.001, 0.002, 0.0))
    for suffix in (".json", ".yaml", ".xml"):
        for mirrored in (True, False, None):
            path = tmp_path / f"cam{suffix}"
            path.write_text(intrinsics_text(Intrinsics(**{**base.__dict__,
                                                          "mirrored": mirrored}), path))
            assert read_intrinsics(path).mirrored is mirrored, (suffix, mirrored)
    data = base.to_open3d_dict() | {"mirrored": "yes"}
    with pytest.raises(CalibrationError, match=r"^intrinsics 'cam.json': mirrored is 'yes'"):
        parse_intrinsics(data, "cam.json")


def test_mirroring_is_told_by_the_option_then_the_intrinsics_then_taken_as_not_mirrored():
    declared = Intrinsics(640, 480, 500.0, 500.0, 300.0, 239.5, mirrored=True)
    assert camera_mirroring(None, declared) == "yes"
    assert camera_mirroring(None, Intrinsics(640, 480, 500.0, 500.0, 300.0, 239.5)) == "no"
    assert camera_mirroring("unknown", declared) == "unknown"
    with pytest.raises(InvalidValueError, match="mirroring must be one of no, yes, unknown"):
        camera_mirroring("sideways")
    flipped = unmirrored_intrinsics(Intrinsics(640, 480, 500.0, 500.0, 300.0, 239.5,
                                               (0.1, 0.01, 0.001, 0.002, 0.0), True))
    assert flipped.cx == 339.0 and flipped.distortion == (0.1, 0.01, 0.001, -0.002, 0.0)
    assert flipped.mirrored is False
    # the flipped lens moves a flipped pixel where the lens moves the pixel, flipped
    px = np.array([[40.0, 30.0], [600.0, 400.0]])
    lens = Intrinsics(640, 480, 500.0, 500.0, 300.0, 239.5, (0.1, 0.01, 0.001, 0.002, 0.0))
    seen = lens.distort_pixels(px)
    mirror = flipped.distort_pixels(np.c_[639 - px[:, 0], px[:, 1]])
    assert np.allclose(np.c_[639 - seen[:, 0], seen[:, 1]], mirror, atol=1e-9)


def test_classify_pair_takes_mirroring_and_refuses_a_bad_value():
    from dgli_vision import classify_pair

    color, depth = SAMPLES / "02_000_color.png", SAMPLES / "02_000_depth.png"
    assert classify_pair(color, depth).confidence >= 0.9
    assert classify_pair(color, depth, mirroring="unknown").confidence <= 0.45
    with pytest.raises(InvalidValueError, match="mirroring must be one of"):
        classify_pair(color, depth, mirroring="sideways")

