"""dgli_vision.verify: one call for "did the fold work?", as dgli verify; and a request
that no frame could satisfy named as the mistake it is (exit 2), not as a failed fold."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import pytest
from click.testing import CliRunner

import dgli_vision
from dgli_vision.cli import main
from dgli_vision.core.errors import InvalidValueError

SAMPLES = Path(__file__).resolve().parents[1] / "sample_images"
CORNER_C = [SAMPLES / "02_000_color.png", SAMPLES / "02_000_depth.png"]  # 02/C
FLAT = [SAMPLES / "01_000_color.png", SAMPLES / "01_000_depth.png"]
TWO = [SAMPLES / "04_000_color.png", SAMPLES / "04_000_depth.png"]  # 04/CD


def test_verify_is_what_the_command_says():
    check = dgli_vision.verify(*CORNER_C, expect="02/C", legs={"BC": 194, "CD": 158})
    assert check.success is True and check.state == ("02", "C")
    res = CliRunner().invoke(main, ["verify", *map(str, CORNER_C), "--expect", "02/C",
                                    "--legs", "BC=194,CD=158", "--json"])
    assert res.exit_code == 0
    assert json.loads(res.stdout) == {**check.to_json(), "frame": "camera"}


def test_legs_as_text_or_a_dict_and_arrays_or_files_agree():
    rgb = cv2.cvtColor(cv2.imread(str(CORNER_C[0])), cv2.COLOR_BGR2RGB)
    depth = cv2.imread(str(CORNER_C[1]), cv2.IMREAD_UNCHANGED)
    a = dgli_vision.verify(*CORNER_C, expect="02/C", legs="BC=100,CD=240")
    b = dgli_vision.verify(rgb, depth, expect=("02", "C"), legs={"CD": 240, "BC": 100},
                           intrinsics=SAMPLES / "intrinsics.json")
    assert a.success is False and a == b and "leg CD 82 mm shorter" in a.line()


def test_a_plans_step_is_checked_with_its_state_and_crease():
    step = dgli_vision.plan(*FLAT, goal="02/C").steps[0]
    after = dgli_vision.verify(*CORNER_C, step=step)
    assert after.fold == "C over" and after.errors["crease_mm"] is not None
    before = dgli_vision.verify(*FLAT, step=step)  # the fold was not made
    assert before.success is False and before.reasons[0].startswith("wrong state: 01")


@pytest.mark.parametrize(
    ("kwargs", "says"),
    [
        ({"expect": "04", "legs": "AB=180,DA=180"}, "give --expect 04/AB or 04/DA"),
        ({"expect": "04/CD", "legs": "AB=180,DA=180"}, "folds corners C and D, not corner A"),
        ({"expect": "01", "legs": "AB=180,DA=180"}, "01 has no fold"),
        ({"expect": "09/CD", "legs": "AB=180,DA=180"}, "has no corner fold"),
        ({"expect": "02/C", "inset": 120}, "has no strip or half fold"),
        ({"expect": "02/C", "inset": 120, "tip": (1, 2)}, "not inset and tip"),
        ({"expect": "13"}, "expect:"),
        ({"expect": "02/C", "tip": (1, 2, 3)}, "tip must be (u, v)"),
        ({}, "give expect="),
    ],
)
def test_a_request_no_frame_could_satisfy_is_refused_before_looking(kwargs, says):
    with pytest.raises(InvalidValueError) as exc:
        dgli_vision.verify("never-read.png", "never-read.png", **kwargs)
    assert says in str(exc.value)


def test_the_command_names_the_mistake_in_the_request_with_exit_2():
    res = CliRunner().invoke(main, ["verify", *map(str, TWO), "--expect", "04",
                                    "--legs", "AB=180,DA=180"])
    assert res.exit_code == 2 and "Traceback" not in res.output and res.stdout == ""
    (line,) = res.stderr.strip().splitlines()
    assert line == ("error: --expect 04 names no variant, and legs AB=180,DA=180 are corner "
                    "A's: give --expect 04/AB or 04/DA (the states of 04 that fold corner A)")
    fine = CliRunner().invoke(main, ["verify", *map(str, TWO), "--expect", "04/DA",
                                     "--legs", "AB=180,DA=180"])
    assert fine.exit_code == 1 and fine.stdout.startswith("failed: wrong state: 04/CD")
