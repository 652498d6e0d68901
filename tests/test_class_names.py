"""A class is read the same way everywhere: its id (02), the id without its zero (2), its
name (corner-over), or both (02_corner-over, as class folders are named)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from dgli_vision.cli import main
from dgli_vision.core.classes import class_id_of
from dgli_vision.planning.plan import parse_state

SAMPLES = Path(__file__).resolve().parents[1] / "sample_images"


@pytest.mark.parametrize(
    "text, cid",
    [("2", "02"), ("02", "02"), ("corner-over", "02"), ("Corner_Over", "02"),
     ("02_corner-over", "02"), ("02 corner-over", "02"), ("8", "08"), ("12", "12"),
     ("four corners centre", "08"), ("03_corner-over", None), ("13", None), ("0", None),
     ("", None), ("corner", None),
     # ASCII digits only: Arabic-Indic 02 was read as 02, a superscript 2 raised
     ("\u0660\u0662", None), ("\uff10\uff12", None), ("\u00b2", None),
     ("\u0662_corner-over", None)],
)
def test_a_class_is_read_from_its_id_or_name(text, cid):
    assert class_id_of(text) == cid


def test_class_ids_in_other_digits_are_refused_saying_so(tmp_path):
    arabic = "\u0660\u0662"  # 02 in Arabic-Indic digits
    flat = [str(SAMPLES / "01_000_color.png"), str(SAMPLES / "01_000_depth.png")]
    for args in (["plan", *flat, "--goal", arabic],
                 ["plan", "--from", arabic, "--goal", "08"],
                 ["verify", *flat, "--expect", arabic]):
        res = CliRunner().invoke(main, args)
        assert res.exit_code == 2 and "Traceback" not in res.output, (args, res.output)
        assert f"unknown class '{arabic}' (its digits are not the ASCII digits 0-9)" in (
            res.output), res.output
    folder = _folder(tmp_path, [f"01_000_color.png,01_000_depth.png,{arabic},",
                                "02_000_color.png,02_000_depth.png,02,C"])
    res = CliRunner().invoke(main, ["evaluate", str(folder), "-j", "1"])
    assert res.exit_code == 2 and "Traceback" not in res.output
    assert f"class '{arabic}' (its digits are not the ASCII digits 0-9) is not" in res.output


def test_plan_takes_a_goal_by_short_id_or_name():
    assert parse_state("8", need_variant=False) == ("08", None)
    assert parse_state("corner-over/A") == ("02", "A")
    with pytest.raises(ValueError, match="a name such as corner-over"):
        parse_state("13")
    res = CliRunner().invoke(main, ["plan", "--from", "flat", "--goal", "8", "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.output)["goal"] == {"class": "08", "variant": None}


def _folder(tmp_path: Path, rows: list[str]) -> Path:
    folder = tmp_path / "set"
    folder.mkdir()
    shutil.copy(SAMPLES / "intrinsics.json", folder)
    for name in ("01_000", "02_000"):
        for kind in ("color", "depth"):
            shutil.copy(SAMPLES / f"{name}_{kind}.png", folder)
    (folder / "labels.csv").write_text("color,depth,label,variant\n" + "\n".join(rows) + "\n")
    return folder


def test_labels_take_short_ids_and_names(tmp_path):
    from dgli_vision.sources.labelled import find_labelled_pairs

    folder = _folder(tmp_path, ["01_000_color.png,01_000_depth.png,flat,",
                                "02_000_color.png,02_000_depth.png,2,C"])
    pairs, problems = find_labelled_pairs(folder)
    assert [p.label for p in pairs] == ["01", "02"] and problems == []


def test_a_second_bad_row_is_called_a_bad_row(tmp_path):
    folder = _folder(tmp_path, ["01_000_color.png,01_000_depth.png,13,",
                                "02_000_color.png,02_000_depth.png,02,Q"])
    res = CliRunner().invoke(main, ["evaluate", str(folder), "-j", "1"])
    assert res.exit_code == 2
    assert "class '13' is not a class: 01-12 (or 1-12)" in res.output
    assert "(and 1 more bad row)" in res.output


def test_verify_takes_the_expected_state_by_name():
    res = CliRunner().invoke(main, [
        "verify", str(SAMPLES / "02_000_color.png"), str(SAMPLES / "02_000_depth.png"),
        "--expect", "corner-over/C", "--intrinsics", str(SAMPLES / "intrinsics.json"),
    ])
    assert res.exit_code == 0 and res.output.startswith("success: 02/C reached"), res.output


def test_conditions_are_read_whatever_their_case():
    from dgli_vision.cli.options import parse_conditions

    assert parse_conditions(None, None, "Gloss, JPEG,clean") == ("gloss", "jpeg", "clean")
