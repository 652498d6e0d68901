"""``dgli robustness --report``: the tables, the three outcomes and per-condition
galleries of the pairs answered wrong or "cannot tell", on one self-contained page."""

from __future__ import annotations

import json

import numpy as np
from click.testing import CliRunner
from html_pages import check_page

from dgli_vision.analysis import robustness
from dgli_vision.classifier.references import load_references
from dgli_vision.cli import main


def fake_outcome(args):
    """Class 01 and 02 right, 03 wrong, the rest "cannot tell"; an overlay for the pairs
    not right when the worker keeps them (as the real worker does)."""
    condition, _, k, class_id = args
    truth = f"{class_id}/x"
    given = {"01": "01", "02": "02", "03": "04"}.get(class_id)
    out = (f"{class_id}_{k:03d}", truth, given, "x", (condition,), (given or "01", 0.5))
    if not robustness._OVERLAYS:
        return out
    extra = None if given == class_id else {
        "reason": None if given else f"too few stickers in {class_id}",
        "overlay": np.full((8, 16, 3), int(class_id), np.uint8),
    }
    return (*out, extra)


def test_the_report_shows_each_conditions_wrong_and_cannot_tell_pairs(tmp_path, monkeypatch):
    monkeypatch.setattr(robustness, "_one", fake_outcome)
    report = tmp_path / "report"
    args = ["robustness", "--per-class", "1", "--conditions", "sheen,mirror", "-j", "1"]
    res = CliRunner().invoke(main, [*args, "--json", "--report", str(report)])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    # the three outcomes over all conditions and per row, as evaluate names them
    assert data["outcomes"] == {"right": 4, "cannot_tell": 18, "wrong": 2, "unreadable": 0}
    assert data["coverage"] == 0.25 and data["accuracy_answered"] == round(4 / 6, 4)
    row = data["rows"][0]
    assert row["outcomes"]["cannot_tell"] == 9 and row["coverage"] == 0.25
    assert json.loads((report / "robustness.json").read_text())["rows"] == data["rows"]
    images, text = check_page(report / "report.html")
    # per condition: 1 wrong and at most 12 "cannot tell" drawn (9 here), overlays written
    assert images[0] == "outcomes.svg"  # the chart of the answers by condition
    assert len(images) == 1 + 2 * (1 + 9)
    svg = (report / "outcomes.svg").read_text()
    assert "sheen" in svg and "mirror" in svg and 'id="legend_1"' in svg
    assert "overlays/sheen/03_000.png" in images and "overlays/mirror/12_000.png" in images
    assert "too few stickers in 07" in text and "Wrong (1)" in text
    assert "cannot tell: cannot tell" not in text
    md = (report / "report.md").read_text()
    assert "| sheen | 12 | 17% | 75% | 8% | 17% | 25% | 67% |" in md
    assert "## Reliability" in md


def test_a_worker_keeps_the_overlay_and_reason_of_a_pair_it_cannot_tell():
    robustness._init(load_references(), True)
    try:
        out = robustness._one(("gripper", 1000, 0, "03"))  # the corner under the gripper
    finally:
        robustness._init(None, False)
    assert out[2] is None  # cannot tell
    extra = out[6]
    assert "stickers" in extra["reason"]
    assert extra["overlay"].shape[1] == robustness.OVERLAY_WIDTH
    assert extra["overlay"].std() > 10  # a picture, not a blank


def test_pictures_show_class_names_whole():
    """The longest class name is drawn whole, inside the confusion and timeline charts."""
    from dgli_vision.analysis.charts import confusion_figure, figure_bgr, timeline_figure
    from dgli_vision.core.classes import CLASS_IDS, CLASS_NAMES

    name = "05 two-adjacent-corners-crossing"
    assert f"05 {CLASS_NAMES['05']}" == name
    for fig in (
        confusion_figure(np.eye(12, 13, dtype=int), list(CLASS_IDS), names=CLASS_NAMES),
        timeline_figure(CLASS_IDS, ["05"] * 3, ["05"] * 3, names=CLASS_NAMES),
    ):
        figure_bgr(fig)  # lays the figure out
        renderer = fig.canvas.get_renderer()
        width = fig.bbox.width
        labels = [t for ax in fig.axes for t in ax.get_yticklabels() if t.get_text() == name]
        assert labels
        for label in labels:
            box = label.get_window_extent(renderer)
            assert 0 <= box.x0 and box.x1 <= width  # not cut at the picture's edge
