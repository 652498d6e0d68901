"""dgli-classify as a user meets it: sample pairs, JSON, overlay, and every bad input."""

from __future__ import annotations

import csv
import json
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.cli import main

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "sample_images"


def run(args):
    result = CliRunner().invoke(main, ["classify", *args])
    assert "Traceback" not in result.output
    assert result.exception is None or isinstance(result.exception, SystemExit)
    return result


def sample_rows():
    with open(SAMPLES / "labels.csv", newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.mark.parametrize("row", sample_rows(), ids=lambda r: r["color"])
def test_every_sample_pair_is_classified_correctly(row):
    result = run([str(SAMPLES / row["color"]), str(SAMPLES / row["depth"]), "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert data["class"] == row["label"]
    assert (data["variant"] or "") == row["variant"]


def test_json_has_the_designed_fields(tmp_path):
    overlay = tmp_path / "overlay.png"
    color, depth = SAMPLES / "05_000_color.png", SAMPLES / "05_000_depth.png"
    result = run([str(color), str(depth), "--json", "--overlay", str(overlay)])
    data = json.loads(result.output)
    assert set(data) == {
        "color",
        "depth",
        "class",
        "name",
        "variant",
        "distance",
        "confidence",
        "runner_up",
        "stickers",
        "candidates",
        "coordinates",
        "corners",
        "folds",
        "up",
        "frame",
        "mirroring",
    }
    assert data["mirroring"] == "no"  # no intrinsics declare the camera mirrored
    assert 0.0 <= data["confidence"] <= 1.0
    assert set(data["stickers"]) == {"found", "missing", "unknown"}
    assert set(data["runner_up"]) == {"class", "name", "variant", "distance"}
    assert data["runner_up"]["class"] != data["class"]
    assert len(data["coordinates"]) == 28
    assert data["stickers"]["found"] + len(data["stickers"]["missing"]) == 16
    img = cv2.imread(str(overlay))
    assert img is not None and img.shape == (720, 1280, 3)


def test_plain_output_is_one_readable_line():
    result = run([str(SAMPLES / "02_000_color.png"), str(SAMPLES / "02_000_depth.png")])
    assert result.exit_code == 0
    line = result.output.strip()
    assert "\n" not in line
    assert line.startswith("02 corner-over (C), distance") and "runner-up" in line


def test_dgli_classify_from_a_cold_shell():
    exe = Path(sys.executable).parent / "dgli-classify"
    if not exe.exists():
        pytest.skip("console script not installed")
    proc = subprocess.run(
        [str(exe), str(SAMPLES / "09_000_color.png"), str(SAMPLES / "09_000_depth.png")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("09 strip-over")
    bad = subprocess.run(
        [str(exe), "nope.png", "nope_depth.png"], capture_output=True, text=True, timeout=60
    )
    assert bad.returncode == 2
    assert bad.stderr.strip() == "error: colour image 'nope.png' does not exist"


@pytest.fixture
def pair(tmp_path):
    """A copy of a sample pair, for damaging."""
    color, depth = tmp_path / "x_color.png", tmp_path / "x_depth.png"
    shutil.copy(SAMPLES / "01_000_color.png", color)
    shutil.copy(SAMPLES / "01_000_depth.png", depth)
    return color, depth


def expect_error(args, code, *needles):
    result = run([str(a) for a in args])
    assert result.exit_code == code, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1, result.output
    for needle in needles:
        assert needle in lines[0]
    return lines[0]


def test_missing_files(pair, tmp_path):
    color, depth = pair
    expect_error([tmp_path / "none.png", depth], 2, "colour image", "none.png", "does not exist")
    expect_error(
        [color, tmp_path / "none_depth.png"], 2, "depth image", "none_depth.png", "does not exist"
    )


def test_not_an_image(pair, tmp_path):
    color, depth = pair
    fake = tmp_path / "fake.png"
    fake.write_text("this is not a PNG")
    expect_error([fake, depth], 2, "fake.png", "not an image")
    expect_error([color, fake], 2, "fake.png", "not an image")


def test_depth_that_is_8_bit(pair, tmp_path):
    color, depth = pair
    d8 = tmp_path / "d8.png"
    cv2.imwrite(str(d8), (cv2.imread(str(depth), cv2.IMREAD_UNCHANGED) // 4).astype(np.uint8))
    expect_error([color, d8], 2, "d8.png", "8-bit", "expected a 16-bit PNG in mm")


def test_colour_given_as_depth(pair):
    color, _ = pair
    expect_error([color, color], 2, "depth image", "x_color.png", "colour image?")


def test_depth_given_as_colour(pair):
    _, depth = pair
    expect_error([depth, depth], 2, "colour image", "16-bit", "depth image given as colour")


def test_sizes_that_differ(pair, tmp_path):
    color, depth = pair
    small = tmp_path / "small_depth.png"
    cv2.imwrite(str(small), cv2.imread(str(depth), cv2.IMREAD_UNCHANGED)[:360, :640])
    expect_error([color, small], 2, "small_depth.png", "640x360", "1280x720", "same size")


def test_all_zero_depth(pair, tmp_path):
    color, _ = pair
    zero = tmp_path / "zero_depth.png"
    cv2.imwrite(str(zero), np.zeros((720, 1280), np.uint16))
    expect_error([color, zero], 2, "zero_depth.png", "all pixels are 0")


@pytest.mark.parametrize(
    ("content", "needle"),
    [
        ("{not json", "not valid JSON"),
        ('{"width": 1280}', "lack height, intrinsic_matrix"),
        ('{"width": 1280, "height": 720, "intrinsic_matrix": [605, 0, 0]}', "9 finite numbers"),
        (
            '{"width": 1280, "height": 720, '
            '"intrinsic_matrix": [-605, 0, 0, 0, 605, 0, 639.5, 359.5, 1]}',
            "must be positive",
        ),
        (
            '{"width": 1280, "height": 720, '
            '"intrinsic_matrix": [605, 0, 639.5, 0, 605, 359.5, 0, 0, 1]}',
            "not a pinhole matrix",
        ),
        (
            '{"width": 640, "height": 480, '
            '"intrinsic_matrix": [605, 0, 0, 0, 605, 0, 319.5, 239.5, 1]}',
            "are for 640x480 images",
        ),
        # a number is a JSON number: fx "605.0" was read as 605, true as 1
        (
            '{"width": 1280, "height": 720, '
            '"intrinsic_matrix": ["605.0", 0, 0, 0, 605, 0, 639.5, 359.5, 1]}',
            'intrinsic_matrix[0] is a string ("605.0"); expected a number',
        ),
        (
            '{"width": 1280, "height": 720, '
            '"intrinsic_matrix": [605, false, 0, 0, 605, 0, 639.5, 359.5, true]}',
            "intrinsic_matrix[1] is a boolean (false); expected a number",
        ),
        (
            '{"width": "1280", "height": 720, '
            '"intrinsic_matrix": [605, 0, 0, 0, 605, 0, 639.5, 359.5, 1]}',
            'width is a string ("1280")',
        ),
        (
            '{"width": 1280.5, "height": 720, '
            '"intrinsic_matrix": [605, 0, 0, 0, 605, 0, 639.5, 359.5, 1]}',
            "width is 1280.5; expected a whole number",
        ),
        (
            '{"width": 1280, "height": 720, "distortion": ["0.1", 0, 0, 0], '
            '"intrinsic_matrix": [605, 0, 0, 0, 605, 0, 639.5, 359.5, 1]}',
            'distortion[0] is a string ("0.1")',
        ),
    ],
)
def test_bad_intrinsics(pair, tmp_path, content, needle):
    color, depth = pair
    intr = tmp_path / "cam.json"
    intr.write_text(content)
    expect_error([color, depth, "--intrinsics", intr], 2, "cam.json", needle)


def test_intrinsics_beside_the_colour_image_are_used(pair, tmp_path):
    color, depth = pair
    (tmp_path / "intrinsics.json").write_text(
        '{"width": 10, "height": 10, "intrinsic_matrix": [5, 0, 0, 0, 5, 0, 4.5, 4.5, 1]}'
    )
    expect_error([color, depth], 2, "intrinsics.json", "are for 10x10 images")


def test_bad_references_file(pair, tmp_path):
    color, depth = pair
    refs = tmp_path / "refs.json"
    refs.write_text('{"format": "something else"}')
    expect_error([color, depth, "--references", refs], 2, "refs.json", "not a dgli reference set")


def test_too_little_seen_exits_1_with_a_reason(tmp_path):
    color = tmp_path / "table_color.png"
    depth = tmp_path / "table_depth.png"
    cv2.imwrite(str(color), np.full((720, 1280, 3), 90, np.uint8))
    cv2.imwrite(str(depth), np.full((720, 1280), 600, np.uint16))
    result = run([str(color), str(depth), "--json"])
    assert result.exit_code == 1
    data = json.loads(result.output)
    assert data["class"] is None and "0 of 16 stickers" in data["reason"]
    plain = run([str(color), str(depth)])
    assert plain.exit_code == 1 and "no class" in plain.output


def test_jpeg_colour_is_accepted(tmp_path):
    color = tmp_path / "scene.jpg"
    cv2.imwrite(
        str(color), cv2.imread(str(SAMPLES / "07_000_color.png")), [cv2.IMWRITE_JPEG_QUALITY, 90]
    )
    result = run([str(color), str(SAMPLES / "07_000_depth.png"), "--json"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.output)["class"] == "07"


def test_an_abstention_is_said_once_and_names_its_candidates(tmp_path):
    """"Cannot tell" is an answer: one line on stdout, exit 1, nothing on stderr; its
    JSON keeps the nearest classes and the kind of reason."""
    from dgli_vision.sim.dataset import render_sample
    from dgli_vision.sources.labelled import write_labelled_folder

    # a gripper over a flat napkin (seed 9090, sample 0): the corner under it may be
    # folded or not
    sample = render_sample("01", 0, 9090, conditions=("gripper",))
    labels = write_labelled_folder(tmp_path / "set", [sample], {"command": "test"})
    color, depth = (str(labels.parent / f"{sample.name}_{k}.png") for k in ("color", "depth"))
    intr = str(labels.parent / "intrinsics.json")
    runner = CliRunner()
    plain = runner.invoke(main, ["classify", color, depth, "--intrinsics", intr])
    assert plain.exit_code == 1
    assert plain.stdout.startswith("no class: cannot tell") and plain.stderr == ""
    as_json = runner.invoke(main, ["classify", "--json", color, depth, "--intrinsics", intr])
    data = json.loads(as_json.stdout)
    assert as_json.exit_code == 1 and data["class"] is None
    assert data["why"]["kind"] == "too close to call"
    assert data["why"]["classes"] == [c["class"] for c in data["candidates"][:2]]
    assert data["candidates"][0]["distance"] <= data["candidates"][1]["distance"]


def test_the_overlay_of_a_cannot_tell_shows_the_object_and_the_missing_stickers(tmp_path):
    """The overlay outlines the object over the napkin (red), circles where the unknown
    stickers would be (orange) and wraps the whole reason inside the image."""
    from dgli_vision.analysis.overlay import _wrapped
    from dgli_vision.sim.dataset import render_sample
    from dgli_vision.sources.labelled import write_labelled_folder

    sample = render_sample("01", 0, 9090, conditions=("gripper",))
    labels = write_labelled_folder(tmp_path / "set", [sample], {"command": "test"})
    color, depth = (str(labels.parent / f"{sample.name}_{k}.png") for k in ("color", "depth"))
    out = tmp_path / "overlay.png"
    args = [color, depth, "--intrinsics", str(labels.parent / "intrinsics.json")]
    result = run([*args, "--overlay", str(out)])
    assert result.exit_code == 1 and out.is_file()
    img = cv2.imread(str(out))
    red = (img[..., 2] > 200) & (img[..., 1] < 40) & (img[..., 0] < 40)
    green = img[..., 1].astype(int)
    orange = (img[..., 2] > 200) & (np.abs(green - 140) < 30) & (img[..., 0] < 40)
    assert red.sum() > 200 and orange.sum() > 20
    lines = _wrapped(result.output.strip(), 1256, 0.8, 2)
    assert len(lines) >= 2
    assert all(cv2.getTextSize(t, cv2.FONT_HERSHEY_SIMPLEX, 0.8, 4)[0][0] <= 1256 for t in lines)
