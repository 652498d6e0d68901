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


def _chunk_compressions(path: Path) -> set[str]:
    """The compression of each chunk of an MCAP file, from its summary."""
    from mcap.reader import make_reader

    with path.open("rb") as f:
        return {c.compression for c in make_reader(f).get_summary().chunk_indexes}


def test_mcap_is_written_with_zstd_chunks_and_reads_back_the_same(folder, tmp_path):
    pytest.importorskip("mcap")  # the 'recordings' extra
    small, big = tmp_path / "z.mcap", tmp_path / "raw.mcap"
    assert CliRunner().invoke(main, ["write-recording", str(folder), str(small)]).exit_code == 0
    res = CliRunner().invoke(main, ["write-recording", str(folder), str(big), "--uncompressed"])
    assert res.exit_code == 0, res.output
    assert _chunk_compressions(small) == {"zstd"} and _chunk_compressions(big) == {""}
    assert small.stat().st_size < 0.8 * big.stat().st_size
    for a, b in zip(open_recording(small).frames, open_recording(big).frames):
        fa, fb = a.load(), b.load()
        assert np.array_equal(fa.color, fb.color) and np.array_equal(fa.depth_mm, fb.depth_mm)


def test_overwrite_replaces_a_recording_once_the_new_one_is_whole(folder, tmp_path):
    out = tmp_path / "e.bag"
    out.write_text("an older recording")
    res = CliRunner().invoke(main, ["write-recording", str(folder), str(out), "--overwrite"])
    assert res.exit_code == 0, res.output
    assert len(list(open_recording(out).frames)) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["e.bag"]  # nothing left beside it
    # a ROS 2 bag folder is replaced whole too
    bag = tmp_path / "ep"
    for _ in range(2):
        res = CliRunner().invoke(main, ["write-recording", str(folder), str(bag), "--overwrite"])
        assert res.exit_code == 0, res.output
    assert len(list(open_recording(bag).frames)) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["e.bag", "ep"]
    # a failure keeps what was there
    empty = tmp_path / "empty"
    empty.mkdir()
    res = CliRunner().invoke(main, ["write-recording", str(empty), str(out), "--overwrite"])
    assert res.exit_code == 2
    assert len(list(open_recording(out).frames)) == 2
