"""Confidence is continuous in the input (issue 38): a tiny change of the images (depth
rounded at another phase, as a 0.1 mm sensor's would be, or one grey level of noise)
never moves it from 1 to 0. Each check that can rule a verdict out lowers the confidence
along a ramp that reaches the "cannot tell" threshold where the check starts to rule it
out, instead of setting it to 0 there."""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache

import numpy as np
import pytest

from dgli_vision.classifier.classify import MIN_CONFIDENCE, reference_terms
from dgli_vision.classifier.consistency import (
    CLEAR_MARGIN,
    MIRROR_MARGIN,
    doubt_factor,
    mirror_problem,
)
from dgli_vision.classifier.pipeline import classify_frame, observe
from dgli_vision.classifier.references import load_references
from dgli_vision.core.camera import Intrinsics
from dgli_vision.core.dgli import cloth_coordinates
from dgli_vision.core.layout import default_layout
from dgli_vision.sim.dataset import render_sample
from dgli_vision.sim.jitter import tiny_changes
from dgli_vision.sources.frames import RGBDFrame

REFS = load_references()
LAYOUT = default_layout()
SMALL = Intrinsics(640, 360, 302.5, 302.5, 319.5, 179.5)
AREA = LAYOUT.width_mm * LAYOUT.height_mm


@lru_cache(maxsize=8)
def _frame(class_id: str, conditions: tuple[str, ...] = ()) -> RGBDFrame:
    r = render_sample(class_id, 0, 11, conditions=conditions, intrinsics=SMALL).result
    return RGBDFrame(r.color, r.depth_mm, r.intrinsics, class_id, class_id, "render")


def test_a_doubt_falls_continuously_to_the_threshold_and_on_to_zero():
    xs = np.linspace(-0.2, 0.3, 5001)
    f = np.array([doubt_factor(x, MIRROR_MARGIN, CLEAR_MARGIN, -MIRROR_MARGIN) for x in xs])
    assert np.abs(np.diff(f)).max() < 0.01
    assert doubt_factor(CLEAR_MARGIN, MIRROR_MARGIN, CLEAR_MARGIN, -MIRROR_MARGIN) == 1.0
    assert doubt_factor(MIRROR_MARGIN, MIRROR_MARGIN, CLEAR_MARGIN, -MIRROR_MARGIN) == (
        pytest.approx(MIN_CONFIDENCE)
    )
    assert doubt_factor(-MIRROR_MARGIN, MIRROR_MARGIN, CLEAR_MARGIN, -MIRROR_MARGIN) == 0.0


def test_the_mirror_check_lowers_the_confidence_along_a_ramp():
    # a real observation whose front-up reading is moved, step by tiny step, from far
    # better than its mirror image to far worse: the factor never jumps, and the check
    # says "cannot tell" exactly where the factor falls below the threshold
    _, _, obs = observe(_frame("02"), LAYOUT)
    coords = cloth_coordinates(obs.segments, obs.up)
    evidence = obs.classifier_evidence()
    terms = reference_terms(coords, REFS, evidence)
    factors, told = [], []
    for t in np.linspace(-0.4, 0.6, 1001):
        moved = replace(terms, dgli=np.clip(terms.dgli + t, 0.0, 2.0))
        doubt = mirror_problem(coords, REFS, evidence, None, AREA, terms=moved)
        factors.append(doubt.factor)
        told.append(doubt.reason is not None)
    factors, told = np.array(factors), np.array(told)
    assert factors.max() == 1.0 and factors.min() == 0.0
    assert np.abs(np.diff(factors)).max() < 0.02
    assert (factors[told] < MIN_CONFIDENCE).all()
    assert (factors[~told] >= MIN_CONFIDENCE).all()


def _perturbed(frame: RGBDFrame, seed: int) -> list[RGBDFrame]:
    """The frame under the three tiny changes of :func:`tiny_changes`."""
    return tiny_changes(frame, np.random.default_rng(seed))


@pytest.mark.parametrize(
    ("class_id", "conditions"), [("02", ("mirror",)), ("09", ("backface", "mirror"))]
)
def test_a_tiny_change_of_the_images_moves_the_confidence_a_little(class_id, conditions):
    frame = _frame(class_id, conditions)
    base = classify_frame(frame, REFS).best_guess
    for other in _perturbed(frame, 3):
        got = classify_frame(other, REFS).best_guess
        assert (base is None) == (got is None)
        if base is not None:
            assert abs(got.confidence - base.confidence) <= 0.1
