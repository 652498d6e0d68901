"""Depth aligned to colour in numpy (sources/depth_align.py) against the RealSense SDK's
own ``rs.align`` on the same recorded frames: the same millimetres at every pixel, and
the same verdicts, where the streams share their centre of projection, with a depth
camera 15 mm to the side and turned by 1 degree, and at colour's own resolution; a
distorted colour stream is left to the SDK. And a frame's pixels sent to a worker
process as recorded decode there to the same frame as here."""

from __future__ import annotations

import math
import pickle
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from guards import require_extra

SAMPLES = Path(__file__).parent.parent / "sample_images"

#: Depth camera 15 mm to the side of colour, turned 1 degree about the vertical axis
#: (column-major rotation, translation in metres: as the SDK holds extrinsics).
_A = math.radians(1.0)
SIDEWAYS = (
    (math.cos(_A), 0.0, -math.sin(_A), 0.0, 1.0, 0.0, math.sin(_A), 0.0, math.cos(_A)),
    (0.015, 0.0003, -0.001),
)


@pytest.fixture(scope="module")
def frames():
    from dgli_vision.sources.frames import read_frame

    return [
        read_frame(SAMPLES / f"{k}_000_color.png", SAMPLES / f"{k}_000_depth.png")
        for k in ("01", "04", "08")
    ]


def _recording(path: Path, frames, intrinsics=None, extrinsics=None, **options) -> Path:
    require_extra("pyrealsense2")
    from dgli_vision.sources.realsense_writer import write_realsense_recording

    data = [(10.0 + k / 30, f.color, f.depth_mm) for k, f in enumerate(frames)]
    return write_realsense_recording(
        path, data, intrinsics or frames[0].intrinsics, extrinsics=extrinsics, **options
    )


def _both(path: Path, align: str = "auto"):
    """The recording's frames aligned by the SDK and here."""
    from dgli_vision.sources.realsense import RealSensePlayback

    with RealSensePlayback(path, align="sdk") as sdk:
        assert sdk.calibration is None
        by_sdk = list(sdk.frames())
    with RealSensePlayback(path, align=align) as own:
        calibration = own.calibration
        by_us = list(own.frames())
    assert len(by_sdk) == len(by_us) > 0
    return by_sdk, by_us, calibration


def test_the_same_centre_of_projection_aligns_exactly_as_the_sdk(frames, tmp_path):
    """Depth at half the colour resolution in 0.1 mm (what a D400 gives): each depth
    pixel's rectangle covers 3 x 3 colour pixels, overlapping its neighbours', the
    nearest kept: the same millimetres at every pixel."""
    by_sdk, by_us, calibration = _both(_recording(tmp_path / "same.db3", frames))
    assert calibration is not None and calibration.fast
    for a, b in zip(by_sdk, by_us):
        np.testing.assert_array_equal(a.color, b.color)
        np.testing.assert_array_equal(a.depth_mm, b.depth_mm)
        assert (b.depth_mm > 0).mean() > 0.9


