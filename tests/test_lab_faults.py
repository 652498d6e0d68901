"""Faults a lab will make (issue 29): bad paths, full disks, closed or full standard
output, damaged or huge images, odd CSV files, wrong arguments from code. Each gives one
line on stderr and its exit code (or a DgliError from code), never a traceback, and
keeps what was already written."""

from __future__ import annotations

import errno
import json
import os
import shutil
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
from cli_runs import one_error_line, run_process
from click.testing import CliRunner
from guards import require_extra

import dgli_vision
from dgli_vision.cli import main
from dgli_vision.core import io as dio
from dgli_vision.core.camera import Intrinsics
from dgli_vision.core.errors import (
    CalibrationError,
    InvalidInputError,
    OutputError,
    ReferenceSetError,
    UnreadableInputError,
)
from dgli_vision.sources.frames import read_color, read_frame
from dgli_vision.sources.labelled import find_labelled_pairs

SAMPLES = Path(__file__).resolve().parent.parent / "sample_images"
COLOR = SAMPLES / "05_000_color.png"
DEPTH = SAMPLES / "05_000_depth.png"
ROOT = Path(__file__).resolve().parent.parent


def run(args: list[str]):
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert "Traceback" not in result.output
    assert not isinstance(result.exception, Exception) or isinstance(
        result.exception, SystemExit
    ), repr(result.exception)
    return result




def assert_one_stderr_line(proc: subprocess.CompletedProcess, code: int = 2) -> str:
    assert proc.returncode == code, proc.stderr
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("error: ")
    return lines[0]


