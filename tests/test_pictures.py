"""The pictures a user looks at (issue 51, item 9): the classify overlay draws hidden
stickers on the cloth (sample 05's 6 and 7 under the flap, not above the napkin's edge),
a legend, fold lines seen on the white napkin; a track report's gallery shows thumbnails
of the napkin large enough to read, each linking to its whole overlay."""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np
from click.testing import CliRunner

from dgli_vision.cli import main

SAMPLES = Path(__file__).resolve().parents[1] / "sample_images"


@lru_cache(maxsize=2)
def _classified(name: str):
    from dgli_vision.classifier.api import frame_from, reference_set_of
    from dgli_vision.classifier.pipeline import classify_frame
    from dgli_vision.sources.frames import read_frame

    frame = read_frame(SAMPLES / f"{name}_color.png", SAMPLES / f"{name}_depth.png")
    return frame, classify_frame(frame_from(frame.color, frame.depth_mm), reference_set_of(None))


def _drawn_missing(name: str) -> tuple[np.ndarray, np.ndarray, list]:
    """Where sample ``name``'s overlay draws each missing sticker, which are hidden, and
    the fold lines in pixels."""
    from dgli_vision.analysis.overlay import _fold_lines_px, folded_over, overlay_evidence

    frame, result = _classified(name)
    ev = overlay_evidence(result)
    lines = _fold_lines_px(result.affordances, frame.intrinsics)
    drawn = folded_over(ev.predicted_px, ev.hidden, result.detections.centroids, lines)
    return drawn, np.asarray(ev.hidden), lines


def test_sample_05s_hidden_stickers_are_drawn_on_the_cloth_not_above_its_edge():
    frame, result = _classified("05_000")
    drawn, hidden, lines = _drawn_missing("05_000")
    assert set(np.flatnonzero(hidden)) == {6, 7} and lines
    found = result.detections.centroids[result.detections.found]
    grey = cv2.cvtColor(frame.color, cv2.COLOR_RGB2GRAY)
    table = float(np.median(grey[:60]))  # the image's top rows: the table
    for k in (6, 7):
        u, v = np.round(drawn[k]).astype(int)
        assert grey[v, u] > table + 60  # on the white napkin, not on the table
        for a, b in lines:  # on the cloth's side of every fold line
            n = np.array([-(b - a)[1], (b - a)[0]])
            assert np.sign((drawn[k] - a) @ n) == np.sign(np.median((found - a) @ n))


def test_a_sticker_folded_under_is_mirrored_across_its_fold_line():
    from dgli_vision.analysis.overlay import folded_over

    found = np.full((16, 2), np.nan)
    found[:8] = np.column_stack([np.linspace(100, 300, 8), np.full(8, 300.0)])
    predicted = np.full((16, 2), np.nan)
    predicted[8] = (200.0, 80.0)  # beyond the fold line y = 100
    predicted[9] = (200.0, 250.0)  # under another flap, on the cloth: stays
    hidden = np.zeros(16, bool)
    hidden[[8, 9]] = True
    line = np.array([[0.0, 100.0], [400.0, 100.0]])
    out = folded_over(predicted, hidden, found, [line])
    assert np.allclose(out[8], (200.0, 120.0)) and np.allclose(out[9], (200.0, 250.0))
    assert np.allclose(folded_over(predicted, hidden, found, []), predicted, equal_nan=True)


def test_the_overlay_has_a_legend_and_dark_rimmed_fold_lines(tmp_path):
    from dgli_vision.analysis.overlay import frame_overlay

    frame, result = _classified("05_000")
    image = frame_overlay(frame, result)
    bgr = cv2.cvtColor(frame.color, cv2.COLOR_RGB2BGR)
    h = image.shape[0]
    panel = (slice(h - 60, h - 15), slice(15, 200))  # the legend's panel, bottom left
    assert np.median(image[panel]) < 0.5 * np.median(bgr[panel])  # darkened, text on it
    # every fold line is drawn as white dashes on a black rim (seen on the white napkin):
    # black pixels all along it, where the napkin and the table have none
    _, _, lines = _drawn_missing("05_000")
    assert lines
    for a, b in lines:
        near = []
        for t in np.linspace(0.15, 0.85, 30):
            u, v = np.round(a + (b - a) * t).astype(int)
            near.append((image[v - 4 : v + 5, u - 4 : u + 5].max(axis=2) < 40).any())
        assert sum(near) >= 20, sum(near)


