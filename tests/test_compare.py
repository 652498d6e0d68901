"""Baselines, Table 1 and the folding sequences, through the library and the CLI."""

from __future__ import annotations

import json
import re

import cv2
import numpy as np
import pytest
from click.testing import CliRunner
from html_pages import check_page

from dgli_vision.analysis.baselines import (
    align,
    corner_distances,
    discrete_frechet,
    hausdorff,
    segment_distances,
)
from dgli_vision.cli import main
from dgli_vision.core.classes import CLASS_IDS
from dgli_vision.core.fold_graph import folds_of
from dgli_vision.sim.cloth.sequences import folding_sequence
from dgli_vision.sim.database import FOLD_BINS_DEG


def run(args):
    result = CliRunner().invoke(main, args)
    assert "Traceback" not in result.output
    return result


def test_frechet_and_hausdorff_on_known_curves():
    t = np.linspace(0, 1, 11)[:, None]
    p = np.hstack([t, 0 * t, 0 * t])
    q = p + np.array([0.0, 1.0, 0.0])
    assert discrete_frechet(p, q) == pytest.approx(1.0)
    assert hausdorff(p, q) == pytest.approx(1.0)
    # Frechet respects order, Hausdorff does not.
    assert hausdorff(p, p[::-1]) == 0.0
    assert discrete_frechet(p, p[::-1]) == pytest.approx(1.0)


def test_alignment_removes_rotation_and_translation():
    rng = np.random.default_rng(0)
    curve = rng.normal(size=(40, 3))
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.linalg.det(q))
    moved = curve @ q.T + [1.0, -2.0, 3.0]
    aligned = align(moved, curve)
    np.testing.assert_allclose(aligned, curve - curve.mean(axis=0), atol=1e-10)


def test_segment_and_corner_distances():
    seg = np.array([[[0, 0, 0], [1, 0, 0]], [[0, 1, 0], [1, 1, 0]], [[2, 0, 1], [3, 0, 1]]], float)
    np.testing.assert_allclose(segment_distances(seg), [1.0, np.sqrt(2), np.sqrt(3)])
    corners = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    np.testing.assert_allclose(corner_distances(corners), [1, np.sqrt(2), 1, 1, np.sqrt(2), 1])


def test_sequence_truth_changes_past_ninety_degrees():
    frames = folding_sequence("I", frames_per_fold=12)
    assert len(frames) == 25
    labels = [f.class_id for f in frames]
    assert labels[6] == "01" and labels[7] == "02"  # 90 deg, then 105 deg
    assert labels[18] == "02" and labels[19] == "06"
    assert frames[-1].variant == "AC"


@pytest.fixture(scope="module")
def small_db(tmp_path_factory):
    out = tmp_path_factory.mktemp("db")
    args = ["simulate", str(out), "--per-class", "2", "--seed", "5", "--in-progress", "1"]
    result = run(args)
    assert result.exit_code == 0, result.output
    return out


def test_simulate_is_deterministic(small_db, tmp_path):
    again = tmp_path / "again"
    args = ["simulate", str(again), "--per-class", "2", "--seed", "5", "--in-progress", "1"]
    assert run(args).exit_code == 0
    for name in ("truth/05_001.json", "meshes/12_000.ply"):
        assert (again / name).read_bytes() == (small_db / name).read_bytes()
    index_a, index_b = (json.loads((d / "index.json").read_text()) for d in (small_db, again))
    assert index_a["provenance"].pop("command") != index_b["provenance"].pop("command")
    assert index_a == index_b
    truth = json.loads((small_db / "truth" / "03_000.json").read_text())
    assert truth["class"] == "03" and len(truth["coordinates"]) == 28
    assert len(truth["visible"]) == 16 and truth["visible"].count(False) == 4