def png_with_header(width: int, height: int, *, bit_depth: int = 8, colour_type: int = 2):
    """A small PNG file whose IHDR claims ``width`` x ``height`` (checksums right, pixel
    data far too short for that size)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
        )

    ihdr = struct.pack(">IIBBBBB", width, height, bit_depth, colour_type, 0, 0, 0)
    idat = zlib.compress(b"\0" * 64)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat) + chunk(b"IEND", b"")


# --- tracebacks instead of one line ------------------------------------------------------


def test_overlay_with_an_unknown_extension_is_one_line_before_the_work(tmp_path):
    out = tmp_path / "out.xyz"
    line = one_error_line(run(["classify", COLOR, DEPTH, "--overlay", out]))
    assert "'--overlay'" in line and "*.png" in line
    assert not out.exists()


def test_writer_without_an_image_format_is_an_output_error(tmp_path):
    with pytest.raises(OutputError, match=r"no image writer for '\.xyz'"):
        dio.write_png(tmp_path / "a.xyz", np.zeros((4, 4, 3), np.uint8))


def test_render_into_an_impossible_folder_stops_before_rendering(tmp_path):
    line = one_error_line(run(["render", "/proc/no-such-dir/out", "--per-class", "1"]))
    assert "cannot write '/proc/no-such-dir/out/" in line
    assert "cannot make its folder" in line


def test_five_thousand_character_path_is_one_short_line():
    long_path = "a/" * 2500 + "depth.png"
    line = one_error_line(run(["classify", COLOR, long_path]))
    assert "depth image" in line and "File name too long" in line
    assert len(line) < 400


def test_stdout_to_dev_full_is_one_line_and_exit_2():
    with open("/dev/full", "w") as full:
        proc = run_process(["coords"], stdout=full)
    line = assert_one_stderr_line(proc)
    assert "cannot write to standard output: No space left on device" in line


def test_help_to_dev_full_is_one_line_and_exit_2():
    with open("/dev/full", "w") as full:
        proc = run_process(["--help"], stdout=full)
    line = assert_one_stderr_line(proc)
    assert "cannot write to standard output: No space left on device" in line


def test_closed_stdout_is_one_line_and_exit_2():
    cmd = f"exec {sys.executable} -m dgli_vision coords >&-"
    proc = subprocess.run(
        ["sh", "-c", cmd], cwd=ROOT, stderr=subprocess.PIPE, text=True, timeout=60
    )
    line = assert_one_stderr_line(proc)
    assert "standard output is closed" in line


def test_full_disk_during_evaluate_is_one_line(tmp_path):
    """results.jsonl on a full disk (/dev/full): one line naming it, not three chained
    tracebacks from the writer, its close and the handler."""
    folder = tmp_path / "pairs"
    folder.mkdir()
    for name in ("05_000_color.png", "05_000_depth.png", "intrinsics.json"):
        shutil.copy(SAMPLES / name, folder / name)
    (folder / "labels.csv").write_text(
        "color,depth,label,variant\n05_000_color.png,05_000_depth.png,05,BC/B\n"
    )
    report = tmp_path / "report"
    report.mkdir()
    (report / "results.jsonl").symlink_to("/dev/full")
    result = run(["evaluate", folder, "--report", report, "--overwrite", "-j", "1"])
    line = one_error_line(result)
    assert f"cannot write '{report / 'results.jsonl'}': No space left on device" in line


def test_full_disk_while_writing_a_report_keeps_and_names_the_files_written(tmp_path, monkeypatch):
    real = dio._write_bytes

    def fill_up(p: Path, data: bytes) -> None:
        if p.name == "c.txt":
            raise dio._unwritable(p, os.strerror(errno.ENOSPC))
        real(p, data)

    monkeypatch.setattr(dio, "_write_bytes", fill_up)
    files = {tmp_path / n: "x\n" for n in ("a.txt", "b.txt", "c.txt", "d.txt")}
    with pytest.raises(OutputError) as caught:
        dio.write_outputs(files, overwrite=False, command="test")
    message = str(caught.value)
    assert "c.txt': No space left on device" in message
    assert "the 2 files written before it are kept" in message
    assert "a.txt" in message and "b.txt" in message
    assert (tmp_path / "a.txt").exists() and not (tmp_path / "d.txt").exists()
    manifest = json.loads((tmp_path / dio.MANIFEST_NAME).read_text())
    assert set(manifest["files"]) == {"a.txt", "b.txt"}  # a rerun replaces them


def test_full_disk_during_simulate_keeps_and_names_the_states_written(tmp_path, monkeypatch):
    real = dio._write_bytes

    def fill_up(p: Path, data: bytes) -> None:
        if p.name == "03_000.json":
            raise dio._unwritable(p, os.strerror(errno.ENOSPC))
        real(p, data)

    monkeypatch.setattr(dio, "_write_bytes", fill_up)
    db = tmp_path / "db"
    line = one_error_line(run(["simulate", db, "--per-class", "1", "--in-progress", "0"]))
    assert "03_000.json': No space left on device" in line
    assert "the 5 files written before it are kept" in line and "01_000.ply" in line
    recorded = json.loads((db / "meshes" / dio.MANIFEST_NAME).read_text())["files"]
    assert set(recorded) == {"01_000.ply", "02_000.ply", "03_000.ply"}


def test_references_build_on_a_truth_file_with_nan_names_it(tmp_path):
    db = tmp_path / "db"
    (db / "truth").mkdir(parents=True)
    states = []
    for k, (cls, variant) in enumerate((("01", None), ("02", "A"))):
        truth = {
            "id": f"s{k}",
            "class": cls,
            "variant": variant,
            "sticker_points_m": np.zeros((16, 3)).tolist(),
            "visible": [True] * 16,
            "visible_fraction": [1.0] * 16,
            "corner_points_m": np.zeros((4, 3)).tolist(),
            "boundary_m": np.zeros((8, 3)).tolist(),
        }
        if k == 1:
            truth["sticker_points_m"][3][2] = float("nan")
        (db / "truth" / f"s{k}.json").write_text(json.dumps(truth))
        states.append({"id": f"s{k}", "truth": f"truth/s{k}.json"})
    index = {"format": "dgli-simulated-db", "version": 1, "states": states}
    (db / "index.json").write_text(json.dumps(index))
    line = one_error_line(run(["references", "build", db, "-o", tmp_path / "refs.json"]))
    assert "s1.json" in line and "sticker_points_m" in line and "not finite" in line
    assert not (tmp_path / "refs.json").exists()


def test_symlink_loop_named_in_labels_csv_is_a_listed_failure(tmp_path):
    folder = tmp_path / "pairs"
    folder.mkdir()
    for name in ("05_000_color.png", "05_000_depth.png", "intrinsics.json"):
        shutil.copy(SAMPLES / name, folder / name)
    (folder / "loop.png").symlink_to("loop.png")
    (folder / "labels.csv").write_text(
        "color,depth,label,variant\n05_000_color.png,05_000_depth.png,05,BC/B\n"
        "loop.png,05_000_depth.png,05,BC/B\n"
    )
    result = run(["evaluate", folder, "-j", "1", "--json"])
    data = json.loads(result.output.splitlines()[-1])
    assert data["n"] == 2 and data["classified"] == 1
    (failure,) = data["failures"]
    assert "loop.png" in failure["error"]
    assert "Too many levels of symbolic links" in failure["error"]


def test_api_intrinsics_of_the_wrong_type_raise_the_tools_error():
    with pytest.raises(InvalidInputError, match="got int"):
        dgli_vision.classify_pair(COLOR, DEPTH, intrinsics=5)
    with pytest.raises(CalibrationError, match="lack height, intrinsic_matrix"):
        dgli_vision.classify_pair(COLOR, DEPTH, intrinsics={"width": 1280})
    with pytest.raises(InvalidInputError, match="references must be"):
        dgli_vision.classify_pair(COLOR, DEPTH, references=5)
    with pytest.raises(InvalidInputError, match="color must be a file path or a numpy array"):
        dgli_vision.classify_pair(None, DEPTH)


def test_api_nan_intrinsics_are_named_not_eigenvalues():
    nan = Intrinsics(1280, 720, float("nan"), 605.0, 639.5, 359.5)
    with pytest.raises(CalibrationError, match="9 finite numbers"):
        dgli_vision.classify_pair(COLOR, DEPTH, intrinsics=nan)
    rgb, depth = read_color(COLOR), cv2.imread(str(DEPTH), cv2.IMREAD_UNCHANGED)
    with pytest.raises(CalibrationError, match="9 finite numbers"):
        dgli_vision.classify_pair(rgb, depth, intrinsics=nan)


def test_api_open3d_intrinsics_dict_is_accepted():
    intr = json.loads((SAMPLES / "intrinsics.json").read_text())
    p = dgli_vision.classify_pair(COLOR, DEPTH, intrinsics=intr)
    assert p.class_id == "05"


# --- memory: sizes from headers before decoding ----------------------------------------


def test_png_claiming_30000_by_30000_is_refused_from_its_header(tmp_path):
    huge = tmp_path / "huge_color.png"
    huge.write_bytes(png_with_header(30000, 30000))
    assert huge.stat().st_size < 200
    with pytest.raises(InvalidInputError, match=r"30000x30000 pixels \(900 megapixels\)"):
        read_color(huge)
    line = one_error_line(run(["classify", huge, DEPTH]))
    assert "huge_color.png' is 30000x30000 pixels" in line


def test_colour_and_depth_of_different_sizes_are_refused_from_their_headers(tmp_path):
    color = tmp_path / "c.png"
    depth = tmp_path / "d.png"
    color.write_bytes(png_with_header(640, 480))
    depth.write_bytes(png_with_header(320, 240, bit_depth=16, colour_type=0))
    with pytest.raises(InvalidInputError, match=r"is 320x240 but colour image .* is 640x480"):
        read_frame(color, depth)


def test_jpeg_size_comes_from_its_frame_header(tmp_path):
    rgb = np.full((48, 64, 3), 128, np.uint8)
    _, buf = cv2.imencode(".jpg", rgb)
    data = bytearray(buf.tobytes())
    sof = data.index(b"\xff\xc0")
    data[sof + 5 : sof + 9] = struct.pack(">HH", 20000, 30000)  # height, width
    big = tmp_path / "big.jpg"
    big.write_bytes(bytes(data))
    with pytest.raises(InvalidInputError, match="30000x20000 pixels"):
        read_color(big)


def test_size_100000_is_refused_at_once(tmp_path):
    line = one_error_line(run(["render", tmp_path / "r", "--size", "100000"]))
    assert "'--size'" in line and "at most 1000 mm" in line
    assert not (tmp_path / "r").exists()


def test_per_class_1e20_is_refused_at_once(tmp_path):
    line = one_error_line(run(["render", tmp_path / "r", "--per-class", str(10**20)]))
    assert "'--per-class'" in line and "0<=x<=50" in line
    line = one_error_line(
        run(["simulate", tmp_path / "db", "--per-class", "150", "--size", "900"])
    )
    assert "'--per-class'" in line and "fit in memory" in line


# --- the smaller points -----------------------------------------------------------------


def _bom_folder(tmp_path: Path, csv_name: str, header: str) -> Path:
    folder = tmp_path / "pairs"
    folder.mkdir()
    for name in ("05_000_color.png", "05_000_depth.png", "intrinsics.json"):
        shutil.copy(SAMPLES / name, folder / name)
    row = "05_000_color.png,05_000_depth.png," + ("05,BC/B" if "label" in header else "0.0")
    (folder / csv_name).write_bytes(f"\ufeff{header}\n{row}\n".encode())
    return folder


def test_labels_csv_with_utf8_bom_is_read(tmp_path):
    folder = _bom_folder(tmp_path, "labels.csv", "color,depth,label,variant")
    result = run(["evaluate", folder, "-j", "1", "--json"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.output)["accuracy"] == 1.0


def test_frames_csv_with_utf8_bom_is_read(tmp_path):
    folder = _bom_folder(tmp_path, "frames.csv", "color,depth,time")
    result = run(["track", folder, "-j", "1", "--json"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.output)["n_frames"] == 1


def test_fifo_is_reported_as_a_fifo_not_as_empty(tmp_path):
    fifo = tmp_path / "color.png"
    os.mkfifo(fifo)
    line = one_error_line(run(["classify", fifo, DEPTH]))
    assert "is a FIFO (named pipe), not a regular file" in line


def test_truncated_png_is_one_line_without_libpng_lines(tmp_path):
    cut = tmp_path / "cut.png"
    cut.write_bytes(COLOR.read_bytes()[:20000])
    line = assert_one_stderr_line(run_process(["classify", cut, DEPTH]))
    assert "is truncated: the PNG ends after 20000 bytes" in line


def test_png_with_a_damaged_chunk_is_one_line_without_libpng_lines(tmp_path):
    data = bytearray(COLOR.read_bytes())
    data[200] ^= 0xFF  # inside the first IDAT
    bad = tmp_path / "bad.png"
    bad.write_bytes(bytes(data))
    line = assert_one_stderr_line(run_process(["classify", bad, DEPTH]))
    assert "is damaged: its PNG chunk 'IDAT'" in line


def test_class_folder_layout_uses_the_root_intrinsics_json(tmp_path):
    """Half-size images with their intrinsics only at the labelled folder's root: the
    nominal 1280 x 720 intrinsics would not fit them."""
    root = tmp_path / "labelled"
    (root / "05_two-adjacent-corners-crossing").mkdir(parents=True)
    rgb = cv2.imread(str(COLOR), cv2.IMREAD_UNCHANGED)
    depth = cv2.imread(str(DEPTH), cv2.IMREAD_UNCHANGED)
    half = root / "05_two-adjacent-corners-crossing" / "a"
    cv2.imwrite(f"{half}_color.png", cv2.resize(rgb, (640, 360), interpolation=cv2.INTER_AREA))
    cv2.imwrite(
        f"{half}_depth.png", cv2.resize(depth, (640, 360), interpolation=cv2.INTER_NEAREST)
    )
    intr = {
        "width": 640,
        "height": 360,
        "intrinsic_matrix": [302.5, 0, 0, 0, 302.5, 0, 319.75, 179.75, 1],
    }
    (root / "intrinsics.json").write_text(json.dumps(intr))
    (pair,), _ = find_labelled_pairs(root)
    frame = pair.load()
    assert frame.intrinsics_source == str(root / "intrinsics.json")
    assert frame.intrinsics.fx == pytest.approx(302.5)
    result = run(["evaluate", root, "-j", "1", "--json"])
    assert json.loads(result.output)["failures"] == []


def test_references_whose_class_carries_another_class_variant_are_refused(tmp_path):
    refs = json.loads((ROOT / "references" / "default.json").read_text())
    flat = next(r for r in refs["references"] if r["class"] == "01")
    flat["variant"] = "AB"  # a strip's side, not a variant of the flat napkin
    bad = tmp_path / "refs.json"
    bad.write_text(json.dumps(refs))
    line = one_error_line(run(["classify", COLOR, DEPTH, "--references", bad]))
    assert "of class 01 has variant 'AB'" in line
    with pytest.raises(ReferenceSetError):
        dgli_vision.classify_pair(COLOR, DEPTH, references=bad)


def test_input_path_that_is_a_symlink_loop_is_named(tmp_path):
    loop = tmp_path / "loop.png"
    loop.symlink_to(loop.name)
    with pytest.raises(UnreadableInputError, match="Too many levels of symbolic links"):
        read_color(loop)


# --- extract -----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def small_bag(tmp_path_factory) -> Path:
    """Three frames of 64 x 48 pixels, 0.1 s apart, in a ROS 2 bag."""
    require_extra("rosbags")
    from dgli_vision.sources.bag_writer import write_bag

    rng = np.random.default_rng(29)
    intr = Intrinsics(64, 48, 60.0, 60.0, 31.5, 23.5)
    frames = [
        (
            1_700_000_000.0 + 0.1 * k,
            rng.integers(0, 255, (48, 64, 3), dtype=np.uint8),
            np.full((48, 64), 500 + k, np.uint16),
        )
        for k in range(3)
    ]
    return write_bag(tmp_path_factory.mktemp("bag") / "ep", frames, intr, fmt="ros2-mcap")


def test_extract_start_nan_is_refused(small_bag, tmp_path):
    line = one_error_line(run(["extract", small_bag, tmp_path / "out", "--start", "nan"]))
    assert "'--start'" in line and "not a time in seconds" in line
    assert not (tmp_path / "out").exists()


def test_extract_window_without_frames_is_an_error_not_an_empty_folder(small_bag, tmp_path):
    line = one_error_line(run(["extract", small_bag, tmp_path / "out", "--start", "50"]))
    assert "holds no frame from 50 s: nothing written" in line
    assert not (tmp_path / "out" / "frames.csv").exists()


def test_extract_into_an_impossible_folder_is_one_line(small_bag):
    line = one_error_line(run(["extract", small_bag, "/proc/no-such-dir"]))
    assert "cannot write '/proc/no-such-dir/frames.csv': cannot make its folder" in line


def test_extract_onto_a_full_disk_keeps_and_names_the_frames_written(
    small_bag, tmp_path, monkeypatch
):
    real = dio._write_bytes

    def fill_up(p: Path, data: bytes) -> None:
        if p.name.startswith("frame_000002"):
            raise dio._unwritable(p, os.strerror(errno.ENOSPC))
        real(p, data)

    monkeypatch.setattr(dio, "_write_bytes", fill_up)
    out = tmp_path / "out"
    line = one_error_line(run(["extract", small_bag, out]))
    assert "No space left on device" in line
    assert "the 2 frame(s) written before it are kept" in line
    assert "frame_000000 to frame_000001" in line
    assert (out / "frame_000001_depth.png").is_file()
