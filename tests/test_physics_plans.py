"""Issue 52: a plan's motion per hand (grasp, timed path, gripper), in JSON and in the
robot's frame, and the motion carried out on MuJoCo flex cloth (the 'physics' extra;
those tests skip where MuJoCo is missing)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dgli_vision.cli import main
from dgli_vision.core.layout import default_layout
from dgli_vision.planning.motion import PHASES, MotionParams, hands_motion

SAMPLES = Path(__file__).resolve().parents[1] / "sample_images"


def _plan(goal: str, *extra: str) -> dict:
    result = CliRunner().invoke(main, ["plan", str(SAMPLES / "01_000_color.png"),
                                       str(SAMPLES / "01_000_depth.png"), "--goal", goal,
                                       "--json", *extra])
    assert result.exit_code == 0, result.output
    return json.loads(result.output)


def _distance_from_line(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d = (b - a) / np.linalg.norm(b - a)
    rel = p - a
    return np.linalg.norm(rel - np.outer(rel @ d, d), axis=1)


def test_a_half_fold_has_two_hands_on_the_sides_corners_moving_together():
    (step,) = _plan("11/CD")["steps"]
    assert step["n_hands"] == 2
    hands = step["hands"]
    assert [h["grasp"]["what"] for h in hands] == ["corner C of side CD", "corner D of side CD"]
    # grasp/place/lift_height stay: the first hand's
    assert step["grasp"]["point"] == hands[0]["grasp"]["point"]
    assert step["place"]["point"] == hands[0]["place"]["point"]
    assert step["lift_height"] == hands[0]["lift_height"]
    for h in hands:
        path = h["path"]
        phases = [w["phase"] for w in path]
        assert [p for p in PHASES if p in phases] == list(dict.fromkeys(phases))
        t = [w["t"] for w in path]
        assert t == sorted(t) and t[0] == 0
        closed = [w["gripper"] == "closed" for w in path]
        # open on the way down, closed from the grasp to the release, open after
        first, last = closed.index(True), len(closed) - 1 - closed[::-1].index(True)
        assert not any(closed[:first]) and all(closed[first:last + 1])
        assert np.allclose(path[first]["point"], h["grasp"]["point"], atol=1e-5)
        assert np.allclose(path[last]["point"], h["place"]["point"], atol=1e-5)
    # both hands reach each waypoint at the same time: the side stays straight
    assert [w["t"] for w in hands[0]["path"]] == [w["t"] for w in hands[1]["path"]]


def test_the_carry_arc_never_takes_the_flap_taut():
    """Between grasp and place the hand keeps within its grasp's distance from the fold
    line (a taut flap drags the napkin on physics cloth), at arc_ratio of it at the top."""
    up = np.array([0.0, 0.0, 1.0])
    a, b = np.array([0.175, 0.0, 0.0]), np.array([0.0, 0.175, 0.0])
    g, p = np.array([0.0, 0.0, 0.0]), np.array([0.175, 0.175, 0.001])
    motion = MotionParams(arc_ratio=0.8)
    (hand,) = hands_motion([("corner A", g, None, p)], (a, b), up, motion)
    pts = np.array([w.point for w in hand.path if w.phase in ("lift", "carry", "lower")])
    r = float(_distance_from_line(g[None], a, b)[0])
    dist = _distance_from_line(pts, a, b)
    assert dist.max() <= r + 1.5e-3
    assert dist.min() == pytest.approx(0.8 * r, rel=0.02)
    assert hand.lift_height == pytest.approx(0.8 * r, rel=0.02)
    # a drag after lowering moves the placed point along the table, away from the line
    dragged = hands_motion([("corner A", g, None, p)], (a, b), up,
                           MotionParams(drag_m=0.02))[0]
    drag = next(w for w in dragged.path if w.phase == "drag")
    assert np.linalg.norm(np.subtract(drag.point, p)) == pytest.approx(0.02, abs=1e-6)
    assert _distance_from_line(np.array([drag.point]), a, b)[0] > r


def test_the_hands_paths_are_in_the_robots_frame_with_extrinsics(tmp_path):
    ext = tmp_path / "hand_eye.json"
    m = [[0, -1, 0, 0.5], [1, 0, 0, -0.2], [0, 0, 1, 0.1], [0, 0, 0, 1]]
    ext.write_text(json.dumps({"matrix": m, "frame": "base_link"}))
    cam = _plan("02/B")["steps"][0]["hands"][0]
    rob = _plan("02/B", "--extrinsics", str(ext))
    assert rob["frame"] == "base_link"
    hand = rob["steps"][0]["hands"][0]
    mat = np.array(m, dtype=float)
    for wc, wr in zip(cam["path"], hand["path"]):
        want = mat[:3, :3] @ np.array(wc["point"]) + mat[:3, 3]
        assert np.allclose(wr["point"], want, atol=2e-5)
        assert (wr["t"], wr["gripper"]) == (wc["t"], wc["gripper"])
    assert hand["grasp"]["pixel"] == cam["grasp"]["pixel"]


def test_physics_goes_with_check():
    result = CliRunner().invoke(main, ["plan", "--physics", "--from", "01", "--goal", "02/A"])
    assert result.exit_code == 2 and "--physics goes with --check" in result.output
    assert "Traceback" not in result.output


def test_physics_table_counts_the_one_step_plans():
    from dgli_vision.planning.physics_check import PhysicsRow, physics_table

    def row(goal, outcome, drag):
        made = {"base_drag_mm": drag, "crease_mm": 2.0, "tip_mm": 3.0, "landing_mm": [3.0]}
        return PhysicsRow(("01", None), goal, "one step", ("01", None), goal,
                          goal if outcome == "right" else None, outcome, True, made)

    rows = [row(("02", "A"), "right", 1.0), row(("11", "AB"), "right", 4.0),
            row(("12", "C"), "cannot tell", 30.0),
            PhysicsRow(("02", "A"), ("01", None), "unfold", ("02", "A"), ("01", None),
                       ("01", None), "right")]
    t = physics_table(rows)
    assert t["trials"] == 4 and t["right"] == 3
    assert t["one_step_success"] == pytest.approx(2 / 3, abs=1e-4)
    assert t["by_kind"] == {"one step": {"right": 2, "cannot tell": 1}, "unfold": {"right": 1}}
    assert t["base_drag_mm"]["max"] == 30.0


def test_the_physics_cloth_is_rendered_where_the_napkin_lies():
    from dgli_vision.sim.physics.export import cloth_state, sim_to_world, world_to_sim

    layout = default_layout()
    g = np.linspace(0, 0.4, 11)
    u, v = np.meshgrid(g, g)
    flat = np.stack([u.ravel(), v.ravel(), np.full(u.size, 0.0015)], axis=1)
    state = cloth_state(flat, (11, 11), layout, radius_m=0.0015, yaw=0.7, offset_m=(0.02, -0.01))
    want = sim_to_world(np.c_[layout.sticker_uv * 1e-3, np.zeros(16)], layout, 0.7, (0.02, -0.01))
    assert np.allclose(state.sticker_points, want, atol=1e-9)
    assert np.all(state.visible)
    back = world_to_sim(state.corner_points, layout, 0.7, (0.02, -0.01))
    assert np.allclose(back[:, :2] * 1e3, layout.corner_uv, atol=1e-6)


def test_a_corner_fold_on_physics_cloth_lands_where_the_path_puts_it():
    """One short fold on a coarse MuJoCo napkin (11 x 11 vertices): corner A carried by
    its hand's path over the fold line lands on its mirror image and the napkin that
    stays barely moves (the full table: benchmarks/physics_plans.py)."""
    pytest.importorskip("mujoco")
    from dgli_vision.sim.physics.grippers import HandPath, execute
    from dgli_vision.sim.physics.model import ClothMaterial, build_model

    layout = default_layout()
    material = ClothMaterial(grid=11)
    r = material.radius_m
    up = np.array([0.0, 0.0, 1.0])
    line = (np.array([0.2, 0.0, r]), np.array([0.0, 0.2, r]))

    grasp, place = np.array([0.0, 0.0, r]), np.array([0.2, 0.2, 3 * r])
    (hand,) = hands_motion([("corner A", grasp, None, place)], line, up,
                           MotionParams(carry_speed_m_s=0.3, lift_speed_m_s=0.2, grip_s=0.1))
    path = HandPath(np.array([w.t for w in hand.path]), np.array([w.point for w in hand.path]),
                    np.array([w.gripper == "closed" for w in hand.path]))
    cm = build_model(layout, material=material, hand_vertices=(0,))
    xyz = execute(cm, [path], settle_s=0.5).xyz
    assert np.linalg.norm(xyz[0, :2] - (0.2, 0.2)) < 0.012  # corner A on its mirror image
    assert xyz[0, 2] > 2 * r  # on top of the napkin, not under it
    far = [10, 110, 120]  # B, D and C stay where they were
    flat = np.array([[0.4, 0.0], [0.0, 0.4], [0.4, 0.4]])
    assert np.abs(xyz[far, :2] - flat).max() < 0.006


def test_the_python_plan_moves_the_hands_into_the_robots_frame():
    import dgli_vision

    m = np.array([[0, -1, 0, 0.5], [1, 0, 0, -0.2], [0, 0, 1, 0.1], [0, 0, 0, 1]], float)
    args = (str(SAMPLES / "01_000_color.png"), str(SAMPLES / "01_000_depth.png"))
    cam = dgli_vision.plan(*args, goal="11/CD").steps[0]
    rob = dgli_vision.plan(*args, goal="11/CD", extrinsics=m).steps[0]
    for hc, hr in zip(cam.hands, rob.hands, strict=True):
        assert np.allclose(hr.grasp_point, m[:3, :3] @ hc.grasp_point + m[:3, 3])
        for wc, wr in zip(hc.path, hr.path, strict=True):
            assert np.allclose(wr.point, m[:3, :3] @ np.array(wc.point) + m[:3, 3])
    assert rob.grasp_point == rob.hands[0].grasp_point