def test_compare_writes_table_and_heatmaps(small_db, tmp_path):
    report = tmp_path / "report"
    result = run(["compare", str(small_db), "--report", str(report), "--json", "-j", "1"])
    assert result.exit_code == 0, result.output
    table = json.loads((report / "table.json").read_text())
    assert table["columns"] == [
        "database",
        "I",
        "II",
        "III",
        "database by variant",
        "by variant, mirrors merged",
    ]
    assert "mirror" in (report / "table.md").read_text()
    assert set(table["rows"]) == {
        "dgli",
        "dgli+visibility",
        "edges",
        "corners",
        "frechet",
        "hausdorff",
    }
    assert json.loads(result.output.splitlines()[0]) == table
    md = (report / "table.md").read_text()
    assert "| dgli |" in md
    # strict JSON (no Infinity): a number, or null where two groups are not separated
    assert "Infinity" not in (report / "table.json").read_text()
    assert all(v is None or v >= 0 for vals in table["rows"].values() for v in vals)
    for name in table["rows"]:  # every heatmap shown, with what its distance is
        assert f"(distances_{name}.png)" in md
    img = cv2.imread(str(report / "distances_dgli.png"))
    assert img is not None and img.shape[0] > 300
    assert img.std() > 20  # a real picture, not a blank
    # the paper's values beside ours, none invented: its dGLI on the database and III
    assert table["paper"]["columns"] == ["paper: database", "paper: III"]
    assert table["paper"]["rows"]["dgli"] == [0.73, 0.21]
    assert table["paper"]["rows"]["dgli+visibility"] == [None, None]
    # each of the paper's values right after ours that compares with it, those first
    assert ("| representation | by variant, mirrors merged | paper: database | III | "
            "paper: III | database | I | II | database by variant |") in md
    assert re.search(r"\| dgli \| [^|]+ \| 0\.73 \| [^|]+ \| 0\.21 \|", md)
    images, text = check_page(report / "report.html")
    assert images == [f"distances_{name}.svg" for name in table["rows"]]  # linking the PNG
    assert "not the classifier's distance" in text and "paper: database" in text


def test_compare_distances_on_two_workers_are_those_of_one():
    from dgli_vision.analysis.compare import dataset_matrices, sequence_records

    datasets = {"II": sequence_records("II"), "III": sequence_records("III")}
    names = ("dgli", "frechet")
    one = dataset_matrices(datasets, names, jobs=1)
    ticks = []
    two = dataset_matrices(datasets, names, jobs=2, on_progress=ticks.append)
    assert len(ticks) == 4
    for column in datasets:
        for name in names:
            np.testing.assert_array_equal(one[column][name], two[column][name])


def test_sequence_command_reports_changes(tmp_path):
    result = run(["sequence", "III", "--json", "--report", str(tmp_path)])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["true_changes"] == [7]
    assert data["frame_accuracy"] > 0.5
    # the report is what `dgli track --report` writes: the same files, the same timeline
    from dgli_vision.analysis.track_report import TRACK_REPORT_FILES

    assert all((tmp_path / name).is_file() for name in TRACK_REPORT_FILES)
    timeline = json.loads((tmp_path / "timeline.json").read_text())
    assert [c["frame"] for c in timeline["changes"]] == data["detected_changes"]
    assert [f["smoothed_class"] for f in timeline["frames"]] == data["smoothed"]
    assert [f["label"] for f in timeline["frames"]] == data["truth"]
    assert timeline["outcomes"]["right"] == round(data["frame_accuracy"] * data["frames"])
    images, _ = check_page(tmp_path / "report.html")
    assert {"timeline.svg", "distances.svg"} <= set(images)


def test_references_build_from_database(small_db, tmp_path):
    out = tmp_path / "refs.json"
    result = run(["references", "build", str(small_db), "-o", str(out)])
    assert result.exit_code == 0, result.output
    data = json.loads(out.read_text())
    assert data["provenance"]["database"]["seed"] == 5
    assert len(data["references"]) >= 12


def test_references_build_on_missing_database_is_one_line_error(tmp_path):
    result = run(["references", "build", str(tmp_path / "none"), "-o", str(tmp_path / "r.json")])
    assert result.exit_code == 2
    assert result.output.strip().count("\n") == 0
    assert "does not exist" in result.output


def test_database_meshes_read_back(small_db):
    from dgli_vision.core.io import read_mesh_ply

    xyz, tri = read_mesh_ply(small_db / "meshes" / "02_000.ply")
    truth = json.loads((small_db / "truth" / "02_000.json").read_text())
    assert xyz.shape == (81 * 81, 3) and tri.shape == (2 * 80 * 80, 3)
    assert xyz[:, 2].min() >= 0 and truth["class"] == "02"


