"""A user's first day: inputs users have, and one call from code."""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

import dgli_vision
from dgli_vision.cli import main
from dgli_vision.core.errors import DgliError

SAMPLES = Path(__file__).resolve().parent.parent / "sample_images"
COLOR, DEPTH = SAMPLES / "05_000_color.png", SAMPLES / "05_000_depth.png"


def test_a_16_bit_colour_png_is_read_as_its_8_bit_image(tmp_path):
    bgr = cv2.imread(str(COLOR))
    path = tmp_path / "c16_color.png"
    cv2.imwrite(str(path), bgr.astype(np.uint16) * 257)
    a = dgli_vision.classify_pair(path, DEPTH, SAMPLES / "intrinsics.json")
    b = dgli_vision.classify_pair(COLOR, DEPTH)
    assert (a.class_id, a.variant, a.distance) == (b.class_id, b.variant, b.distance)


@pytest.mark.parametrize("which", ["color", "depth", "--intrinsics", "--references"])
def test_a_directory_where_a_file_belongs_is_a_one_line_error(which, tmp_path):
    args = [str(COLOR), str(DEPTH)]
    if which == "color":
        args[0] = str(tmp_path)
    elif which == "depth":
        args[1] = str(tmp_path)
    else:
        args += [which, str(tmp_path)]
    r = CliRunner().invoke(main, ["classify", *args])
    assert r.exit_code == 2
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and str(tmp_path) in lines[0]
    assert "is a directory" in lines[0]


def test_classify_pair_takes_arrays_from_a_live_camera_like_files():
    rgb = cv2.cvtColor(cv2.imread(str(COLOR)), cv2.COLOR_BGR2RGB)
    depth = cv2.imread(str(DEPTH), cv2.IMREAD_UNCHANGED)
    from_arrays = dgli_vision.classify_pair(rgb, depth, SAMPLES / "intrinsics.json")
    from_files = dgli_vision.classify_pair(COLOR, DEPTH)
    assert from_arrays == from_files
    assert from_files.class_id == "05" and from_files.confidence >= 0.25


@pytest.mark.parametrize(
    ("color", "depth"),
    [
        (np.zeros((720, 1280), np.uint8), np.zeros((720, 1280), np.uint16)),  # grey
        (np.zeros((720, 1280, 3), np.uint8), np.zeros((720, 1280), np.float32)),  # metres?
        (np.zeros((720, 1280, 3), np.uint8), np.zeros((480, 640), np.uint16)),  # unregistered
    ],
)
def test_classify_pair_refuses_arrays_it_cannot_use(color, depth):
    with pytest.raises(DgliError):
        dgli_vision.classify_pair(color, depth)


ROOT = Path(__file__).resolve().parent.parent
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


@pytest.mark.parametrize("md", DOCS, ids=lambda p: p.name)
def test_the_docs_link_only_inside_the_repository(md):
    import re

    for link in re.findall(r"\]\(([^)\s]+)\)", md.read_text(encoding="utf-8")):
        if link.startswith("#"):
            continue
        assert not link.startswith(("http:", "https:")), link
        target = (md.parent / link.split("#")[0]).resolve()
        assert target.exists() and ROOT in target.parents, f"{md.name}: {link}"


def test_the_napkin_page_gives_the_layout_of_the_package():
    import re

    from dgli_vision.core.layout import default_layout

    layout = default_layout()
    text = (ROOT / "docs" / "napkin.md").read_text(encoding="utf-8")
    positions = {
        int(k): (float(u), float(v)) for k, u, v in re.findall(r"(\d+): \((\d+), (\d+)\)", text)
    }
    assert positions == {k: tuple(uv) for k, uv in enumerate(layout.sticker_uv)}
    colours = {}
    for row in re.findall(r"^\|(.*)\|$", text, flags=re.M):
        cells = [c.strip() for c in row.split("|")]
        for k, disc, dot in (cells[0:3], cells[4:7]) if len(cells) == 7 else ():
            if k.isdigit():
                colours[int(k)] = (disc, dot.split()[0])
    assert colours == {
        k: (layout.sticker_disc[k], layout.sticker_dot[k]) for k in range(layout.n_stickers)
    }


def test_the_readme_example_is_what_the_command_prints():
    # The README's first example: its output line is the command's, word for word.
    text = (ROOT / "README.md").read_text()
    shown = text.split("$ .venv/bin/dgli-classify ", 1)[1].splitlines()
    color, depth = shown[0].split()
    res = CliRunner().invoke(main, ["classify", str(ROOT / color), str(ROOT / depth)])
    assert res.exit_code == 0
    assert res.output.strip() == shown[1].strip()


