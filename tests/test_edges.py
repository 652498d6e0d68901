"""The edges of issue 38 besides `dgli label`: a damaged ROS 2 bag is one line in every
command that reads it; standard output that cannot take the answer is an error naming
its file, and a pipe closed by its reader ends the command quietly; files are written
whole or not at all; a resume re-classifies images captured again under the same names;
workers die with their parent; a rerun removes what the earlier run listed; labels rows
must name frames that exist; napkin sizes out of range are refused with the range."""

from __future__ import annotations

import csv
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.cli import main

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "sample_images"


def run(*args: object):
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert "Traceback" not in result.output, result.output
    return result


def one_error_line(result, code: int = 2) -> str:
    """The one ``error:`` line of a failed command (other lines on stderr are notes)."""
    assert result.exit_code == code, result.output
    lines = [ln for ln in result.output.splitlines() if ln.startswith(("error:", "Error:"))]
    assert len(lines) == 1, result.output
    return lines[0]


def run_process(args: list[object], **kwargs) -> subprocess.CompletedProcess:
    """``python -m dgli_vision ARGS`` in a process of its own, from the repository."""
    kwargs.setdefault("stderr", subprocess.PIPE)
    return subprocess.run(
        [sys.executable, "-m", "dgli_vision", *map(str, args)],
        cwd=ROOT,
        text=True,
        timeout=120,
        **kwargs,
    )


def sample_folder(root: Path, names: tuple[str, ...] = ("05_000", "09_000")) -> Path:
    """A labelled folder of a few sample pairs."""
    root.mkdir(parents=True)
    rows = []
    with (SAMPLES / "labels.csv").open() as fh:
        labels = {r["color"]: r for r in csv.DictReader(fh)}
    for name in names:
        for part in ("color", "depth"):
            shutil.copy(SAMPLES / f"{name}_{part}.png", root / f"{name}_{part}.png")
        row = labels[f"{name}_color.png"]
        rows.append(f"{row['color']},{row['depth']},{row['label']},{row['variant']}")
    shutil.copy(SAMPLES / "intrinsics.json", root / "intrinsics.json")
    (root / "labels.csv").write_text("color,depth,label,variant\n" + "\n".join(rows) + "\n")
    return root


# --- a ROS 2 sqlite bag with 4 KB of garbage inside ---------------------------------------


def _tiny_episode_bag(path: Path, frames: int = 30) -> Path:
    """A ROS 2 sqlite3 bag of ``frames`` small frames, 0.1 s apart."""
    pytest.importorskip("rosbags")
    from dgli_vision.core.camera import Intrinsics
    from dgli_vision.sources.bag_writer import write_bag

    rng = np.random.default_rng(0)
    intr = Intrinsics(64, 48, 60.0, 60.0, 32.0, 24.0)
    data = [
        (100.0 + k * 0.1, rng.integers(0, 255, (48, 64, 3), np.uint8),
         np.full((48, 64), 500 + k, np.uint16))
        for k in range(frames)
    ]
    return write_bag(path, iter(data), intr, fmt="ros2-sqlite3")


@pytest.fixture(scope="module")
def corrupt_bag(tmp_path_factory) -> Path:
    """A 30-frame ROS 2 sqlite3 bag with one 4 KB page overwritten by garbage, one that
    opens and then fails part-way (found by trying the pages in turn)."""
    from dgli_vision.core.errors import UnreadableInputError
    from dgli_vision.sources.recording import open_recording

    root = tmp_path_factory.mktemp("corrupt")
    bag = _tiny_episode_bag(root / "good")
    db3 = next(bag.glob("*.db3"))
    data = db3.read_bytes()
    garbage = np.random.default_rng(1).integers(0, 256, 4096, np.uint8).tobytes()
    for page in range(len(data) // 4096 // 3, len(data) // 4096):
        bad = root / "bad"
        shutil.rmtree(bad, ignore_errors=True)
        shutil.copytree(bag, bad)
        off = page * 4096
        (bad / db3.name).write_bytes(data[:off] + garbage + data[off + 4096 :])
        try:
            recording = open_recording(bad)
        except UnreadableInputError:
            continue  # the damage shows at once: not the case wanted
        n = 0
        try:
            for _ in recording.frames:
                n += 1
        except Exception:  # an UnreadableInputError (an apsw.CorruptError before)
            if n > 0:
                return bad
    pytest.fail("no page of the bag fails part-way")


def test_a_corrupt_db3_is_one_line_in_every_command_that_reads_it(corrupt_bag, tmp_path):
    labels = tmp_path / "labels.csv"
    labels.write_text("frame,label\n" + "".join(f"{k},01\n" for k in range(30)))
    for args in (
        ["track", corrupt_bag, "-j", "1"],
        ["watch", "--bag", corrupt_bag, "--fast"],
        ["evaluate", corrupt_bag, "--labels", labels, "-j", "1"],
        ["extract", corrupt_bag, tmp_path / "out"],
    ):
        line = one_error_line(run(*args))
        assert f"recording '{corrupt_bag}'" in line and "corrupt" in line, (args, line)


def test_extract_of_a_bag_that_fails_part_way_lists_what_it_wrote(corrupt_bag, tmp_path):
    out = tmp_path / "out"
    line = one_error_line(run("extract", corrupt_bag, out))
    with (out / "frames.csv").open() as fh:
        listed = [(r["color"], r["depth"]) for r in csv.DictReader(fh)]
    assert listed and f"the {len(listed)} frames read before it" in line
    on_disk = sorted(p.name for p in out.glob("frame_*.png"))
    assert on_disk == sorted(name for pair in listed for name in pair)  # nothing unlisted
    assert run("track", out, "-j", "1", "--json").exit_code in (0, 1)  # a folder to read