def test_references_from_a_database_with_folds_in_progress(small_db, tmp_path):
    out = tmp_path / "refs.json"
    assert run(["references", "build", str(small_db), "-o", str(out)]).exit_code == 0
    refs = json.loads(out.read_text())["references"]
    finished = [r for r in refs if not r.get("stage")]
    moving = [r for r in refs if r.get("stage")]
    assert {r["class"] for r in finished} == set(CLASS_IDS)
    assert len(moving) == 52 * len(FOLD_BINS_DEG)
    for r in moving:  # below 90 degrees the fold is not made yet, beyond it it is
        motion, fold = r["stage"].split(",")[0].split(" ", 1)
        assert (fold in folds_of(r["class"], r["variant"])) == (motion == "settling")
        # the stickers standing on a flap past vertical are those of a settling fold
        past = max(r.get("past_rate", [0])) > 0
        assert past == (motion == "settling" and max(r.get("lifted_rate", [0])) > 0)
        # a flap held up near vertical stands higher than a fold laid flat
        if r["stage"].endswith(("50-90 deg", "90-130 deg")):
            assert max(hi for _, hi in r["height_range_mm"]) > 40
    assert all(max(r["lifted_rate"]) > 0 for r in moving if "50-90" in r["stage"])
    assert all(max(hi for _, hi in r["height_range_mm"]) < 20 for r in finished)


# --- the mirror symmetry (why visibility is part of the classifier) --------------------


def test_the_dgli_is_unchanged_by_a_mirror_through_the_table():
    from dgli_vision.core.dgli import cloth_coordinates

    rng = np.random.default_rng(14)
    segments = rng.normal(scale=0.1, size=(200, 8, 2, 3))
    mirrored = segments * np.array([1.0, 1.0, -1.0])
    up = np.array([0.0, 0.0, 1.0])
    a, b = cloth_coordinates(segments, up), cloth_coordinates(mirrored, up)
    np.testing.assert_allclose(b, a, atol=1e-9)
    assert np.abs(a).max() > 0.1  # not trivially zero


@pytest.mark.parametrize(("over", "under", "variant"), [("02", "03", "C"), ("09", "10", "DA")])
def test_a_fold_over_and_the_same_fold_under_have_the_same_coordinates(over, under, variant):
    from dgli_vision.core.distance import pairwise_spearman
    from dgli_vision.sim.cloth.states import sample_state

    for seed in range(3):
        a = sample_state(over, variant, seed).coordinates()
        b = sample_state(under, variant, seed).coordinates()
        # the same fold drawn the same way: apart only by cloth thickness (1 mm)
        assert pairwise_spearman(a[None], b[None])[0, 0] < 0.02


def test_mirror_images_are_derived_from_the_fold_definitions():
    from dgli_vision.core.fold_graph import mirror_group, state_keys

    merged = sorted({mirror_group(k) for k in state_keys() if "|" in mirror_group(k)})
    assert merged == sorted(
        [f"02/{c}|03/{c}" for c in "ABCD"]
        + [f"09/{s}|10/{s}" for s in ("AB", "BC", "CD", "DA")]
        + ["05/AB/A|05/AB/B", "05/BC/B|05/BC/C", "05/CD/C|05/CD/D", "05/DA/D|05/DA/A"]
    )
    assert len({mirror_group(k) for k in state_keys()}) == 32
    assert mirror_group(("12", "B")) == "12/B"


def test_curve_distances_for_a_whole_row_equal_those_pair_by_pair():
    """The Frechet and Hausdorff baselines, computed a row at a time, are the pair-by-
    pair definitions (to rounding)."""
    from dgli_vision.analysis.baselines import (
        align,
        discrete_frechet,
        hausdorff,
        pairwise_curve_distances,
    )

    rng = np.random.default_rng(3)
    curves = rng.normal(size=(7, 12, 3))
    centred = curves - curves.mean(axis=1, keepdims=True)
    for metric, fn in (("frechet", discrete_frechet), ("hausdorff", hausdorff)):
        got = pairwise_curve_distances(curves, metric)
        for a in range(7):
            for b in range(a + 1, 7):
                want = fn(align(centred[a], centred[b]), centred[b])
                assert got[a, b] == pytest.approx(want, rel=1e-12, abs=1e-12)
                assert got[b, a] == got[a, b]
        assert np.all(np.diag(got) == 0)
