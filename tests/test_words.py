"""Issue 41 items 9 and 15: counts in the right number ("in 1 step"), and a recording's
frames called frames, not pairs, by dgli track (its lines, its report, its --resume)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from dgli_vision.cli import main
from dgli_vision.core.run_lock import ResumeMismatchError, check_resume, run_header
from dgli_vision.core.words import counted

ROOT = Path(__file__).resolve().parents[1]


def test_counted_is_singular_for_one_only():
    assert counted(1, "step") == "1 step"
    assert [counted(n, "pair") for n in (0, 2)] == ["0 pairs", "2 pairs"]
    assert counted(2, "class", "classes") == "2 classes"


def test_a_one_step_plan_says_one_step():
    out = CliRunner().invoke(main, ["plan", "--from", "01", "--goal", "02/A"]).output
    assert "01 to 02/A in 1 step: fold A over" in out, out


def test_track_calls_its_frames_frames(tmp_path):
    frames = tmp_path / "frames"
    frames.mkdir()
    shutil.copy(ROOT / "sample_images" / "intrinsics.json", frames)
    for kind in ("color", "depth"):
        shutil.copy(ROOT / "sample_images" / f"01_000_{kind}.png", frames / f"f0_{kind}.png")
    (frames / "labels.csv").write_text("color,depth,label\nf0_color.png,f0_depth.png,01\n")
    report = tmp_path / "report"
    res = CliRunner().invoke(main, ["track", str(frames), "-j", "1", "--report", str(report)])
    assert res.exit_code == 0, res.output
    assert res.output.startswith("1 frame; starts as 01"), res.output
    assert "answered 100% of the frames read" in res.output
    for page in ("report.md", "report.html"):
        text = (report / page).read_text()
        assert "of the frames read" in text and "pairs" not in text, page


def test_a_track_resumed_on_other_frames_names_the_list_of_frames():
    with pytest.raises(ResumeMismatchError, match="list of frames changed"):
        check_resume("r.jsonl", run_header("track", {"pairs": "a"}),
                     run_header("track", {"pairs": "b"}))
    with pytest.raises(ResumeMismatchError, match="list of pairs changed"):
        check_resume("r.jsonl", run_header("evaluate", {"pairs": "a"}),
                     run_header("evaluate", {"pairs": "b"}))
