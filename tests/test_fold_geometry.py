"""The fold's geometry in mm (legs and tip, inset and skew, offset and turn) and
`dgli verify`: did the fold reach the planned state and sizes?"""

from __future__ import annotations

import json
import math
from functools import lru_cache
from types import SimpleNamespace

import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.classifier.affordances import _plan
from dgli_vision.classifier.fold_geometry import fit_folds
from dgli_vision.classifier.pipeline import classify_frame
from dgli_vision.classifier.references import load_references
from dgli_vision.cli.main import main
from dgli_vision.core.camera import Intrinsics
from dgli_vision.core.fold_measure import Crease, crease_distance_mm, fold_measures, planned_crease
from dgli_vision.core.layout import default_layout
from dgli_vision.planning.verify import parse_legs, verify_fold
from dgli_vision.sim.cloth.states import (
    FoldStep,
    corner_fold_line,
    make_state,
    sample_state,
    side_fold_line,
)
from dgli_vision.sim.dataset import random_camera
from dgli_vision.sim.render import Lighting, SensorModel, render
from dgli_vision.sources.frames import RGBDFrame, write_color, write_depth

SMALL = Intrinsics(640, 360, 302.5, 302.5, 319.5, 179.5)
LAYOUT = default_layout()


def _observe(state, *, every_sticker: bool = False):
    """The stickers of a simulated state as the pipeline would see them, exactly."""
    pts = state.sticker_points
    seen = np.ones(len(pts), bool) if every_sticker else state.visible
    return SimpleNamespace(points_m=pts, visible=seen, heights_mm=pts[:, 2] * 1e3,
                           up=np.array([0.0, 0.0, 1.0]))


def _truth(state, word):
    return fold_measures(word, Crease.through(*state.params["creases_mm"][word]), LAYOUT)


@pytest.mark.parametrize("class_id", ["02", "04", "05", "06", "07", "08", "09", "11", "12"])
def test_geometry_from_exact_markers_is_the_truth(class_id):
    # every fold family: corners (02, 04-08), a strip (09), a half fold (11) and a
    # diagonal fold (12); the half and diagonal folds hide the napkin under the flap,
    # so here every sticker is given (an oracle that sees through the flap)
    state = sample_state(class_id, None, 5, layout=LAYOUT)
    plan = _plan(state.class_id, state.variant, LAYOUT)
    every = class_id in ("11", "12")
    sizes = fit_folds(_observe(state, every_sticker=every), plan.folds, plan.sticker_part,
                      LAYOUT)
    assert sizes
    for g in sizes:
        assert g.why is None, g.why
        want = _truth(state, g.word)
        for key, value in want.items():
            got = g.values[key]
            if key == "legs_mm":
                for edge in value:
                    assert abs(got[edge] - value[edge]) < 1.5, (g.word, edge)
            elif key == "tip_mm":
                assert math.dist(got, value) < 2.0, g.word
            elif key.endswith("_deg"):
                assert abs(got - value) < 0.5, (g.word, key)
            else:
                assert abs(got - value) < 1.0, (g.word, key)


def test_null_where_no_seen_sticker_fixes_the_fold():
    # a flap folded under: its stickers are hidden
    state = sample_state("03", "B", 1, layout=LAYOUT)
    plan = _plan("03", "B", LAYOUT)
    (g,) = fit_folds(_observe(state), plan.folds, plan.sticker_part, LAYOUT)
    assert g.values["legs_mm"] == {"BC": None, "AB": None} and g.values["tip_mm"] is None
    assert "under" in g.why
    # a half fold: the napkin under the flap is hidden, so it cannot be placed
    state = sample_state("11", "CD", 1, layout=LAYOUT)
    plan = _plan("11", "CD", LAYOUT)
    (g,) = fit_folds(_observe(state), plan.folds, plan.sticker_part, LAYOUT)
    assert g.values == {"inset_mm": None, "skew_deg": None}
    assert "napkin under the flap" in g.why
    # a corner whose flap's stickers are all missing
    state = sample_state("02", "A", 1, layout=LAYOUT)
    plan = _plan("02", "A", LAYOUT)
    obs = _observe(state)
    obs.visible = obs.visible & (np.asarray(plan.sticker_part) != 0)
    (g,) = fit_folds(obs, plan.folds, plan.sticker_part, LAYOUT)
    assert g.values["tip_mm"] is None and g.why == "none of the flap's stickers is seen"
    assert json.loads(json.dumps(g.to_json()))["legs_sd_mm"] is None


def test_planned_creases_and_their_distance():
    c = planned_crease("A over", LAYOUT, legs={"AB": 180.0, "DA": 180.0})
    m = fold_measures("A over", c, LAYOUT)
    assert m["legs_mm"] == pytest.approx({"AB": 180.0, "DA": 180.0})
    assert m["tip_mm"] == pytest.approx([180.0, 180.0])
    assert fold_measures("A over", planned_crease("A over", LAYOUT, tip_mm=(180, 180)),
                         LAYOUT)["legs_mm"]["AB"] == pytest.approx(180.0)
    s = planned_crease("CD strip over", LAYOUT, inset_mm=130.0, skew_deg=5.0)
    assert fold_measures("CD strip over", s, LAYOUT) == pytest.approx(
        {"inset_mm": 130.0, "skew_deg": 5.0})
    straight = planned_crease("CD strip over", LAYOUT, inset_mm=130.0)
    # 5 degrees over a 400 mm crease through the middle: 200 tan(5) at either end
    assert crease_distance_mm(s, straight, LAYOUT) == pytest.approx(
        200 * math.tan(math.radians(5)), abs=0.5)
    assert parse_legs("AD=170, ab=180") == {"DA": 170.0, "AB": 180.0}
    for bad in ("AB=180", "AB=180,CD=170", "AC=1,AB=2", "AB=x,DA=1"):
        with pytest.raises(ValueError):
            parse_legs(bad)


