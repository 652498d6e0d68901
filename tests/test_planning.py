"""Affordances (corners a robot can grasp, folds seen) and plans towards a goal state."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import dgli_vision
from dgli_vision.classifier.pipeline import classify_frame
from dgli_vision.classifier.references import load_references
from dgli_vision.cli.main import main
from dgli_vision.core.camera import Intrinsics
from dgli_vision.core.layout import default_layout
from dgli_vision.planning.api import plan_frame
from dgli_vision.planning.check import run_pair
from dgli_vision.planning.plan import PlanRefused, parse_state, shortest_path
from dgli_vision.planning.truth import corner_truth
from dgli_vision.sim.dataset import render_sample
from dgli_vision.sources.frames import RGBDFrame

SAMPLES = Path(__file__).resolve().parents[1] / "sample_images"
SMALL = Intrinsics(640, 360, 302.5, 302.5, 319.5, 179.5)


@pytest.fixture(scope="module")
def refs():
    return load_references(None)


def _frame(r) -> RGBDFrame:
    return RGBDFrame(r.color, r.depth_mm, r.intrinsics, "<render>", "<render>", "given")


def test_corners_on_renders_match_the_simulators_truth(refs):
    layout = default_layout()
    errors, states, grasp = [], [], []
    for class_id in ("01", "03", "05", "07", "09", "11", "12"):
        s = render_sample(class_id, 0, 2026, intrinsics=SMALL)
        result = classify_frame(_frame(s.result), refs)
        assert result.prediction is not None
        corners = result.prediction.corners
        assert list(corners) == ["A", "B", "C", "D"]
        for c, (state, free, world) in zip(corners.values(), corner_truth(s.state, layout)):
            states.append(c.state == state)
            grasp.append(c.graspable == free)
            if free and c.graspable:
                truth = s.result.pose.world_to_camera(world[None])[0]
                errors.append(np.linalg.norm(np.asarray(c.point) - truth) * 1e3)
    assert all(states)
    assert np.mean(grasp) >= 0.95
    assert len(errors) >= 15 and np.median(errors) < 10.0


def test_classify_json_has_corners_and_folds():
    result = CliRunner().invoke(
        main,
        ["classify", str(SAMPLES / "05_000_color.png"), str(SAMPLES / "05_000_depth.png"),
         "--json"],
    )
    data = json.loads(result.output)
    assert set(data["corners"]) == {"A", "B", "C", "D"}
    for c in data["corners"].values():
        assert set(c) == {"point", "pixel", "state", "graspable", "placed_by"}
    # 05 BC/B: B's flap lies on C's, so B can be grasped and C cannot
    assert data["corners"]["B"]["state"] == "on a flap over" and data["corners"]["B"]["graspable"]
    assert data["corners"]["C"]["state"] == "on a flap over"
    assert not data["corners"]["C"]["graspable"]
    assert [f["fold"] for f in data["folds"]] == ["C over", "B over crossing C"]
    assert all(len(f["line"]) == 2 for f in data["folds"])


def test_shortest_path_follows_the_fold_graph():
    assert shortest_path(("03", "A"), ("11", "BC")) == [
        ("unfold", "A under", ("01", None)),
        ("fold", "BC half", ("11", "BC")),
    ]
    assert [s[2] for s in shortest_path(("01", None), ("08", None))] == [
        ("02", "A"), ("04", "AB"), ("07", "C"), ("08", None)
    ]
    assert parse_state("05/AB/B") == ("05", "AB/B")
    with pytest.raises(ValueError, match="needs a variant"):
        parse_state("02")


def test_a_state_with_a_variant_it_cannot_have_is_named_plainly():
    res = CliRunner().invoke(main, ["plan", "--from", "08/A", "--goal", "01"])
    assert res.exit_code == 2 and "Traceback" not in res.output
    assert "class 08 has no variant; write it as 08 (not 08/A)" in res.output
    assert "None" not in res.output
    with pytest.raises(ValueError, match=r"class 02 has no variant 'E'; it has 02/A, 02/B, "):
        parse_state("02/E")


def test_plan_from_a_state_without_an_image():
    runner = CliRunner()
    result = runner.invoke(main, ["plan", "--from", "02/A", "--goal", "05/AB/B", "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert data["from"] == {"class": "02", "variant": "A"}
    # a corner-over flap is too small for B to cross: A is unfolded and folded again
    first, *_, last = data["steps"]
    assert (first["action"], first["corner"]) == ("unfold", "A")
    assert first["expect"] == {"class": "01", "variant": None}
    assert (last["action"], last["fold"]) == ("fold", "B over crossing A")
    assert last["expect"] == {"class": "05", "variant": "AB/B"}
    assert first["grasp"]["point"] is None
    bad = runner.invoke(main, ["plan", "--from", "02", "--goal", "08"])
    assert bad.exit_code == 2


def test_plan_from_an_image_gives_a_pick_and_place(tmp_path):
    out = tmp_path / "plan.png"
    result = CliRunner().invoke(
        main,
        ["plan", str(SAMPLES / "05_000_color.png"), str(SAMPLES / "05_000_depth.png"),
         "--goal", "02/C", "--json", "--overlay", str(out)],
    )
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    (step,) = data["steps"]
    assert step["action"] == "unfold" and step["corner"] == "B"
    assert set(step) >= {"grasp", "place", "fold_line", "lift_height", "expect"}
    grasp, place = np.array(step["grasp"]["point"]), np.array(step["place"]["point"])
    ends = np.array(step["fold_line"])
    # the fold line is the perpendicular bisector of grasp -> place: equally far from both
    mid = ends.mean(axis=0)
    assert abs(np.linalg.norm(grasp - mid) - np.linalg.norm(place - mid)) < 0.02
    assert out.is_file()


def test_no_plan_when_the_state_cannot_be_told(refs):
    s = render_sample("02", 0, 7, intrinsics=SMALL, conditions=("mirror",))
    frame = _frame(s.result)
    result = classify_frame(frame, refs)
    assert result.prediction is None
    with pytest.raises(PlanRefused, match="cannot be told"):
        plan_frame(result, frame, ("08", None), default_layout())


def test_python_plan_matches_the_command():
    p = dgli_vision.plan(goal="12/C", start="01")
    assert [(s.action, s.fold) for s in p.steps] == [("fold", "C diagonal")]


@pytest.mark.parametrize(
    "start,goal",
    [(("01", None), ("02", "C")), (("06", "BD"), ("02", "B")), (("09", "CD"), ("01", None))],
)
def test_closed_loop_in_the_simulator(refs, start, goal):
    row = run_pair(start, goal, (99, 1), refs, intrinsics=SMALL)
    assert row.outcome == "right", row
    if start != ("01", None):  # the other two are unfolds: no crease to check
        assert row.geometry is None
        return
    # the fold made lands near the planned crease, and the after frame measures it
    g = row.geometry
    assert g["fold"] == "C over" and g["why"] is None, g
    assert g["made"]["crease_mm"] < 20 and g["made"]["tip_mm"] < 20, g
    assert g["seen"]["crease_mm"] < 20 and g["seen"]["tip_mm"] < 20, g
    assert g["measure_mm"] < 5, g


def test_check_table_reports_the_geometry_against_the_plan():
    from dgli_vision.core.fold_measure import Crease
    from dgli_vision.planning.check import CheckRow, check_table, fold_errors

    layout = default_layout()
    planned = Crease.through((180.0, 0.0), (0.0, 180.0))  # A over, legs 180 mm

    def row(shift: float, seen_shift: float | None) -> CheckRow:
        made = Crease.through((180.0 + shift, 0.0), (0.0, 180.0 + shift))
        seen = None
        if seen_shift is not None:
            class _G:  # a measured fold's geometry: its crease, no why
                why = None
                crease = Crease.through((180.0 + seen_shift, 0.0), (0.0, 180.0 + seen_shift))
            seen = _G()
        geometry = fold_errors("A over", planned, made, seen, layout,
                               None if seen else "not measured")
        return CheckRow(("01", None), ("02", "A"), 1, ("01", None), ("02", "A"), ("02", "A"),
                        "right", geometry=geometry)

    # made 5, 15 and 40 mm beyond the plan (legs longer: the crease moves by s / sqrt 2)
    rows = [row(5.0, 6.0), row(15.0, 15.0), row(40.0, None)]
    g = check_table(rows)["geometry"]
    assert g["fold_steps"] == 3 and g["made"]["measured"] == 3 and g["seen"]["measured"] == 2
    # the legs s longer move the crease by s / sqrt 2, the tip by twice that
    assert g["made"]["crease_mm"]["max"] == pytest.approx(40.0 / 2**0.5, abs=0.1)
    assert g["made"]["tip_mm"]["median"] == pytest.approx(15 * 2**0.5, abs=0.1)
    assert g["made"]["success"] == {"10": pytest.approx(1 / 3, abs=1e-3),
                                    "20": pytest.approx(1 / 3, abs=1e-3),
                                    "45": pytest.approx(2 / 3, abs=1e-3)}
    assert g["seen"]["success"]["45"] == pytest.approx(2 / 3, abs=1e-3)
    assert g["not_seen"] == {"not measured": 1}
    assert g["measure_mm"]["max"] == pytest.approx(1.0 / 2**0.5, abs=0.05)


def test_track_frames_carry_corners_and_folds(refs):
    from dgli_vision.analysis.evaluate import (
        _classify_pair,
        outcome_from_dict,
    )
    from dgli_vision.analysis.track import track_outcomes
    from dgli_vision.sources.labelled import LabelledPair

    pairs = [
        LabelledPair(str(SAMPLES / f"{n}_000_color.png"), str(SAMPLES / f"{n}_000_depth.png"), n)
        for n in ("01", "02")
    ]
    outcomes = [_classify_pair(p, refs, distances=True) for p in pairs]
    # a resumed run reads them back from results.jsonl
    outcomes = [outcome_from_dict(json.loads(json.dumps(o.to_json()))) for o in outcomes]
    frames = track_outcomes(outcomes, refs).to_json()["frames"]
    assert frames[0]["corners"]["A"]["state"] == "flat" and frames[0]["folds"] == []
    assert frames[1]["corners"]["C"]["state"] == "on a flap over"
    assert [f["fold"] for f in frames[1]["folds"]] == ["C over"]
