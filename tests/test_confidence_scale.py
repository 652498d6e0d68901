"""The confidence users see, pinned in numbers: ``"confidence"`` in JSON, the 0.25
threshold of "cannot tell" and the reliability table all rest on one scale. Every
expected value here is a literal, not derived from the library's constants, so a change
of the scale fails these tests: it is then a decision (update the numbers, the docs and
the threshold together), not an accident."""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest

from dgli_vision.classifier.classify import Evidence, classify_coordinates, confidence_of
from dgli_vision.classifier.references import load_references
from dgli_vision.core.camera import Intrinsics

REFS = load_references()
#: Half SPEC's camera in each direction: a quarter of the pixels, to keep the test fast.
SMALL = Intrinsics(640, 360, 302.5, 302.5, 319.5, 179.5)


@pytest.mark.parametrize(
    ("margin", "unknown", "coordinates", "confidence"),
    [
        # the margin to the runner-up: full confidence at 0.2, in proportion below
        (0.2, 0, None, 1.0),
        (0.35, 0, None, 1.0),
        (0.1, 0, None, 0.5),
        (0.07, 0, None, 0.35),  # the closest right answers (two flaps crossing or not)
        (0.05, 0, None, 0.25),  # the "cannot tell" threshold, every sticker known
        (0.01, 0, None, 0.05),
        (0.0, 0, None, 0.0),
        (-0.02, 0, None, 0.0),
        (float("inf"), 0, None, 1.0),  # no runner-up
        # times the cube of the share of stickers whose state is known
        (0.2, 4, None, 0.4219),
        (0.12, 4, None, 0.2531),  # four unknown: a margin of 0.12 reaches the threshold
        (0.15, 2, None, 0.5024),
        (0.2, 16, None, 0.0),
        # times the share of the six coordinates that earn full confidence
        (0.2, 0, 3, 0.5),
        (0.1, 0, 3, 0.25),
        (0.2, 0, 28, 1.0),
        (0.16, 2, 4, 0.3573),
    ],
)
def test_known_margins_give_known_confidences(margin, unknown, coordinates, confidence):
    assert confidence_of(margin, unknown, 16, coordinates) == confidence


def fixed_distances(best: float, same_class: float, runner_up: float) -> np.ndarray:
    """Distances to every shipped reference: the first 02/A at ``best``, the first 02/B
    (the same class) at ``same_class``, the first 04/AB (another class) at
    ``runner_up``, every other reference at 2."""
    dist = np.full(len(REFS.references), 2.0)
    keys = [(r.class_id, r.variant) for r in REFS.references]
    dist[keys.index(("02", "A"))] = best
    dist[keys.index(("02", "B"))] = same_class
    dist[keys.index(("04", "AB"))] = runner_up
    return dist


@pytest.mark.parametrize(
    ("distances", "unknown", "known_coordinates", "margin", "confidence"),
    [
        ((0.30, 0.31, 0.33), 0, 28, 0.03, 0.15),  # the runner-up is of another class
        ((0.10, 0.12, 0.18), 0, 28, 0.08, 0.4),
        ((0.10, 0.12, 0.45), 0, 28, 0.35, 1.0),
        ((0.10, 0.12, 0.25), 4, 28, 0.15, 0.3164),  # four stickers' state unknown
        ((0.10, 0.12, 0.30), 0, 4, 0.2, 0.6667),  # four coordinates known of 28
    ],
)
def test_a_fixed_observation_gets_its_pinned_margin_and_confidence(
    distances, unknown, known_coordinates, margin, confidence
):
    coords = np.full(28, 0.1)
    coords[known_coordinates:] = np.nan
    unknown_mask = np.arange(16) < unknown
    p = classify_coordinates(
        coords, REFS, Evidence(unknown=unknown_mask), distances=fixed_distances(*distances)
    )
    assert (p.class_id, p.variant) == ("02", "A")
    assert (p.runner_up.class_id, p.runner_up.variant) == ("04", "AB")
    assert p.margin == pytest.approx(margin, abs=1e-12)
    assert p.confidence == confidence


def test_the_reliability_table_of_a_fixed_render_set(monkeypatch):
    """Five renders of a gripper over the napkin or a corner held, classified as `dgli
    robustness` does: their best guesses' confidences and the reliability table. Three
    of them are set by the margin (0.018, 0.127, 0.167), two by the stickers the gripper
    leaves unknown. Within 0.03: changes to the detector move a margin a little (the
    held 04 read 0.0377, then 0.0226 after a detector change); a change of the scale
    moves them by 0.04-0.27."""
    from dgli_vision.analysis import robustness
    from dgli_vision.sim import dataset

    monkeypatch.setattr(dataset, "render_sample", partial(dataset.render_sample, intrinsics=SMALL))
    held = robustness.score_condition("grasp", REFS, per_class=1, seed=1, classes=("04", "05"))
    gripper = ("02", "05", "08")
    scores = held + robustness.score_condition(
        "gripper", REFS, per_class=1, seed=1, classes=gripper
    )
    guesses = [g for s in scores for g in s.guesses]
    # the held 05 (0.2679 by its margin) has its flap held up with 04 next: "cannot tell"
    # which of the two it lands as, its confidence lowered along the landing check's ramp
    # (classifier/pipeline.py); the 02, a state with a mirror twin, is no longer capped at
    # 0.45 under a camera that does not mirror (issue 51: the cap is for unknown handedness)
    expected = [0.0237, 0.0203, 0.824, 0.542, 0.4219]  # 04, 05 held; 02, 05, 08 gripper
    np.testing.assert_allclose([c for c, _ in guesses], expected, atol=0.03)
    assert all(right for _, right in guesses)
    rows = robustness.reliability_rows(scores)
    assert [r["answers"] for r in rows] == [2, 0, 1, 1, 1]
    assert [r["right"] for r in rows] == [2, 0, 1, 1, 1]
    _, table = robustness.reliability_table(scores)
    assert table[2] == ["[0.25, 0.5)", "1", "1", "100%"]


def test_the_nearest_and_the_runner_up_are_those_a_stable_sort_puts_first():
    # ties go to the first reference, finite or not (the verdict must not depend on how
    # the nearest is found)
    rng = np.random.default_rng(3)
    codes = REFS.class_codes()
    coords = rng.normal(size=28)
    for trial in range(200):
        d = rng.choice([0.1, 0.2, 0.3], len(REFS.references))
        if trial % 3 == 0:
            d[rng.integers(len(d), size=4)] = np.inf
        if trial % 4 == 0:
            d[rng.integers(len(d), size=2)] = np.nan
        order = np.argsort(d, kind="stable")
        best = REFS.references[order[0]]
        runner = REFS.references[order[int(np.argmax(codes[order] != codes[order[0]]))]]
        got = classify_coordinates(coords, REFS, distances=d)
        assert (got.class_id, got.variant) == (best.class_id, best.variant)
        assert (got.runner_up.class_id, got.runner_up.variant) == (runner.class_id, runner.variant)
