"""References and classification of coordinates: accuracy on a fresh simulated database."""

from __future__ import annotations

import json

import numpy as np
import pytest

from dgli_vision.classifier.classify import Evidence, classify_coordinates
from dgli_vision.classifier.references import (
    build_references,
    load_references,
    read_references,
    write_references,
)
from dgli_vision.core.errors import (
    DetectionError,
    InvalidInputError,
    ReferenceSetError,
    UnreadableInputError,
)
from dgli_vision.sim.database import records_from_states, simulate_states


@pytest.fixture(scope="module")
def fresh():
    """A database drawn with another seed than the shipped references (seed 0)."""
    return records_from_states(simulate_states(20, 1))


@pytest.fixture(scope="module")
def shipped():
    return load_references()


def accuracy(records, refs, coords, with_visibility=True):
    hits = []
    for k in range(len(records)):
        vis = records.visible[k] if with_visibility else None
        p = classify_coordinates(coords[k], refs, Evidence(visible=vis))
        hits.append((p.class_id == records.classes[k], p.variant == records.variants[k]))
    return np.mean(hits, axis=0)


def test_shipped_references_cover_every_class_and_variant(shipped):
    from dgli_vision.sim.cloth import VARIANTS

    keys = {(r.class_id, r.variant) for r in shipped.references}
    assert keys == {(c, v) for c, vs in VARIANTS.items() for v in vs}
    assert shipped.provenance["database"]["seed"] == 0
    assert shipped.provenance["database"]["per_class"] >= 20


def test_accuracy_on_a_fresh_database_all_stickers_known(fresh, shipped):
    class_acc, variant_acc = accuracy(fresh, shipped, fresh.coordinates)
    assert class_acc >= 0.99
    assert variant_acc >= 0.95


def test_accuracy_on_a_fresh_database_hidden_stickers_removed(fresh, shipped):
    class_acc, _ = accuracy(fresh, shipped, fresh.hidden_coordinates())
    assert class_acc >= 0.97


def test_leave_one_out_accuracy_on_the_fresh_database(fresh):
    coords = fresh.hidden_coordinates()
    hits = 0
    everyone = np.arange(len(fresh))
    for k in range(0, len(fresh), 3):  # every third sample keeps the test fast
        refs = build_references(fresh.subset(everyone != k))
        hits += (
            classify_coordinates(coords[k], refs, Evidence(visible=fresh.visible[k])).class_id
            == fresh.classes[k]
        )
    assert hits / len(range(0, len(fresh), 3)) >= 0.97


def test_visibility_is_evidence_over_or_under(fresh, shipped):
    # Corner over and corner under have the same shape seen from above; the hidden
    # corner stickers decide.
    k = fresh.classes.index("03")
    assert (
        classify_coordinates(
            fresh.hidden_coordinates()[k], shipped, Evidence(visible=fresh.visible[k])
        ).class_id
        == "03"
    )


def test_prediction_fields(fresh, shipped):
    p = classify_coordinates(fresh.coordinates[0], shipped, Evidence(visible=fresh.visible[0]))
    assert p.class_id == "01" and p.name == "flat" and p.variant is None
    assert p.runner_up is not None and p.runner_up.class_id != p.class_id
    assert p.margin == pytest.approx(p.runner_up.distance - p.distance)
    assert p.margin >= 0


def test_too_few_coordinates_cannot_be_classified(shipped):
    coords = np.full(28, np.nan)
    coords[:2] = [1, 2]
    with pytest.raises(DetectionError, match="only 2 of 28"):
        classify_coordinates(coords, shipped)


def test_three_coordinates_are_ranked_with_confidence_scaled_down(shipped):
    full = shipped.references[0].coordinates
    coords = np.full(28, np.nan)
    coords[[0, 1, 7]] = full[[0, 1, 7]]  # segments 0, 1 and 2: pairs 0-1, 0-2, 1-2
    p = classify_coordinates(coords, shipped)
    assert p.confidence <= 0.5


def test_references_round_trip(tmp_path, shipped):
    path = tmp_path / "refs.json"
    write_references(path, shipped)
    again = read_references(path)
    assert len(again) == len(shipped)
    np.testing.assert_allclose(again.matrix(), shipped.matrix(), atol=1e-9)
    np.testing.assert_allclose(again.height_ranges(), shipped.height_ranges(), atol=0.05)
    np.testing.assert_allclose(again.past_rates(), shipped.past_rates(), atol=1e-4)


def test_a_set_written_before_heights_were_kept_still_classifies(tmp_path, fresh, shipped):
    """Sets without height ranges or past-vertical rates load; those terms then say
    nothing, and finished states are classified as before."""
    data = shipped.to_json()
    for item in data["references"]:
        item.pop("height_range_mm", None)
        item.pop("past_rate", None)
    path = tmp_path / "old.json"
    path.write_text(json.dumps(data))
    old = read_references(path)
    assert np.isnan(old.height_ranges()).all() and not old.past_rates().any()
    heights = fresh.sticker_points[:, :, 2] * 1e3
    for k in range(0, len(fresh), 7):
        p = classify_coordinates(
            fresh.coordinates[k], old,
            Evidence(visible=fresh.visible[k], heights_mm=heights[k], past=np.zeros(16)),
        )
        assert p.class_id == fresh.classes[k]