def test_a_bgr_array_is_named_as_the_likely_cause():
    """OpenCV reads BGR; classify_pair takes RGB: when the swapped array reads, say so
    (a "cannot tell", not an exception)."""
    samples = Path(__file__).resolve().parents[1] / "sample_images"
    bgr = cv2.imread(str(samples / "05_000_color.png"))
    depth = cv2.imread(str(samples / "05_000_depth.png"), cv2.IMREAD_UNCHANGED)
    p = dgli_vision.classify_pair(bgr, depth)
    assert p.class_id is None and p.why == "colour channels"
    assert re.search(r"^cannot tell: .*is the colour array BGR.*color\[\.\.\., ::-1\]",
                     p.reason)
    assert dgli_vision.classify_pair(bgr[..., ::-1].copy(), depth).class_id == "05"


@lru_cache(maxsize=1)
def _flat_napkin() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sample 01 (RGB, depth) and its 16 sticker centres (16, 2) in pixels."""
    from dgli_vision.classifier.api import frame_from, reference_set_of
    from dgli_vision.classifier.pipeline import classify_frame

    rgb = cv2.cvtColor(cv2.imread(str(SAMPLES / "01_000_color.png")), cv2.COLOR_BGR2RGB)
    depth = cv2.imread(str(SAMPLES / "01_000_depth.png"), cv2.IMREAD_UNCHANGED)
    result = classify_frame(frame_from(rgb, depth), reference_set_of(None))
    assert result.detections.found.all()
    return rgb, depth, result.detections.centroids


def _with_stickers(keep: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Sample 01 with its colour washed to grey but around the stickers ``keep``."""
    rgb, depth, centres = _flat_napkin()
    out = cv2.cvtColor(cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY), cv2.COLOR_GRAY2RGB)
    for k in keep:
        u, v = np.round(centres[k]).astype(int)
        out[v - 25:v + 26, u - 25:u + 26] = rgb[v - 25:v + 26, u - 25:u + 26]
    return out, depth


def test_a_frame_with_three_stickers_in_view_is_a_cannot_tell_not_an_exception():
    rgb, depth = _with_stickers([0, 1, 2])
    p = dgli_vision.classify_pair(rgb, depth)
    assert p.class_id is None and p.name is None and p.variant is None
    assert p.why == "too few stickers"
    assert p.reason.startswith("cannot tell: 3 of 16 stickers located")
    assert p.stickers.found == (0, 1, 2) and p.confidence == 0.0 and p.candidates == ()


def test_a_frame_with_no_depth_reading_is_a_cannot_tell():
    rgb, depth = _flat_napkin()[:2]
    p = dgli_vision.classify_pair(rgb, np.zeros_like(depth))
    assert p.class_id is None and p.why == "too few stickers"
    assert p.reason.startswith("cannot tell:") and "depth" in p.reason


