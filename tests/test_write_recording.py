"""``dgli write-recording FOLDER OUT``: a folder of PNG pairs as a ROS 1 bag, a ROS 2
MCAP file or a RealSense recording, which read back as the same frames."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.cli import main
from dgli_vision.sources.frames import read_frame
from dgli_vision.sources.recording import open_recording

SAMPLES = Path(__file__).resolve().parents[1] / "sample_images"

pytest.importorskip("rosbags")  # the 'recordings' extra; scripts/setup.sh --test installs it


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("frames")
    shutil.copy(SAMPLES / "intrinsics.json", out)
    for t, name in enumerate(("01_000", "02_000")):
        for kind in ("color", "depth"):
            shutil.copy(SAMPLES / f"{name}_{kind}.png", out / f"f{t:03d}_{kind}.png")
    return out


@pytest.mark.parametrize("suffix", [".bag", ".mcap", ".db3"])
def test_a_folder_written_as_a_recording_reads_back_the_same(folder, tmp_path, suffix):
    if suffix == ".db3":
        pytest.importorskip("pyrealsense2")  # the 'realsense' extra
    out = tmp_path / f"episode{suffix}"
    res = CliRunner().invoke(main, ["write-recording", str(folder), str(out)])
    assert res.exit_code == 0, res.output
    assert f"wrote 2 frames to {out}" in res.stderr
    recording = open_recording(out)
    back = [p.load() for p in recording.frames]
    assert len(back) == 2
    for frame, name in zip(back, ("01_000", "02_000")):
        original = read_frame(SAMPLES / f"{name}_color.png", SAMPLES / f"{name}_depth.png")
        assert np.array_equal(frame.color, original.color)
        if suffix == ".db3":  # the SDK aligns depth to colour again as it reads: edges move
            assert (frame.depth_mm == original.depth_mm).mean() > 0.85
        else:
            assert np.array_equal(frame.depth_mm, original.depth_mm)
        assert frame.intrinsics.fx == pytest.approx(original.intrinsics.fx)


def test_an_unknown_suffix_or_an_existing_file_is_a_one_line_error(folder, tmp_path):
    res = CliRunner().invoke(main, ["write-recording", str(folder), str(tmp_path / "e.x")])
    assert res.exit_code == 2 and "cannot tell the format from '.x'" in res.output
    (tmp_path / "e.bag").write_text("mine")
    res = CliRunner().invoke(main, ["write-recording", str(folder), str(tmp_path / "e.bag")])
    assert res.exit_code == 2 and "exists" in res.output
    assert (tmp_path / "e.bag").read_text() == "mine"
