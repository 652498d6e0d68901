"""One evidence record for the single-frame classifier and the batch labeller (issue 42):
each distance term has one implementation, vectorised over frames, so a block of frames
gets exactly the distances each frame gets alone, every term included."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dgli_vision.classifier.classify import (
    Evidence,
    batch_distances,
    reference_distances,
)
from dgli_vision.classifier.pipeline import ClothObservation, FrameResult
from dgli_vision.classifier.references import load_references
from dgli_vision.core.layout import default_layout

REFS = load_references()
LAYOUT = default_layout()


def _block(n: int, seed: int) -> tuple[np.ndarray, Evidence]:
    """n frames of varied evidence, every term told somewhere and missing somewhere."""
    rng = np.random.default_rng(seed)
    flat = np.asarray(LAYOUT.flat_coordinates())
    coords = flat[None] + rng.normal(0, 0.05, (n, len(flat)))
    visible = rng.random((n, 16)) > 0.2
    visible[:, :8] = True  # four segments seen: six coordinates at least
    unknown = ~visible & (rng.random((n, 16)) > 0.5)

    def some(shape, lo, hi, told=0.7):
        x = rng.uniform(lo, hi, shape)
        return np.where(rng.random(shape) < told, x, np.nan)

    return coords, Evidence(
        visible=visible,
        unknown=unknown,
        lifted=np.round(some((n, 16), 0, 1)),
        heights_mm=some((n, 16), 0, 150),
        past=some((n, 16), 0, 1, told=0.3),
        back=np.round(some((n, 4), 0, 1)),
        spread_mm=some((n, 120), 20, 420),
        tips=some((n, 4), 0, 1, told=0.5),
    )


def test_a_block_of_frames_gets_the_distances_each_frame_gets_alone_tips_included():
    coords, ev = _block(6, 1)
    batch = batch_distances(coords, ev, REFS)
    assert np.isfinite(batch).all()
    for t in range(len(coords)):
        one = reference_distances(coords[t], REFS, ev.frame(t))
        np.testing.assert_allclose(batch[t], one, rtol=0, atol=1e-12)
    # the tip term counts in the batch as in the single frame
    without = batch_distances(coords, dataclasses.replace(ev, tips=None), REFS)
    assert (np.abs(batch - without) > 1e-9).any()


def test_a_frame_with_too_few_coordinates_is_a_row_of_nan_in_a_block():
    coords, ev = _block(3, 2)
    coords[1, 2:] = np.nan
    batch = batch_distances(coords, ev, REFS)
    assert np.isnan(batch[1]).all() and np.isfinite(batch[[0, 2]]).all()


def test_the_records_are_keyword_only_and_frozen():
    with pytest.raises(TypeError):
        Evidence(np.ones(16, bool))  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        Evidence().visible = np.ones(16, bool)  # type: ignore[misc]
    segments, visible, up = np.zeros((8, 2, 3)), np.ones(16, bool), np.array([0, 0, -1.0])
    with pytest.raises(TypeError):
        ClothObservation(segments, visible, up)  # type: ignore[misc]
    obs = ClothObservation(segments=segments, visible=visible, up=up)
    assert obs.classifier_evidence().visible is visible
    with pytest.raises(TypeError):
        FrameResult(None, None, obs, np.zeros(28), None)  # type: ignore[misc]