def test_the_readme_capture_loop_runs_as_written():
    """The README's loop, executed as it is printed, on frames with 0 to 16 stickers in
    view: no exception; each "cannot tell" carries its reason, the full view a class."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    code = text.split("In a capture loop:", 1)[1].split("```python\n", 1)[1].split("```")[0]
    frames = [_with_stickers(list(range(n))) for n in range(16)]  # 0 to 15 in view
    frames.append(_flat_napkin()[:2])  # and all 16

    class Camera:
        def read(self):
            return frames.pop(0)

    class Robot:
        def __init__(self):
            self.seen: list[tuple] = []

        @property
        def running(self) -> bool:
            return bool(frames)

        def look_again(self, reason):
            self.seen.append(("look again", reason))
            assert reason.startswith("cannot tell:")

        def on_state(self, class_id, variant):
            self.seen.append((class_id, variant))

    robot = Robot()
    exec(compile(code, "README.md", "exec"), {"robot": robot, "camera": Camera()})
    assert len(robot.seen) == 17
    assert all(what == "look again" for what, _ in robot.seen[:3])  # 0-2 stickers
    assert robot.seen[-1] == ("01", None)


def test_a_bgr_array_that_reads_mirrored_says_its_channels_are_swapped():
    # red and blue swapped turn corner A's discs into D's: the layout reads mirrored
    samples = Path(__file__).resolve().parents[1] / "sample_images"
    bgr = cv2.imread(str(samples / "07_000_color.png"))
    depth = cv2.imread(str(samples / "07_000_depth.png"), cv2.IMREAD_UNCHANGED)
    p = dgli_vision.classify_pair(bgr, depth)
    assert p.why == "colour channels" and p.reason.startswith(
        "cannot tell: colour channels swapped (BGR?): with red and blue swapped it reads as 07"
    )
    assert p.class_id is None and p.name is None and p.variant is None
    assert p.confidence < 0.25  # (candidates: those of the reading as given, if any)


def test_a_cannot_tell_names_no_class_and_keeps_the_nearest_in_candidates():
    samples = Path(__file__).resolve().parents[1] / "sample_images"
    rgb = cv2.imread(str(samples / "02_000_color.png"))[:, ::-1, ::-1].copy()  # mirrored
    depth = cv2.imread(str(samples / "02_000_depth.png"), cv2.IMREAD_UNCHANGED)[:, ::-1].copy()
    p = dgli_vision.classify_pair(rgb, depth)
    assert p.reason.startswith("cannot tell:") and "mirror" in p.reason
    assert p.class_id is None and len(p.candidates) >= 2
    assert p.candidates[0][2] == pytest.approx(p.distance, abs=1e-5)


def test_a_cannot_tell_with_its_yellow_stickers_in_view_is_classified_once(monkeypatch):
    """A BGR array never shows a yellow sticker, so a mirrored RGB frame (yellow in view)
    is not classified a second time with its channels swapped: that would double the
    time of every "cannot tell" frame in a live loop."""
    import dgli_vision.classifier.pipeline as pipeline

    calls = []
    real = pipeline.classify_frame
    monkeypatch.setattr(
        pipeline, "classify_frame", lambda *a, **k: calls.append(1) or real(*a, **k)
    )
    samples = Path(__file__).resolve().parents[1] / "sample_images"
    rgb = cv2.imread(str(samples / "02_000_color.png"))[:, ::-1, ::-1].copy()  # mirrored
    depth = cv2.imread(str(samples / "02_000_depth.png"), cv2.IMREAD_UNCHANGED)[:, ::-1].copy()
    p = dgli_vision.classify_pair(rgb, depth)
    assert p.class_id is None and "mirror" in p.reason
    assert len(calls) <= 1


def test_a_gripper_over_the_yellow_corner_is_classified_once(monkeypatch, pytestconfig):
    """A gripper over corner B hides its four yellow stickers, as a BGR array would; the
    frame read swapped shows no yellow disc either (its colour labels say so, no second
    classification), so it is classified once; a BGR array shows them and is looked at
    swapped (test_a_bgr_array_is_named_as_the_likely_cause)."""
    from render_cache import rendered

    import dgli_vision.classifier.pipeline as pipeline

    frame = rendered(pytestconfig, "01", 0, 2024, ("gripper",))
    calls = []
    real = pipeline.classify_frame
    monkeypatch.setattr(
        pipeline, "classify_frame", lambda *a, **k: calls.append(1) or real(*a, **k)
    )
    p = dgli_vision.classify_pair(frame.color, frame.depth_mm, frame.intrinsics)
    assert not {2, 3, 4, 5} & set(p.stickers.found)  # (corner B's stickers unseen)
    assert p.why != "colour channels" and len(calls) == 1
    calls.clear()
    bgr = cv2.imread(str(Path(__file__).resolve().parents[1] / "sample_images/05_000_color.png"))
    depth = cv2.imread(
        str(Path(__file__).resolve().parents[1] / "sample_images/05_000_depth.png"),
        cv2.IMREAD_UNCHANGED,
    )
    assert dgli_vision.classify_pair(bgr, depth).why == "colour channels"
    assert len(calls) == 2  # (its yellow stickers show as cyan ones: looked at swapped)


def test_a_pair_of_another_size_without_intrinsics_is_told_where_they_go(tmp_path):
    samples = Path(__file__).resolve().parents[1] / "sample_images"
    for kind in ("color", "depth"):
        img = cv2.imread(str(samples / f"05_000_{kind}.png"), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(tmp_path / f"s_{kind}.png"),
                    cv2.resize(img, (640, 360), interpolation=cv2.INTER_NEAREST))
    res = CliRunner().invoke(main, ["classify", str(tmp_path / "s_color.png"),
                                    str(tmp_path / "s_depth.png")])
    assert res.exit_code == 2
    assert "put the camera's intrinsics.json beside 's_color.png' or give --intrinsics" in (
        res.output)
