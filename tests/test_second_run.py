"""A second run into the same report folder: what the README, the help and the command
say agree (the run's results.jsonl is kept unless --resume or --overwrite is given)."""

from __future__ import annotations

import shutil
from pathlib import Path

from click.testing import CliRunner

from dgli_vision.cli import main

ROOT = Path(__file__).resolve().parents[1]


def test_a_second_track_into_the_same_folder_asks_for_resume_or_overwrite(tmp_path):
    frames = tmp_path / "frames"
    frames.mkdir()
    shutil.copy(ROOT / "sample_images" / "intrinsics.json", frames)
    for kind in ("color", "depth"):
        shutil.copy(ROOT / "sample_images" / f"01_000_{kind}.png", frames / f"f000_{kind}.png")
    report = tmp_path / "report"
    args = ["track", str(frames), "-j", "1", "--report", str(report)]
    assert CliRunner().invoke(main, args).exit_code == 0
    again = CliRunner().invoke(main, args)
    assert again.exit_code == 2
    said = "holds the results of an earlier run; use --resume to go on with it, or " \
           "--overwrite to start again"
    assert said in again.output
    assert CliRunner().invoke(main, [*args, "--overwrite"]).exit_code == 0
    readme = " ".join((ROOT / "docs" / "usage.md").read_text().split())  # the README's page
    assert "one exception: the `results.jsonl` that `dgli evaluate --report` and `dgli " \
           "track --report` keep of a run" in readme
    for command in ("track", "evaluate"):
        help_text = " ".join(CliRunner().invoke(main, [command, "--help"]).output.split())
        assert "replace the results.jsonl an earlier run left in the report folder" in help_text
