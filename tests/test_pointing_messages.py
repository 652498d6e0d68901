"""Issue 41 item 7: a message names the likely cause, not something else: depth in cm or
whole metres says so (with the factor), a focal length that is not the camera's is named
with the one that fits, and the nominal camera's intrinsics say where this camera's go."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import cv2
import numpy as np
import pytest

from dgli_vision.camera import Intrinsics
from dgli_vision.classifier.consistency import depth_range_hint, scale_causes
from dgli_vision.classifier.pipeline import classify_frame
from dgli_vision.classifier.references import load_references
from dgli_vision.sources.frames import RGBDFrame, read_frame

SAMPLES = Path(__file__).resolve().parents[1] / "sample_images"


@cache
def sample() -> RGBDFrame:
    return read_frame(SAMPLES / "05_000_color.png", SAMPLES / "05_000_depth.png")


@cache
def refs():
    return load_references()


def reason_of(frame: RGBDFrame) -> str:
    res = classify_frame(frame, refs())
    assert res.prediction is None
    return res.reason


def with_depth(depth: np.ndarray) -> RGBDFrame:
    f = sample()
    return RGBDFrame(f.color, depth.astype(np.uint16), f.intrinsics, f.color_path, "d.png")


def test_depth_in_cm_says_cm_and_the_factor():
    why = reason_of(with_depth(np.round(sample().depth_mm / 10)))
    assert "depth in cm? (x10 gives 6" in why, why


def test_depth_in_whole_metres_says_so_and_how_to_write_it():
    why = reason_of(with_depth(np.round(sample().depth_mm / 1000)))
    assert "depth in metres stored as whole numbers" in why, why
    assert "metres x 1000 as 16-bit" in why


def test_a_focal_length_not_the_cameras_is_named_with_the_one_that_fits():
    f = sample()
    k = f.intrinsics
    wrong = Intrinsics(k.width, k.height, 910.0, 910.0, k.cx, k.cy)
    why = reason_of(RGBDFrame(f.color, f.depth_mm, wrong, f.color_path, f.depth_path, "i.json"))
    # the sample's camera has fx 605: the stickers' size says so
    assert "the focal length would be about 6" in why and "not 910 as the intrinsics" in why
    assert why.index("focal length") < why.index("depth reads"), why


def test_the_nominal_cameras_intrinsics_on_a_zoomed_camera_say_where_the_right_ones_go():
    f = sample()
    y0, x0 = 120, 213  # the middle two thirds, as a camera with fx 907 sees it
    color = cv2.resize(f.color[y0 : y0 + 480, x0 : x0 + 853], (1280, 720))
    depth = cv2.resize(
        f.depth_mm[y0 : y0 + 480, x0 : x0 + 853], (1280, 720), interpolation=cv2.INTER_NEAREST
    )
    why = reason_of(RGBDFrame(color, depth, f.intrinsics, "c.png", "d.png", "default"))
    assert "not the nominal camera's 605" in why, why
    assert "intrinsics.json beside the images, or --intrinsics" in why


@pytest.mark.parametrize(
    ("scale", "said"),
    [
        (10.2, "depth in 0.1 mm instead of mm? /10 gives mm"),
        (0.098, "in cm instead of mm? x10 gives mm"),
        (0.66, "the focal length would be about 601 px, not 910"),
        (1.34, "the focal length would be about 1219 px, not 910"),
    ],
)
def test_scale_causes_lead_with_units_for_powers_of_ten_and_the_focal_length_otherwise(
    scale, said
):
    intr = Intrinsics(1280, 720, 910.0, 910.0, 639.5, 359.5)
    assert said in scale_causes(scale, intr)


def test_a_plausible_depth_image_says_nothing_of_its_range():
    assert depth_range_hint(sample().depth_mm) == ""
