"""Which face each corner shows: from the stickers' turn in the image or from above."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from dgli_vision.classifier.pipeline import observe
from dgli_vision.classifier.references import (
    default_references_path,
    load_references,
    references_from_dict,
)
from dgli_vision.core.layout import default_layout
from dgli_vision.perception.handedness import back_face_up, corner_turns, image_turns
from dgli_vision.sim.cloth.states import sample_state
from dgli_vision.sources.frames import read_frame

SAMPLES = Path(__file__).resolve().parents[1] / "sample_images"
LAYOUT = default_layout()

#: Corners on a flap folded over (back face up), by class and variant, as SPEC defines
#: the states (A-D = 0-3).
OVER = {("01", None): [], ("02", "B"): [1], ("06", "AC"): [0, 2], ("08", None): [0, 1, 2, 3]}


def _rotate(xy: np.ndarray, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return xy @ np.array([[c, -s], [s, c]]).T


def test_the_flat_napkin_shows_its_front_at_every_corner_in_any_pose() -> None:
    for angle in (0.0, 1.0, 2.5, -2.0):
        xy = _rotate(LAYOUT.sticker_uv, angle) + np.array([300.0, -120.0])
        assert corner_turns(xy, LAYOUT).tolist() == [1, 1, 1, 1]
        # a mirror (x -> -x) turns every corner round
        assert corner_turns(xy * [-1.0, 1.0], LAYOUT).tolist() == [-1, -1, -1, -1]


def test_a_corner_needs_three_stickers_and_says_nothing_edge_on() -> None:
    xy = LAYOUT.sticker_uv.astype(float).copy()
    xy[[0, 1]] = np.nan  # corner A keeps 14 and 15 only
    assert corner_turns(xy, LAYOUT).tolist() == [0, 1, 1, 1]
    edge_on = LAYOUT.sticker_uv * [1.0, 1e-3]  # the napkin seen from its side
    assert corner_turns(edge_on, LAYOUT).tolist() == [0, 0, 0, 0]
    assert np.isnan(back_face_up(np.array([0.0, 1.0, -1.0, 0.0]))[[0, 3]]).all()
    assert back_face_up(np.array([0.0, 1.0, -1.0, 0.0]))[1:3].tolist() == [0.0, 1.0]


@pytest.mark.parametrize(("class_id", "variant"), sorted(OVER, key=str))
def test_simulated_states_show_the_back_face_exactly_at_the_corners_folded_over(
    class_id: str, variant: str | None
) -> None:
    state = sample_state(class_id, variant, rng=5)
    turns = corner_turns(state.sticker_points[:, :2] * 1e3, LAYOUT)
    expected = [-1 if k in OVER[class_id, variant] else 1 for k in range(4)]
    assert turns.tolist() == expected


def test_the_shipped_references_know_which_corners_lie_folded_over() -> None:
    refs = load_references(None)
    for r in refs.references:
        if r.stage or r.class_id not in {"01", "02", "08"}:
            continue
        over = {"01": "", "02": r.variant or "", "08": "ABCD"}[r.class_id]
        expected = [1.0 if name in over else 0.0 for name in "ABCD"]
        assert r.back_rate.tolist() == expected, (r.class_id, r.variant)


def test_a_reference_set_without_back_face_rates_still_loads_and_ranks() -> None:
    data = json.loads(default_references_path().read_text())
    for item in data["references"]:
        item.pop("back_rate", None)
    old = references_from_dict(data, source="old.json")
    assert np.isnan(old.back_rates()).all()


def test_every_shipped_sample_shows_the_faces_of_its_state() -> None:
    """On the rendered samples, a corner whose stickers tell shows its back face exactly
    when the sample's class folds it over (a mirror of a folded state would not)."""
    told = 0
    with open(SAMPLES / "labels.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    refs = load_references(None)
    for row in rows:
        frame = read_frame(
            SAMPLES / row["color"], SAMPLES / row["depth"], SAMPLES / "intrinsics.json"
        )
        detections, markers, _ = observe(frame, LAYOUT)
        located = np.where(markers.found[:, None], detections.centroids, np.nan)
        back = back_face_up(image_turns(located, LAYOUT))
        rates = np.array(
            [
                r.back_rate
                for r in refs.references
                if r.class_id == row["label"] and r.variant == (row["variant"] or None)
                and not r.stage
            ]
        )
        ok = np.isfinite(back)
        told += int(ok.sum())
        assert np.allclose(back[ok], np.round(rates[0][ok])), row["color"]
    assert told >= 30  # most corners of the twelve samples tell
