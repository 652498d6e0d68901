"""Issue 41 item 9: the plan overlay has a legend with the grasp point in 3D and the lift
height, a grasp colour apart from the segments' magenta, a fold line seen on white, no
marker cut off at the image's edge, and an overlay (saying why) when there is no plan."""

from __future__ import annotations

import shutil
from pathlib import Path

import cv2
import numpy as np
from click.testing import CliRunner

from dgli_vision.camera import Intrinsics
from dgli_vision.cli import main
from dgli_vision.planning import overlay
from dgli_vision.planning.plan import PlanStep

INTR = Intrinsics(1280, 720, 605.0, 605.0, 639.5, 359.5)
SAMPLES = Path(__file__).resolve().parents[1] / "sample_images"


def at(u: float, v: float, z: float = 0.5) -> tuple[float, float, float]:
    """The 3D point (m) that projects to pixel (u, v) at depth z."""
    return ((u - INTR.cx) * z / INTR.fx, (v - INTR.cy) * z / INTR.fy, z)


def step(grasp_v: float = 400.0) -> PlanStep:
    return PlanStep(
        "fold", "B over", "B", None, False, ("04", "BC"),
        grasp_point=at(900, grasp_v), place_point=at(500, 300),
        fold_line=(at(400, 500), at(1000, 250)), lift_height=0.133,
    )


def test_the_grasp_is_not_the_segments_magenta():
    assert overlay.GRASP != overlay.SEGMENT
    assert overlay.SEGMENT == (255, 0, 255)  # what report.overlay_image draws segments in


def test_a_grasp_below_the_image_is_drawn_whole_just_inside_it():
    img = overlay.draw_step(np.full((720, 1280, 3), 128, np.uint8), step(735.0), INTR)
    grasp = np.all(img == overlay.GRASP, axis=2)
    rows = np.flatnonzero(grasp[:, 850:950].any(axis=1))
    # the disc (radius 10) whole: its rows end above the last row, with room for its rim
    assert rows.size and rows.max() <= 716 and rows.max() - rows.min() >= 18


def test_the_fold_line_has_a_dark_rim_on_a_white_napkin():
    img = overlay.draw_step(np.full((720, 1280, 3), 255, np.uint8), step(), INTR)
    a, b = np.array([400.0, 500.0]), np.array([1000.0, 250.0])
    line = [np.round(a + (b - a) * t).astype(int) for t in np.linspace(0.05, 0.45, 60)]
    dark = sum(int(img[v - 3 : v + 4, u - 3 : u + 4].min() < 60) for u, v in line)
    assert dark > 30  # dark pixels around the white dashes all along the line


def test_the_legend_gives_the_grasp_point_in_3d_and_the_lift_height():
    lines = overlay._step_lines(step(), "next: fold B -> 04/BC")
    assert lines[0] == "next: fold B -> 04/BC"
    assert lines[1] == "grasp (0.215, 0.033, 0.500) m, lift 0.133 m"
    assert lines[2].startswith("place (")
    img = overlay.draw_step(np.full((720, 1280, 3), 200, np.uint8), step(), INTR, "x")
    # the legend: a dark box at the foot of the image with every mark's symbol in it
    foot = img[640:718]
    assert (foot < 90).all(axis=2).mean() > 0.2
    assert np.all(foot == overlay.PLACE, axis=2).any()


def test_with_no_plan_the_overlay_is_written_and_says_why(tmp_path):
    frames = tmp_path / "f"
    frames.mkdir()
    shutil.copy(SAMPLES / "intrinsics.json", frames)
    shutil.copy(SAMPLES / "05_000_color.png", frames / "c.png")
    depth = cv2.imread(str(SAMPLES / "05_000_depth.png"), cv2.IMREAD_UNCHANGED)
    cv2.imwrite(str(frames / "d.png"), (depth // 10).astype(np.uint16))  # cm: no state
    out = tmp_path / "plan.png"
    res = CliRunner().invoke(
        main, ["plan", str(frames / "c.png"), str(frames / "d.png"), "--goal", "08",
               "--overlay", str(out)],
    )
    assert res.exit_code == 1 and "the state cannot be told" in res.output, res.output
    img = cv2.imread(str(out))
    assert img is not None and img.shape == (720, 1280, 3)
    before = cv2.imread(str(frames / "c.png"))
    foot = (slice(-36, -4), slice(4, 400))  # the box with why at the foot, darkened
    assert img[foot].mean() < 0.6 * before[foot].mean()
