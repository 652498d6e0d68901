"""The Python API's answer carries why it could not tell and which stickers it rests on
(found, hidden by cloth, unknown with why), as ``dgli-classify --json`` does."""

from __future__ import annotations

from pathlib import Path

import dgli_vision
from dgli_vision.classifier.classify import MIN_CONFIDENCE
from dgli_vision.sim.dataset import render_sample

SAMPLES = Path(__file__).resolve().parents[1] / "sample_images"


def test_a_clear_answer_has_no_reason_and_lists_its_stickers():
    p = dgli_vision.classify_pair(SAMPLES / "03_000_color.png", SAMPLES / "03_000_depth.png")
    assert p.class_id == "03" and p.confidence >= MIN_CONFIDENCE
    assert p.reason is None and p.why is None
    s = p.stickers
    assert len(s.found) == 12 and len(s.hidden) == 4  # a corner folded under: 4 hidden
    assert set(s.found).isdisjoint(s.hidden) and s.unknown == ()


def test_an_answer_that_cannot_be_told_says_why_and_which_stickers_are_unknown():
    sample = render_sample("02", 0, 1000, conditions=("gripper",))  # the corner held
    r = sample.result
    p = dgli_vision.classify_pair(r.color, r.depth_mm, r.intrinsics)
    assert p.confidence < MIN_CONFIDENCE
    assert p.reason and "nearly as close" in p.reason and p.why == "too close to call"
    s = p.stickers
    assert s.unknown and len(s.reasons) == len(s.unknown)
    assert all("object" in why for why in s.reasons)  # possibly under the gripper
    assert len(s.found) + len(s.unknown) + len(s.hidden) <= 16
