"""Corners and folds worked out when first read, not by every classified frame."""

from __future__ import annotations

import pickle
from pathlib import Path

import pytest

SAMPLES = Path(__file__).resolve().parents[1] / "sample_images"


@pytest.fixture(scope="module")
def refs():  # type: ignore[no-untyped-def]
    from dgli_vision.classifier.references import load_references

    return load_references(None)


@pytest.mark.parametrize("name", ["03_000", "05_000"])
def test_corners_and_folds_cost_nothing_until_read_and_then_are_the_same(
    name: str, refs: object, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``classify_frame`` does not work out the grasp geometry; reading the corners or
    the folds (as ``--json``, ``plan`` and ``verify`` do) works it out once, the same as
    :func:`affordances_of` itself, and a pickled result carries it."""
    from dgli_vision.classifier import affordances, pipeline
    from dgli_vision.sources.frames import read_frame

    calls: list[object] = []
    real = affordances.affordances_of

    def counted(*args: object, **kwargs: object) -> object:
        calls.append((args, kwargs))
        return real(*args, **kwargs)

    monkeypatch.setattr(pipeline, "affordances_of", counted)
    frame = read_frame(SAMPLES / f"{name}_color.png", SAMPLES / f"{name}_depth.png")
    result = pipeline.classify_frame(frame, refs)  # type: ignore[arg-type]
    assert calls == []
    p = result.prediction
    assert p is not None
    folds = list(p.folds)  # folds and corners of the prediction and of the result: one fit
    assert len(result.affordances.corners) == 4 and len(calls) == 1
    (args, kwargs), = calls  # (worked out again, eagerly, with the same arguments)
    assert args[0] is result.observation and args[1:3] == (p.class_id, p.variant)
    eager = real(*args, **kwargs)
    assert result.affordances.to_json() == eager.to_json()
    assert folds == list(eager.folds) and p.folds == eager.folds
    assert dict(p.corners) == dict(eager.corners)
    again = pickle.loads(pickle.dumps(pipeline.classify_frame(frame, refs)))  # type: ignore[arg-type]
    assert again.affordances.to_json() == eager.to_json()
