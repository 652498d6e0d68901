"""The pipeline's answers on a varied set of rendered frames are the ones recorded before
it was made faster (issue 40): class, variant, kind of "cannot tell", best guess, its
confidence and distance to 1e-6, stickers found. The record is
tests/data/verdicts_locked.json, written by scripts/record_verdicts.py (see there)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest
from render_cache import rendered

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location(
    "record_verdicts", ROOT / "scripts/record_verdicts.py"
)
record = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(record)

RECORDED = json.loads((ROOT / "tests/data/verdicts_locked.json").read_text())


@pytest.fixture(scope="module")
def results(request):
    from dgli_vision.classifier.pipeline import classify_frame
    from dgli_vision.classifier.references import load_references

    refs = load_references(None)
    out = {}
    for class_id, k, conditions in record.FRAMES:
        frame = rendered(request.config, class_id, k, record.SEED, conditions)
        label = f"{class_id}_{k} {'+'.join(conditions) or 'clean'}"
        out[label] = record.verdict(classify_frame(frame, refs))
    return out


def test_the_record_covers_the_frames():
    assert RECORDED["seed"] == record.SEED
    assert len(RECORDED["verdicts"]) == len(record.FRAMES)
    kinds = {v["class"] for v in RECORDED["verdicts"].values()}
    assert len(kinds) >= 7 and None in kinds  # several classes and a "cannot tell"


@pytest.mark.parametrize("label", list(RECORDED["verdicts"]))
def test_verdict_unchanged(results, label):
    got, want = results[label], RECORDED["verdicts"][label]
    for key in ("class", "variant", "why", "guess_class", "guess_variant", "found"):
        assert got[key] == want[key], (label, key)
    for key in ("confidence", "distance"):
        if want[key] is None:
            assert got[key] is None, (label, key)
        else:
            assert got[key] == pytest.approx(want[key], abs=1e-6), (label, key)
