"""What a "cannot tell" names (issue 51 item 8): a flap raised is no object over the
napkin, and a state without a variant is named without ``None``."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from dgli_vision.classifier import pipeline
from dgli_vision.classifier.references import load_references
from dgli_vision.sources.frames import read_frame

SAMPLES = Path(__file__).resolve().parents[1] / "sample_images"


@pytest.fixture(scope="module")
def flat():
    frame = read_frame(SAMPLES / "01_000_color.png", SAMPLES / "01_000_depth.png")
    return pipeline.classify_frame(frame, load_references())


def _reason(result, *, occluded: bool, flap_deg: float | None) -> str:
    obs = result.observation
    lean = np.full(16, np.nan)
    if flap_deg is not None:
        lean[[0, 1]] = flap_deg
    obs = replace(obs, evidence=replace(obs.evidence, occluded=occluded), flap_deg=lean)
    return pipeline._low_confidence_reason(result.best_guess, obs, 0.25, 1.0)


def test_a_flap_raised_is_said_as_a_flap_not_as_an_object_over_the_napkin(flat):
    said = _reason(flat, occluded=True, flap_deg=62.0)
    assert "covered by an object" not in said
    assert "a flap is raised, at about 62 degrees" in said
    assert "an object holding it" in said  # something stands above: the flap, or a hand


def test_an_object_over_the_napkin_with_no_flap_raised_is_still_named(flat):
    said = _reason(flat, occluded=True, flap_deg=None)
    assert "the napkin is partly covered by an object above it" in said
    assert "flap" not in said
    assert "object" not in _reason(flat, occluded=False, flap_deg=None)


def test_a_state_without_a_variant_is_named_by_its_distance_alone():
    assert pipeline._named("08", None, 0.859) == "08 four-corners-centre (0.859)"
    assert pipeline._named("04", "AB", 0.016) == "04 two-adjacent-corners (AB, 0.016)"