def test_height_tells_a_half_fold_from_a_strip_held_up_at_the_same_angle(shipped):
    """Mid-fold at 110 degrees, with only the flat stickers' coordinates known: the
    flap's edge stands about 180 mm high for a half fold and 110 mm for a strip."""
    from dgli_vision.sim.cloth.states import sample_state

    for class_id, stand in (("11", 180.0), ("09", 110.0)):
        fold = "AB half" if class_id == "11" else "AB strip over"
        state = sample_state(
            class_id, "AB", np.random.default_rng(3), last_fold=fold, last_fold_deg=110.0
        )
        rec = records_from_states([("x", state)])
        vis = ~rec.lifted[0]  # the flap's stickers edge-on: held up, not seen
        heights = np.where(rec.lifted[0], rec.sticker_points[0, :, 2] * 1e3, 0.0)
        assert abs(np.nanmax(heights) - stand) < 25
        coords = rec.hidden_coordinates()[0]
        p = classify_coordinates(coords, shipped, Evidence(
            visible=vis, unknown=rec.lifted[0], lifted=rec.lifted[0].astype(float),
            heights_mm=heights, past=np.where(rec.lifted[0], 1.0, np.nan),
        ))
        assert p.class_id == class_id


@pytest.mark.parametrize(
    ("content", "error", "message"),
    [
        # not JSON at all: the JSON reader's error, as for any JSON file dgli reads
        ("{", InvalidInputError, r"reference set '.*bad\.json' is not valid JSON \(line 1, "),
        (
            '{"format": "other"}',
            ReferenceSetError,
            r"'.*bad\.json' is not a dgli reference set \(no \"format\": \"dgli-references\"\)",
        ),
        (
            '{"format": "dgli-references", "version": 9}',
            ReferenceSetError,
            r"'.*bad\.json' has reference format version 9; expected 1$",
        ),
        (
            '{"format": "dgli-references", "version": 1, "references": [{"class": "02"}]}',
            ReferenceSetError,
            r"'.*bad\.json': reference 0 is malformed \('coordinates'\)$",
        ),
    ],
)
def test_bad_reference_files_name_the_file(tmp_path, content, error, message):
    path = tmp_path / "bad.json"
    path.write_text(content)
    with pytest.raises(error, match=message) as info:
        read_references(path)
    assert type(info.value) is error  # not a subclass standing in for it
    assert str(path) in str(info.value)
    assert info.value.exit_code == 2


def test_missing_reference_file(tmp_path):
    path = tmp_path / "nope.json"
    message = r"^reference set '.*nope\.json' does not exist$"
    with pytest.raises(UnreadableInputError, match=message) as info:
        load_references(path)
    assert type(info.value) is UnreadableInputError and info.value.exit_code == 2


def test_reference_json_records_provenance(shipped):

    data = json.loads(json.dumps(shipped.to_json()))
    assert data["provenance"]["command"].startswith("dgli references build")
    assert all(len(r["visible_rate"]) == 16 for r in data["references"])


def test_reference_ranks_are_kept_per_mask_and_give_the_same_distances(fresh, shipped):
    from dgli_vision.classifier.classify import TIE_SCALE, reference_distances
    from dgli_vision.core.distance import centred_unit_ranks, spearman_to_ranked

    known = np.isfinite(fresh.coordinates[3]) & (np.arange(28) % 3 != 0)
    ranked = shipped.ranked(known)
    assert shipped.ranked(known.copy()) is ranked  # ranked once per mask
    assert not ranked.flags.writeable
    coords = np.where(known, fresh.coordinates[3], np.nan)
    # the frame's near ties share their ranks (TIE_SCALE); the references' rank exactly
    fresh_ranks = centred_unit_ranks(shipped.matrix()[:, known])
    spearman = spearman_to_ranked(coords[known], fresh_ranks, tie_scale=TIE_SCALE)
    got = reference_distances(coords, shipped)
    np.testing.assert_allclose(got, spearman, rtol=0, atol=1e-12)  # no other term given


def test_loaded_references_come_with_the_tables_every_frame_reads(tmp_path, shipped):
    # the first frame of a process must not build them (milliseconds in a real-time loop)
    path = tmp_path / "refs.json"
    write_references(path, shipped)
    refs = load_references(path)
    for name in ("coordinates", "visible_rate", "lifted_rate", "class_codes", "spread_lo",
                 "height_lo", "back_rate", "past_rate", "footprint_range", "tip_clear",
                 "lifted_rate by row", "past_rate by row", "back_rate by row",
                 "tip_clear by row"):
        assert name in refs._stacks, name
    assert np.array_equal(refs.matrix(), shipped.matrix())
    assert np.array_equal(refs.tip_clear(), shipped.tip_clear())
