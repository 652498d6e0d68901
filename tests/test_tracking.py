"""Folds in progress and tracking: the fold graph, mid-fold states, the smoothing, and
`dgli render --sequence` + `dgli track` end to end."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from html_pages import check_page

from dgli_vision.analysis.compare import analyse_sequence
from dgli_vision.analysis.track import (
    score_timeline,
    smooth,
    transition_log_matrix,
    viterbi,
)
from dgli_vision.classifier.references import load_references
from dgli_vision.cli import main
from dgli_vision.core.classes import CLASS_IDS, VARIANTS
from dgli_vision.core.fold_graph import fold_edges, folds_of, neighbours, state_keys, unfold
from dgli_vision.sim.cloth.sequences import SEQUENCES, folding_sequence, sequence_label
from dgli_vision.sim.cloth.states import sample_state
from dgli_vision.sim.database import records_from_states

REFS = load_references()

# --- the fold graph -------------------------------------------------------------------


def test_every_state_is_reachable_from_flat_by_single_folds():
    reached, todo = {("01", None)}, [("01", None)]
    while todo:
        here = todo.pop()
        for a, b, _ in fold_edges():
            if a == here and b not in reached:
                reached.add(b)
                todo.append(b)
    assert reached == set(state_keys())
    assert len(state_keys()) == sum(len(VARIANTS[c]) for c in CLASS_IDS)


def test_the_graph_follows_the_class_definitions():
    assert set(neighbours(("01", None))) == {
        (c, v) for c in ("02", "03", "09", "10", "11", "12") for v in VARIANTS[c]
    }
    # two crossing flaps: only the flap folded first can have been there alone
    assert [a for a, b, _ in fold_edges() if b == ("05", "AB/B")] == [("02", "A")]
    # three corners: from two adjacent corners or from two opposite ones
    assert {a for a, b, _ in fold_edges() if b == ("07", "D")} == {
        ("04", "AB"),
        ("04", "BC"),
        ("06", "AC"),
    }
    for key in state_keys():  # moves go both ways
        for other in neighbours(key):
            assert key in neighbours(other)
    assert unfold(("08", None), "C over") == ("07", "C")


def test_the_simulator_folds_what_the_definitions_say():
    for class_id in CLASS_IDS:
        for variant in VARIANTS[class_id]:
            state = sample_state(class_id, variant, 3)
            assert frozenset(state.params["folds"]) == folds_of(class_id, variant)


@pytest.mark.parametrize(("class_id", "variant"), [("04", "AB"), ("11", "CD"), ("07", "B")])
def test_a_fold_in_progress_keeps_the_earlier_class_up_to_90_degrees(class_id, variant):
    last = sorted(folds_of(class_id, variant))[0]
    before = sample_state(class_id, variant, 1, last_fold=last, last_fold_deg=80)
    after = sample_state(class_id, variant, 1, last_fold=last, last_fold_deg=100)
    assert (before.class_id, before.variant) == unfold((class_id, variant), last)
    assert (after.class_id, after.variant) == (class_id, variant)
    assert before.params["stage"] == f"rising {last}"
    # the flap stands up: some of its stickers are well above the table
    assert before.sticker_points[:, 2].max() > 0.05


def test_sequence_labels_change_once_a_fold_passes_90_degrees():
    assert sequence_label("I", 0.5) == ("01", None)
    assert sequence_label("I", 0.51) == ("02", "A")
    assert sequence_label("II", 4.0) == ("08", None)
    for name in SEQUENCES:
        frames = folding_sequence(name, frames_per_fold=4)
        assert (frames[-1].class_id, frames[-1].variant) == SEQUENCES[name][1][-1]


# --- the smoothing --------------------------------------------------------------------


def test_transition_rows_are_probabilities_and_only_folds_are_likely():
    logp = transition_log_matrix()
    p = np.exp(logp)
    np.testing.assert_allclose(p.sum(axis=1), 1.0)
    keys = state_keys()
    i, j, k = keys.index(("01", None)), keys.index(("02", "A")), keys.index(("08", None))
    assert p[i, i] > 0.9 and p[i, j] > 1e-3 and p[i, k] < 1e-8


def test_viterbi_ignores_one_frame_that_jumps_and_fills_gaps():
    keys = state_keys()
    flat, corner, under = (keys.index(k) for k in [("01", None), ("02", "A"), ("03", "A")])
    costs = np.full((12, len(keys)), 1.0)
    costs[:5, flat] = 0.0
    costs[5:, corner] = 0.0
    costs[7] = 1.0
    costs[7, under] = 0.0  # one confident frame of a state no fold away
    costs[9] = np.nan  # a frame that could not be read
    path = viterbi(costs, transition_log_matrix())
    assert list(path) == [flat] * 5 + [corner] * 7


def test_scores_count_changes_within_two_frames_once():
    truth = ["01"] * 5 + ["02"] * 5 + ["06"] * 5
    smoothed = ["01"] * 6 + ["02"] * 2 + ["01"] + ["02"] + ["06"] * 5
    raw = [*smoothed[:-1], None]
    sc = score_timeline(truth, raw, smoothed)
    assert sc.true_changes == (5, 10)
    assert sc.found_changes == (6, 8, 9, 10)
    assert sc.recall == 1.0 and sc.precision == 0.5
    assert sc.smoothed_accuracy == pytest.approx(13 / 15)
    assert sc.raw_accuracy == pytest.approx(12 / 15)


@pytest.mark.parametrize("name", list(SEQUENCES))
def test_dgli_sequence_finds_exactly_the_true_changes(name):
    frames = folding_sequence(name)
    records = records_from_states([(f"{name}_{k}", s) for k, s in enumerate(frames)])
    result = analyse_sequence(records, REFS)
    # the first frame past 90 degrees already shows the fold: the flap leans in
    assert list(result.detected_changes) == list(result.true_changes)
    assert result.smoothed_accuracy == 1.0


def test_smoothing_returns_one_state_per_frame():
    d = np.full((3, len(REFS)), np.nan)
    states, costs = smooth(d, REFS)
    assert len(states) == 3 and costs.shape == (3, len(state_keys()))


# --- end to end -----------------------------------------------------------------------


@pytest.fixture(scope="module")
def half_fold(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("seq") / "III"
    r = CliRunner().invoke(
        main, ["render", str(out), "--sequence", "III", "--frames", "17", "--seed", "5"]
    )
    assert r.exit_code == 0, r.output
    return out


def test_render_sequence_writes_frames_in_order_with_times_and_labels(half_fold):
    with (half_fold / "frames.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert [r["color"] for r in rows] == [f"III_{k:03d}_color.png" for k in range(17)]
    assert float(rows[1]["time"]) > float(rows[0]["time"])
    with (half_fold / "labels.csv").open() as fh:
        labels = [r["label"] for r in csv.DictReader(fh)]
    # frame k has the fold at 180 k / 16 degrees: past 90 from frame 9
    assert labels == ["01"] * 9 + ["11"] * 8


def test_track_smooths_a_folding_recording_into_the_true_timeline(half_fold, tmp_path):
    report = tmp_path / "report"
    r = CliRunner().invoke(main, ["track", str(half_fold), "-j", "1", "--report", str(report)])
    assert r.exit_code == 0, r.output
    assert "-> 11 half-fold AB" in r.output and "frames' own answers: right " in r.output
    data = json.loads((report / "timeline.json").read_text())
    score = data["score"]
    assert score["smoothed_accuracy"] >= 0.85  # one fold, 17 frames 11 degrees apart
    assert score["recall"] == 1.0 and score["precision"] == 1.0
    assert [c["to"]["class"] for c in data["changes"]] == ["11"]
    for name in ("timeline.csv", "timeline.png", "distances.png", "report.md"):
        assert (report / name).stat().st_size > 0
    # the three outcomes of the frames' own answers, in the JSON and the pages
    counts = data["outcomes"]
    assert sum(counts.values()) == 17 and counts["unreadable"] == 0
    assert data["coverage"] == round((counts["right"] + counts["wrong"]) / 17, 4)
    images, text = check_page(report / "report.html")
    assert {"timeline.svg", "distances.svg"} <= set(images)
    told = [f for f in data["frames"] if f["raw_class"] is None]
    assert len([i for i in images if i.startswith("overlays/")]) == len(told) + counts["wrong"]
    assert f"Cannot tell ({len(told)})" in text and "11 half-fold" in text
    assert f"cannot tell {counts['cannot_tell']}" in (report / "report.md").read_text()


def test_a_frame_that_cannot_be_read_is_a_gap_and_the_run_goes_on(half_fold, tmp_path):
    folder = tmp_path / "broken"
    folder.mkdir()
    rows = []
    for k in range(0, 17, 2):
        for kind in ("color", "depth"):
            name = f"III_{k:03d}_{kind}.png"
            (folder / name).write_bytes((half_fold / name).read_bytes())
        rows.append(f"III_{k:03d}_color.png,III_{k:03d}_depth.png,{k}")
    rows.insert(3, "missing_color.png,missing_depth.png,5")
    (folder / "frames.csv").write_text("color,depth,time\n" + "\n".join(rows) + "\n")
    r = CliRunner().invoke(main, ["track", str(folder), "-j", "1", "--json"])
    assert r.exit_code == 0, r.output
    data = json.loads(r.output)
    assert data["n_frames"] == 10
    assert [g["frame"] for g in data["gaps"]] == [3]
    assert "missing_color.png" in data["gaps"][0]["why"]
    assert data["frames"][-1]["smoothed_class"] == "11"
