"""`dgli label`: each fold's geometry from the simulator's meshes, and `--goal`."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.cli import main
from dgli_vision.core.classes import VARIANTS
from dgli_vision.core.fold_measure import Crease, fold_measures
from dgli_vision.core.layout import default_layout
from dgli_vision.labelling.episodes import ReadOptions
from dgli_vision.labelling.export import remesh, rigid_motion, write_npz
from dgli_vision.labelling.goal import parse_goal
from dgli_vision.labelling.label import EpisodeLabels
from dgli_vision.labelling.run import LabelJob, label_episodes
from dgli_vision.sim.cloth.mesh import flat_mesh
from dgli_vision.sim.cloth.states import draw_fold_steps, make_state, sample_state

SEED = 41


def _label(path: str, **kw) -> EpisodeLabels:
    (result,) = label_episodes(LabelJob((path,), ReadOptions(), **kw))
    assert isinstance(result, EpisodeLabels), result
    return result


def _errors(word: str, got: dict, want: dict) -> list[float]:
    """|measured - true| of every size of one fold (mm; the tip: its distance)."""
    out = []
    for key, value in want.items():
        if key == "legs_mm":
            out += [abs(got[key][e] - v) for e, v in value.items() if v is not None]
        elif key == "tip_mm":
            out.append(math.dist(got[key], value))
        elif key.endswith("_mm"):
            out.append(abs(got[key] - value))
    return out


@pytest.mark.parametrize("remeshed", [False, True])
def test_fold_geometry_from_meshes_within_2_mm_of_the_truth(tmp_path, remeshed):
    """Every class (folds under and half folds too: a mesh hides nothing), wrinkled and
    placed at random, on the simulator's grid and remeshed (3,000 vertices)."""
    rng = np.random.default_rng(SEED)
    states = [sample_state(c, vs[-1], np.random.default_rng([SEED, int(c)]))
              for c, vs in VARIANTS.items() if c != "01"]
    meshes = [flat_mesh(default_layout())] + [s.mesh for s in states]
    path = tmp_path / "folds.npz"
    if remeshed:
        rm = remesh((400.0, 400.0), 3000, rng)
        write_npz(path, rigid_motion(rm.positions(meshes), rng), faces=rm.faces)
    else:
        pos = np.stack([m.xyz for m in meshes])
        write_npz(path, rigid_motion(pos, rng), grid=meshes[0].shape)
    ep = _label(str(path))
    layout = default_layout()
    assert ep.frames[0].folds == ()  # the flat cloth has none
    worst = 0.0
    for frame, state in zip(ep.frames[1:], states):
        assert (frame.class_id, frame.variant) == (state.class_id, state.variant)
        creases = state.params["creases_mm"]
        assert sorted(f["fold"] for f in frame.folds) == sorted(creases)
        for f in frame.folds:
            assert f["geometry_from"] == "mesh" and f["why"] is None, f
            want = fold_measures(f["fold"], Crease.through(*creases[f["fold"]]), layout)
            errors = _errors(f["fold"], f, want)
            assert errors and max(errors) < 2.0, (state.class_id, f, want)
            worst = max(worst, max(errors))
    assert worst > 0.0  # measured, not copied


def _corner_state(legs: tuple[float, float], yaw: float, offset: tuple[float, float]):
    """02/B folded with the given legs (BC, AB), wrinkled and placed as given."""
    layout = default_layout()
    steps, params = draw_fold_steps("02", "B", layout, np.random.default_rng(SEED))
    from dgli_vision.sim.cloth.states import corner_fold_line

    steps = [corner_fold_line(layout, "B", *legs)]
    params["creases_mm"] = {"B over": [list(steps[0].p0), list(steps[0].p1)]}
    return make_state("02", "B", steps, layout=layout, wrinkle_mm=5.0, yaw=yaw,
                      offset_m=offset, rng=SEED, params=params)


def test_goal_benchmark_distance_and_ours_side_by_side(tmp_path):
    yaw, offset = 0.7, (0.02, -0.03)
    flat = make_state("01", None, [], yaw=yaw, offset_m=offset, wrinkle_mm=5.0, rng=SEED)
    good = _corner_state((182.0, 177.0), yaw, offset)  # as planned: legs 180, 180
    short = _corner_state((150.0, 150.0), yaw, offset)  # the corner 42 mm short
    paths = []
    for name, last in (("good", good), ("short", short)):
        p = tmp_path / f"{name}.npz"
        write_npz(p, np.stack([flat.mesh.xyz, last.mesh.xyz]), grid=flat.mesh.shape)
        paths.append(str(p))
    goal = parse_goal("02:AB=180,BC=180")
    assert goal.variant == "B"  # the legs name the corner
    ok, bad = (_label(p, goal=goal).goal for p in paths)
    assert ok["goal"] == "02/B" and ok["dgli"]["success"] is True, ok
    assert ok["softgym"]["success"] is True and ok["softgym"]["max_distance_mm"] < 15, ok
    assert ok["dgli"]["folds"][0]["tip_mm"] < 5, ok
    # 30 mm shorter legs: the tip lands 42 mm short; the benchmark sees it as its
    # largest vertex distance, ours as the crease and tip errors
    assert bad["dgli"]["success"] is False and bad["softgym"]["max_distance_mm"] > 40, bad
    assert bad["dgli"]["folds"][0]["tip_mm"] == pytest.approx(30 * 2**0.5, abs=2), bad
    assert any("tip" in r for r in bad["dgli"]["reasons"]), bad
    # the command line: its JSON, its line and the summary
    res = CliRunner().invoke(main, ["label", *paths, "--goal", "02/B:AB=180,BC=180"])
    assert res.exit_code == 0, res.output
    assert "goal 02/B: benchmark success" in res.output and "dgli success" in res.output
    assert "B over: tip 42 mm off the planned one" in res.output, res.output
    res = CliRunner().invoke(main, ["label", paths[1], "--goal", "09:inset=130", "--json"])
    data = json.loads(res.stdout)
    assert data["episodes"][0]["goal"]["dgli"]["reasons"][0].startswith(
        "the episode ends in 02/B"), data
    assert data["summary"]["goal"] == {"episodes": 1, "softgym_success": 0,
                                       "dgli_success": 0, "dgli_cannot_tell": 0}
    # without the frames' geometry (faster): no sizes per frame, the goal all the same
    res = CliRunner().invoke(main, ["label", paths[0], "--goal", "02:AB=180,BC=180",
                                    "--no-geometry", "--json"])
    ep = json.loads(res.stdout)["episodes"][0]
    assert [f["folds"] for f in ep["frames"]] == [[], []]
    assert ep["goal"]["dgli"]["success"] is True, ep["goal"]


@pytest.mark.parametrize("text,message", [
    ("13", "unknown class"),
    ("02:AB=x,BC=180", "not a number"),
    ("09:AB=180,BC=180", "no corner fold"),
    ("02/A:AB=180,BC=180", "corner B is not folded"),
    ("02:inset=120", "no side fold"),
])
def test_bad_goals_are_one_line_errors(tmp_path, text, message):
    res = CliRunner().invoke(main, ["label", str(tmp_path / "none.npz"), "--goal", text])
    assert res.exit_code == 2 and message in res.output, res.output
    assert "Traceback" not in res.output