@pytest.mark.parametrize("moved", ["aside", "turned", "one to one"])
def test_a_depth_camera_elsewhere_aligns_as_the_sdk(frames, tmp_path, moved):
    """A depth camera 15 mm to the side and turned 1 degree (``aside``: where a pixel
    lands depends on its depth), only turned (the rectangles are worked out once, but
    rows and columns no longer map apart), or at colour's own resolution (``one to
    one``: every corner at a rounding tie, which the SDK decides at each pixel's depth;
    some pixels land one over and leave a hole): the SDK's millimetres at every pixel,
    aligned pixel by pixel where it matters (``align="numpy"``), and the same verdicts.
    None of them is ``fast`` (turned, some corners land near a tie): by default the SDK
    aligns them."""
    from dgli_vision.classifier.pipeline import classify_frame
    from dgli_vision.classifier.references import load_references
    from dgli_vision.sources.realsense import RealSensePlayback

    extrinsics = {"aside": SIDEWAYS, "turned": (SIDEWAYS[0], (0.0, 0.0, 0.0))}.get(moved)
    step = {"depth_step": 1, "depth_scale_m": 0.001} if moved == "one to one" else {}
    path = _recording(tmp_path / "side.db3", frames, extrinsics=extrinsics, **step)
    by_sdk, by_us, calibration = _both(path, "numpy")
    assert calibration is not None and not calibration.fast
    with RealSensePlayback(path) as auto:
        assert (auto.calibration is not None) == calibration.fast
    refs = load_references(None)
    for a, b, written in zip(by_sdk, by_us, frames):
        np.testing.assert_array_equal(a.depth_mm, b.depth_mm)
        assert (a.depth_mm != written.depth_mm).mean() > 0.001  # moved by the alignment
        pa = classify_frame(_frame(a), refs).prediction
        pb = classify_frame(_frame(b), refs).prediction
        assert (pa and (pa.class_id, pa.variant)) == (pb and (pb.class_id, pb.variant))


def test_a_distorted_colour_stream_is_aligned_by_the_sdk(frames, tmp_path):
    from dgli_vision.sources.realsense import RealSensePlayback

    intr = replace(frames[0].intrinsics, distortion=(0.05, -0.02, 0.001, -0.0005, 0.0))
    path = _recording(tmp_path / "lens.db3", frames[:1], intr)
    with RealSensePlayback(path) as rec:
        assert rec.calibration is None
        assert "aligned to colour by the SDK" in rec.notes[0]


def test_a_frame_sent_to_a_worker_as_recorded_decodes_to_the_same_frame(frames, tmp_path):
    """The live loop's worker processes get a RealSense frame's pixels as recorded
    (through shared memory, or copied when no slot is free) and align them there."""
    from dgli_vision.core.parallel import SharedSlots
    from dgli_vision.sources.recording import open_recording

    path = _recording(tmp_path / "raw.db3", frames[:2])
    slots = SharedSlots(1)
    try:
        for pair in open_recording(path, live=True).frames:
            assert pair.portable
            here = pair.load()
            for sent, slot in (pair.shared(slots), pair.shared(slots)):  # 2nd: no slot
                there = pickle.loads(pickle.dumps(sent)).load()
                np.testing.assert_array_equal(there.color, here.color)
                np.testing.assert_array_equal(there.depth_mm, here.depth_mm)
                assert there.intrinsics == here.intrinsics and there.color_path == pair.color
                if slot is not None:
                    slots.release(slot)
    finally:
        slots.close()


def _frame(f):
    from dgli_vision.sources.frames import RGBDFrame

    return RGBDFrame(f.color, f.depth_mm, f.intrinsics)


def test_the_row_and_column_gathers_equal_the_whole_image_ones():
    """Streams that differ only in their intrinsics (any sizes and centres) take the
    separable path; it gives what the per-pixel gathers give, readings and holes."""
    from dgli_vision.sources import depth_align as A

    rng = np.random.default_rng(7)
    for (dw, dh), (cw, ch) in (((64, 36), (128, 72)), ((48, 40), (100, 70)), ((90, 60), (60, 40))):
        depth = A.StreamCamera(dw, dh, 0.9 * dw, 0.9 * dw, dw / 2 - 0.3, dh / 2 + 0.2)
        colour = A.StreamCamera(cw, ch, 0.95 * cw, 0.95 * cw, cw / 2 + 0.4, ch / 2 - 0.1)
        cal = A.DepthToColour(depth, colour, A._IDENTITY, (0.0, 0.0, 0.0), 1e-4)
        raw = rng.integers(0, 9000, (dh, dw)).astype(np.uint16)
        raw[rng.random((dh, dw)) < 0.2] = 0
        whole = A._gather_min(raw, A._fixed_sources(cal), (ch, cw))
        np.testing.assert_array_equal(cal.align(raw), whole)
        assert (whole > 0).mean() > 0.5
