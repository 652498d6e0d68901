"""Any napkin size: ``--size W[xH]`` keeps the stickers' distances from the corners,
scales the fold sizes with the cloth, and a reference set built for that cloth
classifies renders of it."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.cli import main
from dgli_vision.core.layout import default_layout, layout_of_size, parse_size
from dgli_vision.sim.cloth.states import sample_state


def _distance_to_nearest_corner(layout):
    d = layout.sticker_uv[:, None, :] - layout.corner_uv[None, :, :]
    k = np.abs(d).sum(axis=2).argmin(axis=1)
    return np.abs(d[np.arange(len(k)), k])


@pytest.mark.parametrize(
    ("text", "size"),
    [("300", (300.0, 300.0)), ("500x700", (500.0, 700.0)), ("450X450mm", (450, 450))],
)
def test_sizes_are_read_as_w_or_w_x_h_in_mm(text, size):
    assert parse_size(text) == size


@pytest.mark.parametrize("text", ["abc", "0", "300x", "-400", "200"])
def test_a_bad_or_too_small_size_is_refused_in_one_line(text):
    r = CliRunner().invoke(main, ["simulate", "unused", "--size", text])
    assert r.exit_code == 2
    assert "--size" in r.output and text in r.output


@pytest.mark.parametrize("size", [(300.0, 300.0), (500.0, 700.0)])
def test_stickers_keep_their_distances_from_the_corners(size):
    other = layout_of_size(size)
    assert (other.width_mm, other.height_mm) == size
    np.testing.assert_allclose(
        _distance_to_nearest_corner(other), _distance_to_nearest_corner(default_layout())
    )


def test_fold_sizes_scale_with_the_cloth_along_each_side():
    rect = layout_of_size((500.0, 700.0))
    # a strip folded from side AB reaches into the napkin along its height (700 = 1.75x)
    strip = sample_state("09", "AB", 3, layout=rect).params["inset_mm"]
    assert 125 * 1.75 <= strip <= 140 * 1.75
    # from side BC, along its width (500 = 1.25x)
    half = sample_state("11", "BC", 3, layout=rect).params["inset_mm"]
    assert 198 * 1.25 <= half <= 210 * 1.25
    # corner B's legs: along BC (height) and along AB (width)
    leg_bc, leg_ab = sample_state("02", "B", 3, layout=rect).params["legs_mm"]["B"]
    assert 150 * 1.75 <= leg_bc <= 200 * 1.75 and 150 * 1.25 <= leg_ab <= 200 * 1.25


def test_the_nominal_size_draws_the_same_states_as_before():
    a = sample_state("05", "AB/A", 11)
    b = sample_state("05", "AB/A", 11, layout=layout_of_size((400.0, 400.0)))
    assert np.array_equal(a.sticker_points, b.sticker_points)


def _invoke(args):
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 0, r.output
    return r


# 500 x 700 (not square: each side its own scale) runs by default; the square 300 mm
# napkin goes through the same code with one scale, and is kept for `-m slow` (9 s of CPU).
@pytest.mark.parametrize("size", [pytest.param("300", marks=pytest.mark.slow), "500x700"])
def test_references_built_for_a_napkin_size_classify_renders_of_that_napkin(size, tmp_path):
    db, refs, renders = tmp_path / "db", tmp_path / "refs.json", tmp_path / "renders"
    _invoke(["simulate", str(db), "--per-class", "8", "--in-progress", "0", "--size", size])
    _invoke(["references", "build", str(db), "-o", str(refs), "--size", size])
    assert json.loads(refs.read_text())["provenance"]["napkin_mm"] == list(parse_size(size))
    _invoke(["render", str(renders), "--seed", "5", "--size", size])
    r = _invoke(["evaluate", str(renders), "--references", str(refs), "-j", "1", "--json"])
    report = json.loads(r.output)
    labels, confusion = report["labels"], np.array(report["confusion"])
    right = int(np.trace(confusion[:, : len(labels)]))
    wrong = int(confusion[:, : len(labels)].sum()) - right
    assert right >= 10 and wrong <= 1, (right, wrong, confusion)


def test_a_reference_set_is_built_only_for_the_size_its_database_was_simulated_for(tmp_path):
    db = tmp_path / "db"
    _invoke(["simulate", str(db), "--per-class", "1", "--in-progress", "0"])
    r = CliRunner().invoke(
        main, ["references", "build", str(db), "-o", str(tmp_path / "r.json"), "--size", "300"]
    )
    assert r.exit_code == 2
    (line,) = r.output.strip().splitlines()
    assert "400 x 400" in line and "--size 300x300" in line