def _skewed(step: FoldStep, deg: float) -> FoldStep:
    p0, p1 = np.asarray(step.p0), np.asarray(step.p1)
    mid, half = 0.5 * (p0 + p1), 0.5 * (p1 - p0)
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    turned = np.array([c * half[0] - s * half[1], s * half[0] + c * half[1]])
    return FoldStep(tuple(mid - turned), tuple(mid + turned), step.flap, step.under)


#: Planned folds and how each was carried out: (state, the planned sizes, the fold made).
PAIRS = {
    "corner made as planned": (("02", "B"), {"legs": {"AB": 180.0, "BC": 170.0}},
                               corner_fold_line(LAYOUT, "B", 170.0, 180.0)),
    # the tip 40 mm short of its target: the crease 20 mm nearer the corner
    "corner 40 mm short": (("02", "B"), {"legs": {"AB": 180.0, "BC": 170.0}},
                           corner_fold_line(LAYOUT, "B", 170.0 - 20 * math.sqrt(2) * 170 / 175,
                                            180.0 - 20 * math.sqrt(2) * 180 / 175)),
    "corner crease skewed 15 degrees": (("02", "B"), {"legs": {"AB": 180.0, "BC": 170.0}},
                                        _skewed(corner_fold_line(LAYOUT, "B", 170.0, 180.0), 15)),
    "strip made as planned": (("09", "CD"), {"inset_mm": 130.0},
                              side_fold_line(LAYOUT, "CD", 130.0)),
    "strip crease skewed 15 degrees": (("09", "CD"), {"inset_mm": 130.0},
                                       _skewed(side_fold_line(LAYOUT, "CD", 130.0), 15)),
}


@lru_cache(maxsize=8)
def _after(case: str):
    """The frame after the fold of ``case``, rendered small (made once)."""
    (cid, variant), _, step = PAIRS[case]
    rng = np.random.default_rng(7)
    flat = make_state("01", None, [], layout=LAYOUT, yaw=0.4, wrinkle_mm=3.0, rng=3)
    pose, _ = random_camera(flat, rng, intrinsics=SMALL)
    state = make_state(cid, variant, [step], layout=LAYOUT, yaw=0.4, wrinkle_mm=3.0, rng=3)
    r = render(state, pose, intrinsics=SMALL, lighting=Lighting.random(rng),
               sensor=SensorModel(), rng=rng, layout=LAYOUT)
    return RGBDFrame(r.color, r.depth_mm, r.intrinsics, "<render>", "<render>", "given")


@pytest.fixture(scope="module")
def refs():
    return load_references(None)


@pytest.mark.parametrize("case", list(PAIRS))
def test_verify_tells_a_fold_made_well_from_one_made_badly(refs, case):
    (cid, variant), sizes, _ = PAIRS[case]
    result = classify_frame(_after(case), refs, layout=LAYOUT)
    check = verify_fold(result, (cid, variant), LAYOUT, **sizes)
    if case.endswith("as planned"):
        assert check.success is True, check.line()
        assert check.errors["crease_mm"] < 10.0
    else:
        assert check.success is False, check.line()  # never a success for a bad fold
    if case == "corner 40 mm short":
        assert check.errors["tip_short_mm"] == pytest.approx(40.0, abs=8.0)
        assert "short of its target" in check.line()
    if "skewed" in case:
        assert "crease" in check.line() or "wrong state" in check.line()


def test_verify_cli_exit_codes(refs, tmp_path):
    frames = {}
    for case in ("corner made as planned", "corner 40 mm short"):
        f = _after(case)
        color, depth = tmp_path / f"{len(frames)}_color.png", tmp_path / f"{len(frames)}_depth.png"
        write_color(color, f.color)
        write_depth(depth, f.depth_mm)
        (tmp_path / "intrinsics.json").write_text(json.dumps(SMALL.to_open3d_dict()))
        frames[case] = [str(color), str(depth)]
    run = CliRunner().invoke
    good = run(main, ["verify", *frames["corner made as planned"], "--expect", "02/B",
                      "--legs", "AB=180,BC=170"])
    assert good.exit_code == 0 and good.output.startswith("success: 02/B"), good.output
    bad = run(main, ["verify", *frames["corner 40 mm short"], "--expect", "02/B",
                     "--legs", "AB=180,BC=170", "--json"])
    assert bad.exit_code == 1
    out = json.loads(bad.output)
    assert out["outcome"] == "failed" and out["errors"]["tip_mm"] > 20
    assert set(out["errors"]) >= {"crease_mm", "legs_mm", "tip_mm", "tip_short_mm"}
    wrong = run(main, ["verify", *frames["corner made as planned"], "--expect", "04/AB"])
    assert wrong.exit_code == 1 and "wrong state: 02/B" in wrong.output
    missing = run(main, ["verify", str(tmp_path / "no.png"), frames["corner 40 mm short"][1],
                         "--expect", "02/B"])
    assert missing.exit_code == 2
    both = run(main, ["verify", *frames["corner made as planned"], "--expect", "02/B",
                      "--inset", "100", "--tip", "1,2"])
    assert both.exit_code == 2
