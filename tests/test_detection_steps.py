"""The detection of one frame is a few steps on one search frame: the napkin is found
once (stage 1), the frame's halving, depth, hue table and palette are worked out once
(:func:`search_frame`), and the search for stickers washed out by a sheen is a step on
them, not a second pass through :func:`detect_stickers`."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from render_cache import rendered

from dgli_vision.classifier import pipeline
from dgli_vision.core.layout import default_layout
from dgli_vision.perception import detect
from dgli_vision.perception.detect import (
    find_washed_out,
    first_search,
    search_frame,
    washed_out_search,
)
from dgli_vision.perception.lift import estimate_table_plane
from dgli_vision.perception.napkin import balance_lut, find_napkin
from dgli_vision.perception.regions import cloth_regions
from dgli_vision.perception.washed import (
    PastelLooks,
    merge_second_search,
    pastel_params,
    with_unread,
)

LAYOUT = default_layout()


@pytest.fixture(scope="module")
def sheen(request):
    """A frame whose sheen washes a corner's four stickers out (12 found at first)."""
    frame = rendered(request.config, "01", 0, 0, ("sheen",))
    up, offset = estimate_table_plane(frame.depth_mm, frame.intrinsics)
    napkin = find_napkin(frame.color, frame.depth_mm, frame.intrinsics, up, offset)
    return frame, napkin, cloth_regions(frame.color, napkin.white_rgb)


def _same(a, b):
    for key in ("centroids", "areas", "scores", "depth_mm", "foreshortening", "pale_px"):
        x, y = getattr(a, key), getattr(b, key)
        assert (x is None) == (y is None), key
        if x is not None:
            np.testing.assert_array_equal(x, y, err_msg=key)
    assert a.rejected == b.rejected and a.pale_colours == b.pale_colours


def test_the_first_search_is_detect_stickers(sheen):
    frame, napkin, _ = sheen
    f = search_frame(frame.color, frame.depth_mm, frame.intrinsics, LAYOUT, napkin)
    got = first_search(f)
    _same(got, detect.detect_stickers(
        frame.color, frame.depth_mm, frame.intrinsics, LAYOUT, napkin=napkin
    ))
    assert 8 <= got.found.sum() < 16


def test_the_washed_out_step_finds_what_a_second_full_search_found(sheen):
    """The step on the first search's frame gives, bit for bit, what the second search
    gave as a whole pass of detect_stickers over the napkin balanced to the low level."""
    frame, napkin, regions = sheen
    f = search_frame(frame.color, frame.depth_mm, frame.intrinsics, LAYOUT, napkin)
    found = first_search(f)
    step = washed_out_search(f, found, regions=regions)
    assert step.found.sum() > found.found.sum()  # (the sheen's stickers, found again)

    # the second search as a whole pass (how it was done before it was a step)
    import cv2

    params = f.params
    lower = replace(napkin, lut=balance_lut(napkin.white_rgb, params.washed_level))
    looks = PastelLooks(frame.color, lower, regions)
    cloth = looks.cloth(found.centroids)
    m = 2 * params.washed_margin_cells + 1
    roi = cv2.dilate(cloth.astype(np.uint8), np.ones((m, m), np.uint8)).astype(bool)
    again = detect.detect_stickers(
        frame.color, frame.depth_mm, frame.intrinsics, LAYOUT, pastel_params(params),
        napkin=lower, roi=roi, report=~found.found, known=found.centroids,
    )
    whole = with_unread(
        frame.color, merge_second_search(found, again), LAYOUT, params, lower, None,
        looks=looks,
    )
    _same(step, whole)
    # and the public function is the same step
    _same(step, find_washed_out(
        frame.color, frame.depth_mm, frame.intrinsics, LAYOUT, found, napkin=napkin,
        regions=regions,
    ))


def test_a_frame_is_detected_from_one_search_frame_and_one_napkin(sheen, monkeypatch):
    frame, _, _ = sheen
    calls = []
    original = detect.search_frame

    def counted(*args, **kwargs):
        calls.append(1)
        return original(*args, **kwargs)

    def no_napkin(*args, **kwargs):
        raise AssertionError("the detection found the napkin again")

    monkeypatch.setattr(detect, "search_frame", counted)
    from dgli_vision.perception import observe as path

    monkeypatch.setattr(path, "search_frame", counted)
    monkeypatch.setattr(detect, "find_napkin", no_napkin)
    detections, _, _ = pipeline.observe(frame)
    assert detections.found.sum() == 16  # (the washed-out search ran, and found them)
    assert len(calls) == 1