def test_the_track_gallery_shows_readable_thumbnails_linking_to_the_overlays(tmp_path):
    rec = tmp_path / "grip"
    r = CliRunner().invoke(main, ["render", str(rec), "--sequence", "I", "--frames", "6",
                                  "--gripper", "--seed", "5"])
    assert r.exit_code == 0, r.output
    report = tmp_path / "report"
    r = CliRunner().invoke(main, ["track", str(rec), "-j", "1", "--report", str(report)])
    assert r.exit_code == 0, r.output
    page = (report / "report.html").read_text()
    links = re.findall(r'<a href="(overlays/[^"]+)"><img src="(overlays/thumbs/[^"]+)"', page)
    assert links, page[-2000:]
    for full, thumb in links:
        assert (report / full).is_file() and thumb == full.replace("overlays/", "overlays/thumbs/")
        small = cv2.imread(str(report / thumb))
        whole = cv2.imread(str(report / full))
        assert small.shape[1] == 480 and whole.shape[1] == 1280
        # the napkin as the page shows it: the thumbnail at 480 px wide, against the
        # whole overlay at a gallery figure's 340 px: three times as many of its pixels
        cloth = lambda img: (cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) > 200).sum()  # noqa: E731
        assert cloth(small) > 3 * cloth(whole) * (340 / 1280) ** 2


def test_the_distance_heatmap_names_its_axes_and_says_what_grey_is():
    from dgli_vision.analysis.charts import heatmap_figure

    m = np.array([[0.0, np.nan, 1.0], [np.nan, 0.0, 0.5], [1.0, 0.5, 0.0]])
    fig = heatmap_figure(m, title="t", groups=["01", "01", "02"], group_label="true class",
                         missing="no distance: too few coordinates in both")
    ax = fig.axes[0]
    assert ax.get_ylabel().startswith("true class") and ax.get_xlabel().startswith("true class")
    assert "group (in order)" not in ax.get_ylabel()
    notes = [t.get_text() for t in ax.texts]
    assert "grey (2 of 9 cells): no distance: too few coordinates in both" in notes
    full = heatmap_figure(np.zeros((2, 2)), title="t", groups=["01", "02"])
    assert not full.axes[0].texts  # nothing grey, nothing said


def test_the_risk_coverage_curve_has_a_point_per_answer_when_confidences_tie():
    from dgli_vision.analysis.charts import risk_coverage_figure

    # 24 pairs read, 20 answered at two confidences only: 1.0 (16, one wrong), 0.45 (4)
    ranked = [(1.0, 0.5 - k / 100, k != 3) for k in range(16)] + [(0.45, 0.2, True)] * 4
    points = [(1.0, 16 / 24, 15 / 16), (0.45, 20 / 24, 19 / 20)]
    fig = risk_coverage_figure(points, ranked, 24)
    lines = fig.axes[0].get_lines()
    per_answer = max(lines, key=lambda ln: len(ln.get_xdata()))
    assert len(per_answer.get_xdata()) == 20
    assert np.allclose(per_answer.get_xdata()[[0, -1]], [1 / 24, 20 / 24])
    acc = per_answer.get_ydata()
    assert acc[2] == 1.0 and acc[3] == 0.75  # the wrong one comes fourth (its margin)


def test_overlay_leaves_nothing_hidden_beside_the_users_file(tmp_path):
    """``--overlay`` signs its picture instead of recording it in a hidden
    ``.dgli-outputs.json``: run again it replaces its own picture, but not one the user
    edited or wrote, and the folder holds only the picture."""
    from dgli_vision.core.io import signed_ours

    color, depth = str(SAMPLES / "05_000_color.png"), str(SAMPLES / "05_000_depth.png")
    for name in ("seen.png", "seen.jpg"):
        out = tmp_path / name
        args = ["classify", color, depth, "--overlay", str(out)]
        assert CliRunner().invoke(main, args).exit_code == 0
        assert signed_ours(out) and cv2.imread(str(out)).shape == (720, 1280, 3)
        assert CliRunner().invoke(main, args).exit_code == 0  # its own: replaced
        data = bytearray(out.read_bytes())
        data[-100] ^= 0xFF  # the user's edit
        out.write_bytes(bytes(data))
        assert not signed_ours(out)
        r = CliRunner().invoke(main, args)
        assert r.exit_code == 2 and "refusing to replace" in r.output
        assert out.read_bytes() == bytes(data)
    mine = tmp_path / "mine.png"
    cv2.imwrite(str(mine), np.zeros((4, 4, 3), np.uint8))
    assert not signed_ours(mine)
    r = CliRunner().invoke(main, ["plan", color, depth, "--goal", "08", "--overlay", str(mine)])
    assert r.exit_code == 2 and "refusing to replace" in r.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.png", "seen.jpg", "seen.png"]
